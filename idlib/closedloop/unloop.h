// Plant from an identified closed loop (DESIGN.md item 3; seed 000, eq 14).
//
// With the project's convention (controller C maps e = −q to u_c, u = u_c + v),
// the identified closed loop is G = P (I + C P)⁻¹ : v → q.  Solving for P:
//   G (I + C P) = P  ⇒  G = P − G C P = (I − G C) P  ⇒  P = (I − G C)⁻¹ G = G (I − C G)⁻¹,
// a POSITIVE feedback of C around G (interconnect.h: positive_feedback_with),
// of order n_G + n_C.  Since G already contains a copy of the controller, 2 n_C
// modes of this interconnection sit at the controller's poles and cancel
// (uncontrollable/unobservable): for the 3-DOF platform with a PI per axis,
// 9 + 3 = 12 states, 6 cancelled at z = 1, plant order 6 (the seed's P_6).
//
// With an identified (noisy) G the cancellation is only approximate: the
// near-cancelled eigenvalues form a perturbed multiple eigenvalue near the
// controller poles that may split by ε^{1/k} and leave the unit circle, while
// genuine plant poles can also lie close to z = 1.  Balanced truncation of the
// interconnection then fails (unstable or not defined).  This function instead
//   1. forms the interconnection P_full = G (I − C G)⁻¹;
//   2. takes as candidates the eigenvalue groups (real or complex pairs) of
//      P_full nearest to the controller poles: enough for the k = min(2 n_C,
//      n_G + n_C − plant_order) modes to remove plus `extra_candidates` more;
//   3. for every candidate set of exactly k eigenvalues (conjugate pairs kept
//      together) removes it with remove_modes (ordered Schur + Sylvester) and
//      scores the result by how little the removal changes the response:
//        score = mean_ω ‖P_kept − P_full‖₂ / (‖P_full‖₂ + ‖P_kept‖₂)
//      on a log grid up to Nyquist (the removed modal part P_full − P_kept is
//      exactly the removed modes' contribution Σ R_i/(λ − λ_i), so this ranks
//      modes by distance to the controller poles AND smallness of their
//      residue: a genuine plant pole near z = 1 has a large residue and is kept);
//      among near-equal scores (within a factor 2) a stable result is preferred
//      over an unstable one (an unstable plant, e.g. maglev, must stay possible);
//   4. refits the kept model's B (poles, C, D fixed) by linear least squares
//      to P_full on the grid a decade above the fastest removed mode (relative
//      weighting): with a noisy G the removed residues do not sum to zero and
//      their tail is part of the measured response in the band (measured on the
//      test stage: error 6e-2 without, 4.7e-3 with, for 5.1e-3 in P_full itself);
//   5. if the order still exceeds plant_order, balanced truncation (when the
//      reduced model is stable).
// If there are more than kMaxCandidateSets candidate sets, the search is greedy
// (one group at a time, same score).
//
// | model        | inputs | outputs | states |
// |--------------|--------|---------|--------|
// | closed_loop G| m (v)  | p (q)   | n_G    |
// | controller C | p (e)  | m (u_c) | n_C    |
// | plant P      | m (u)  | p (q)   | plant_order |
//
// @throws InputError  a model is invalid; sample periods of G and C differ (the
//                     message names both); dimensions do not match; I − D_C D_G is
//                     singular (algebraic loop); options invalid; plant_order (or
//                     n_G − n_C when 0) not in [1, n_G + n_C].
#pragma once

#include <Eigen/Core>

#include "idlib/core/error.h"
#include "idlib/core/types.h"

namespace lpvid {

struct UnloopOptions {
  // Step 0 (before 1.): impose G(λ) = 0 and G'(λ) = R⁻¹ at the controller's poles
  // (interpolation.h), so that the controller modes cancel exactly.  On the
  // simulated platform this is what makes the recovered z channel right: without
  // it a genuine plant pole at z = 0.994 is confused with the split pair at z = 1.
  bool impose_controller_interpolation = true;
  Index plant_order = 0;  // 0: n_G − n_C
  // Candidate groups considered beyond the k nearest eigenvalues (see header).
  Index extra_candidates = 4;
  // Warn when the removed modes' peak gain over the grid exceeds this fraction
  // of the kept plant's peak gain: the cancellation was then not exact and the
  // removed modes carried part of the measured behaviour.
  double removed_gain_warning = 1e-2;
  // Throws InputError naming the option and the rule.
  void validate() const;
};

struct UnloopResult {
  StateSpace plant;
  Eigen::VectorXcd removed_poles;    // eigenvalues of P_full that were removed
  Index interconnection_order = 0;   // n_G + n_C
  double removed_relative_gain = 0;  // peak ‖P_full − P_kept‖ / peak ‖P_kept‖ over the grid
  Report report;
  bool interpolation_applied = false;  // step 0 changed G
  std::string interpolation_note;      // what step 0 did, or why not
};

// Candidate sets above this count switch the search to greedy (bounded cost:
// each set costs one Schur form and one response evaluation of P_full).
inline constexpr Index kMaxCandidateSets = 2000;

UnloopResult plant_from_closed_loop(const StateSpace& closed_loop, const StateSpace& controller, const UnloopOptions& options);

}  // namespace lpvid
