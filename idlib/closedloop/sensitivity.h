// Plant frequency response from closed-loop frequency-response data (FRD),
// frequency by frequency (DESIGN.md item 4; seed 000, eq 15; docs/math.md §4).
//
// Convention of the project (idlib/lti/interconnect.h): the controller C maps the
// error e = −q to u_c, the plant input is u = u_c + v (v injected), q = P u:
//   input sensitivity   S = (I + C P)⁻¹      : v → u   (m x m)
//   closed-loop output  G = P (I + C P)⁻¹    : v → q   (p x m)
// Solving for P at each frequency ω:
//   S⁻¹ = I + C P          ⇒  P = C⁻¹ (S⁻¹ − I)          (needs a square C: p = m)
//   G (I + C P) = P        ⇒  P = G (I − C G)⁻¹
// The seed's eq (15) prints P = C⁻¹ (S − I)⁻¹, which equals −C⁻¹ − C⁻¹ P⁻¹ C⁻¹,
// not P; plant_from_sensitivity_printed_eq15 keeps it only to show that it fails.
//
// C(ω) is the controller's response from evaluate_response (idlib/lti/
// frequency_response.h): C(e^{jωTs}) for a discrete controller (Ts = its
// sample_period_s), C(jω) for a continuous one.
//
// | data / model   | shape (per frequency) | maps |
// |----------------|-----------------------|------|
// | S (FRD)        | m x m complex         | v → u |
// | G (FRD)        | p x m complex         | v → q |
// | controller C   | m outputs, p inputs   | e → u_c |
// | plant P (FRD)  | p x m complex         | u → q |
//
// Every function throws InputError when: the controller is invalid
// (StateSpace::validate); the FRD is empty, its response count differs from its
// frequency count, its matrices differ in shape between frequencies or do not match
// the controller (the message names both shapes); coherence or flagged are
// present with the wrong count/shape; a frequency or a response entry is NaN/Inf;
// a frequency lies above the Nyquist frequency π / Ts of a discrete controller
// (|ω| > π / Ts · (1 + 1e-9)); options are invalid.
#pragma once

#include <string>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/types.h"

namespace lpvid {

struct SensitivityUnloopOptions {
  // Flag a frequency when the 2-norm condition number (σ_max / σ_min, from an SVD)
  // of S, of S⁻¹ − I (= C P) or of C(ω) exceeds this; > 1.  Relative errors in S
  // are amplified by up to this factor in P.
  double max_condition = 1e6;
  // Flag a frequency when the coherence of S (if present) is below this in some
  // row or some column: the best-explained entry of every row and of every column
  // must reach it.  (So a weak cross-coupling entry with a low ORDINARY coherence
  // — see idlib/signal/frf.h — does not flag the frequency, but an output or an
  // input that no entry explains does.)  In [0, 1]; 0 disables the check.
  double min_coherence = 0.5;
  // Flag a frequency when the loop gain is this small in some direction:
  // σ_min(S⁻¹ − I) = σ_min(C P) < min_loop_gain.  There S ≈ I and P rests on
  // S − I ≈ −C P, a difference of order min_loop_gain against entries of order 1;
  // the default 1e-4 (80 dB) is about the dynamic range an analyzer resolves next
  // to a full-scale signal (16-bit front ends: ~90 dB).  Not a judgement of the
  // noise: with noise from the sensors, P's relative error there is the output
  // noise-to-signal ratio (docs/math.md §4), which coherence tells.  >= 0; 0
  // disables the check.
  double min_loop_gain = 1e-4;
  // @throws InputError naming the option and the rule.
  void validate() const;
};

struct SensitivityUnloopResult {
  // P at the frequencies of S.  input_names = S.output_names (the plant inputs u),
  // output_names = controller.input_names; coherence is left empty (P's quality is
  // described by the flags).  flagged[k] == !flag_reasons[k].empty().
  // At a flagged frequency the response is still P = C⁻¹ (S⁻¹ − I) when S and C are
  // numerically invertible (σ_min > 0), and ZERO otherwise.
  FrequencyResponse plant;
  // One entry per frequency: empty when ok, otherwise the reasons joined by "; ",
  // each starting with one of
  //   "input flagged"          S.flagged[k] was set by the producer of S;
  //   "C ill-conditioned"      cond(C(ω)) > max_condition (or C(ω) singular / a
  //                            controller pole exactly at ω);
  //   "S ill-conditioned"      cond(S) > max_condition (S⁻¹ unreliable);
  //   "S^-1 - I ill-conditioned"  cond(S⁻¹ − I) > max_condition (loop gain C P
  //                            nearly singular: its small directions are lost in
  //                            the noise of S);
  //   "low coherence"          the coherence rule of the options;
  //   "low loop gain"          σ_min(S⁻¹ − I) < min_loop_gain (see the options).
  std::vector<std::string> flag_reasons;
  Index flagged_count = 0;
  // usable == false when every frequency is flagged; warnings count each reason.
  Report report;
};

// Relative tolerance |ω_C − ω_data| / ω_data for a measured controller's
// frequencies to be the data's (files written by lpvid and read back agree to ~1e-15).
inline constexpr double kMeasuredControllerFrequencyRelTolerance = 1e-9;

// The controller of the per-frequency routes below: a model (C(ω) evaluated at
// every data frequency, as before), or its MEASURED response (FRD: p inputs, m
// outputs, C(ω_k) = response[k]) on exactly the data's frequencies (relative
// kMeasuredControllerFrequencyRelTolerance), else InputError naming the first
// frequency that differs.  Implicit from either; holds a reference (the caller
// keeps the controller alive).
class KnownController {
 public:
  KnownController(const StateSpace& model) : model_(&model) {}                // NOLINT: implicit by design
  KnownController(const FrequencyResponse& measured) : measured_(&measured) {}  // NOLINT: implicit by design
  const StateSpace* model() const { return model_; }
  const FrequencyResponse* measured() const { return measured_; }
  Index num_inputs() const { return model_ ? model_->num_inputs() : measured_->num_inputs(); }
  Index num_outputs() const { return model_ ? model_->num_outputs() : measured_->num_outputs(); }
  const std::vector<std::string>& input_names() const { return model_ ? model_->input_names : measured_->input_names; }
  // StateSpace::validate, or a measured response with frequencies and finite values.
  void validate() const;

