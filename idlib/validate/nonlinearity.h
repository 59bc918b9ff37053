// Whether a linear model's residual on a log holds a nonlinearity (issue 24: a positioning
// axis with Coulomb friction gave identify a best linear approximation with an 82.5 %
// simulation fit, and nothing said that no linear model could do better).
//
// The residual of a linear model is e = y − ŷ, ŷ the model's simulation from the logged
// excitation.  When the plant is linear, e is the noise (plus, for a wrong linear model, a
// linear function of the excitation); it is then uncorrelated with any function of ŷ that
// is uncorrelated with linear functionals of the excitation.  For a Gaussian ŷ, g(ŷ) − b ŷ
// with b = E[g(ŷ) ŷ] / E[ŷ²] is such a function (Bussgang).  For any distribution (a
// reference trajectory is not Gaussian) the tested features — nonlinear functions of each
// simulated output — are made orthogonal to the span of [1, ŷ_j(t−K), …, ŷ_j(t+K)], K = 10,
// whatever a short linear filter of ŷ_j can hold:
//   "sign of the rate"  sign(Δŷ_j)   (friction: a force that flips with the velocity)
//   "square"            ŷ_j²         (an even nonlinearity: a one-sided force, a gap)
//   "cube"              ŷ_j³         (an odd one: a stiffening or softening spring)
// A nonlinear plant leaves in e what its linear approximation cannot follow, which
// correlates with some of them.
//
// Significance without assuming white signals (the features of a slow motion are strongly
// coloured): the record is cut into S segments; r_s(τ) = Σ_{t∈s} e_i(t+τ) f(t) / (‖e_i‖_s ‖f‖_s),
// each segment's own correlation coefficient, per segment and lag τ = −L..L; the statistic is the mean over segments divided by its
// standard error from their spread, a t with S − 1 degrees of freedom, judged against the
// family-wise (Bonferroni over every lag, feature and residual channel) quantile at
// `confidence`, mapped from the normal quantile by the Cornish–Fisher expansion
// (Abramowitz & Stegun 26.7.5).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

struct NonlinearityOptions {
  Index max_lag = 25;        // L, samples
  Index segments = 32;       // S (fewer when the record is short: each at least 16 L samples)
  double confidence = 0.99;  // family-wise
  void validate() const;     // @throws InputError naming the field
};

struct NonlinearityTest {
  Index residual_channel = 0, feature_channel = 0;
  std::string feature;  // "sign of the rate", "square", "cube"
  double r = 0;         // the mean segment correlation at the worst lag
  int lag = 0;          // τ: e(t + τ) against f(t)
  double t = 0;         // its t statistic
};

struct NonlinearityResult {
  bool ran = false;      // false when the record is too short (reason says so)
  std::string reason;
  Index segments = 0;
  double threshold = 0;  // the family-wise quantile of |t|
  std::vector<NonlinearityTest> tests;  // one per (residual channel, feature), worst lag each
  std::vector<Index> significant;       // indices into tests with |t| > threshold, by |t| descending
};

// | residual: N × p (measured − simulated) | simulated: N × p (the model's ŷ) |
// @throws InputError  shapes that differ; non-finite values; invalid options.
NonlinearityResult nonlinearity_tests(const Eigen::MatrixXd& residual, const Eigen::MatrixXd& simulated,
                                      const NonlinearityOptions& options = {});

// One sentence for a report: the strongest significant features and what they suggest,
// or that none was seen.  `names`: the outputs' names (p).
std::string nonlinearity_sentence(const NonlinearityResult& r, const std::vector<std::string>& names);

}  // namespace lpvid
