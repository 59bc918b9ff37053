// The interpolation conditions a controller imposes on its closed loop, and
// their enforcement on an identified closed loop before the loop is inverted.
//
// With the project's convention (C maps e = −q to u_c, u = u_c + v) the closed
// loop is G = P (I + C P)⁻¹.  Near a pole λ of the controller with residue
// R = lim_{z→λ} (z − λ) C(z) (m x p, invertible), C ≈ R / (z − λ), so
//   I + C P ≈ R P(λ) / (z − λ)   and   G = P (I + C P)⁻¹ ≈ (z − λ) R⁻¹,
// that is, EXACTLY for the true loop (whenever R P(λ) is invertible):
//   G(λ) = 0          and          G'(λ) = dG/dz(λ) = R⁻¹.
// An identified G meets these only approximately; then the 2 n_C modes of the
// interconnection G (I − C G)⁻¹ at the controller poles cancel only nearly,
// split like a perturbed Jordan block (by ~sqrt of the error) and mingle with
// genuine plant poles near z = 1.  Imposing the conditions restores exact
// cancellation, so that unloop removes modes that are exactly at the
// controller's poles.  For an integrating (PI) controller, λ = 1 and G(1) = 0
// says the loop rejects constant disturbances completely, as it does.
//
// The correction changes B only, by the minimum-Frobenius-norm ΔB meeting the
// linear conditions  C (λI − A)⁻¹ ΔB = −G(λ)  and  −C (λI − A)⁻² ΔB = R⁻¹ − G'(λ)
// for every distinct controller pole λ (complex λ: real and imaginary parts).
#pragma once

#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

struct InterpolationCorrection {
  StateSpace closed_loop;        // G with B replaced by B + ΔB (or unchanged)
  bool applied = false;          // false: no usable controller pole (see note)
  double relative_change = 0.0;  // ‖ΔB‖_F / ‖B‖_F
  Index conditions = 0;          // real scalar equations imposed
  std::string note;              // one line: what was imposed, or why not
};

// | argument    | shape |
// |-------------|-------|
// | closed_loop | G: m inputs (v), p outputs (q), n_G states, discrete or continuous |
// | controller  | C: p inputs (e), m outputs (u_c), same sample period |
//
// Poles of C whose residue is not square and well conditioned (condition number
// above kMaxResidueCondition), a defective controller A, a pole of C that is
// also an eigenvalue of G's A, or more equations than states: the correction is
// skipped (applied = false, note says why); it never throws for these.
// @throws InputError  shapes of G and C do not match.
InterpolationCorrection impose_controller_interpolation(const StateSpace& closed_loop, const StateSpace& controller);

// Residues above this condition number are not inverted (R⁻¹ would amplify the
// controller's rounding): 1e8 leaves 8 of 16 digits.
inline constexpr double kMaxResidueCondition = 1e8;

}  // namespace lpvid