 private:
  const StateSpace* model_ = nullptr;
  const FrequencyResponse* measured_ = nullptr;
};

// P(ω) = C(ω)⁻¹ (S(ω)⁻¹ − I) at every frequency of S, with flags (see above).
// Cost per frequency: three m x m complex SVDs (S, S⁻¹ − I, C) plus one controller
// evaluation, O(n_C² m) after a one-off Hessenberg reduction.
SensitivityUnloopResult plant_from_sensitivity(const FrequencyResponse& S, const KnownController& controller,
                                               const SensitivityUnloopOptions& options);

// E|P̂ − P|² per entry of P = C⁻¹ (S⁻¹ − I) from the per-entry variance of the measured S
// (s_variance[k](k', l) = E|Ŝ_k'l − S_k'l|² at S's frequency k), to first order in the
// error and with the errors of different entries of S taken as independent:
//   dP = −C⁻¹ S⁻¹ dS S⁻¹   ⇒   E|dP_ab|² = Σ_kl |(C⁻¹ S⁻¹)_ak|² |(S⁻¹)_lb|² E|dS_kl|².
// At a frequency where S or C(ω) is singular, or a variance is not finite, the result is
// +inf (nothing is known of P there).
// @throws InputError  as plant_from_sensitivity for S and the controller; s_variance
//                     not one m × m matrix per frequency, or holding a negative value.
std::vector<Eigen::MatrixXd> plant_variance_from_sensitivity(const FrequencyResponse& S,
                                                             const std::vector<Eigen::MatrixXd>& s_variance,
                                                             const KnownController& controller);

// The seed's printed eq (15): C(ω)⁻¹ (S(ω) − I)⁻¹.  WRONG (it is −C⁻¹ − C⁻¹P⁻¹C⁻¹);
// kept to demonstrate the failure.  No conditioning checks: frequencies where
// S − I or C is exactly singular are flagged and set to zero; names as above.
FrequencyResponse plant_from_sensitivity_printed_eq15(const FrequencyResponse& S, const StateSpace& controller);

// P(ω) = G(ω) (I − C(ω) G(ω))⁻¹ for closed-loop FRD G: v → q (p x m) and a
// controller with p inputs and m outputs.  Frequencies where G is flagged, or
// where I − C G is singular or has a 2-norm condition number above
// SensitivityUnloopOptions{}.max_condition, are flagged (the value is computed
// when I − C G is numerically invertible, zero otherwise).  input_names /
// output_names are copied from G; coherence is left empty.
FrequencyResponse plant_from_closed_loop_frd(const FrequencyResponse& G, const KnownController& controller);

}  // namespace lpvid
