// Transfer functions to state space (idlib/lti/transfer_function.h): the state
// space's frequency response (evaluate_response: (e^{jωT} I − A)^-1 B + D) against
// the transfer function evaluated here directly from its coefficients or factors
// (Horner's rule / the product of factors, written in this file).
#include "idlib/lti/transfer_function.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>

#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"

namespace lpvid {
namespace transfer_function_test {

constexpr double kTs = 1e-4;  // 10 kHz, a motion controller's rate
constexpr double kPi = std::numbers::pi;

// Σ c_k x^(n−k) (descending).
Complex polyval(const std::vector<double>& c, Complex x) {
  Complex v = 0;
  for (const double a : c) v = v * x + a;
  return v;
}
// Π(z − r) as descending real coefficients (the roots in conjugate pairs).
std::vector<double> poly(const std::vector<Complex>& roots) {
  std::vector<Complex> c = {1.0};
  for (const Complex& r : roots) {
    std::vector<Complex> next(c.size() + 1, 0.0);
    for (size_t k = 0; k < c.size(); ++k) {
      next[k] += c[k];
      next[k + 1] -= r * c[k];
    }
    c = next;
  }
  std::vector<double> out;
  for (const Complex& v : c) out.push_back(v.real());
  return out;
}

// The lab's controller: PID (integrator pole at 1, derivative filter pole), a notch
// at 300 Hz (zeros 1e-4 inside the unit circle, poles at radius 0.98) and a
// second-order low-pass at 1.5 kHz.  4 zeros, 6 poles.
struct Lab {
  double notch_rad = 2 * kPi * 300 * kTs;
  double lp_rad = 2 * kPi * 1500 * kTs;
  std::vector<Complex> zeros = {0.995, 0.98, std::polar(0.9999, notch_rad), std::polar(0.9999, -notch_rad)};
  std::vector<Complex> poles = {1.0, 0.5, std::polar(0.98, notch_rad), std::polar(0.98, -notch_rad),
                                std::polar(0.85, lp_rad), std::polar(0.85, -lp_rad)};
  double gain = 0.8;
  Complex at(double w) const {  // k Π(z − z_i) / Π(z − p_i)
    const Complex z = std::polar(1.0, w * kTs);
    Complex v = gain;
    for (const Complex& q : zeros) v *= z - q;
    for (const Complex& p : poles) v /= z - p;
    return v;
  }
};

// A grid from 0.5 Hz to just below Nyquist with points at and within 0.01 % of the notch.
Eigen::VectorXd grid_with_notch(double notch_hz) {
  Eigen::VectorXd w = log_frequency_grid(2 * kPi * 0.5, 2 * kPi * 4900, 400);
  Eigen::VectorXd out(w.size() + 5);
  out << w, 2 * kPi * notch_hz * Eigen::Vector<double, 5>(0.999, 0.9999, 1.0, 1.0001, 1.001);
  return out;
}

// Worst relative error over w, optionally only where |f − exclude_hz| > exclude_width_hz.
double max_rel_error(const StateSpace& s, const Eigen::VectorXd& w, const std::function<Complex(double)>& truth,
                     double exclude_hz = 0, double exclude_width_hz = -1) {
  const std::vector<Eigen::MatrixXcd> h = evaluate_response(s, w);
  double worst = 0;
  for (Index k = 0; k < w.size(); ++k) {
    if (std::abs(w[k] / (2 * kPi) - exclude_hz) <= exclude_width_hz) continue;
    worst = std::max(worst, std::abs(h[static_cast<size_t>(k)](0, 0) - truth(w[k])) / std::abs(truth(w[k])));
  }
  return worst;
}

TEST(TransferFunction, ZpkCascade_MatchesTheFactorsToRoundOffIncludingAtTheNotch) {
  const Lab lab;
  SisoTf tf;
  tf.is_zpk = true;
  tf.zeros = lab.zeros;
  tf.poles = lab.poles;
  tf.gain = lab.gain;
  const StateSpace s = realize_siso(tf, TfVariable::kZ, kTs);
  EXPECT_EQ(s.order(), 6);
  const auto truth = [&](double w) { return lab.at(w); };
  // Away from the notch (|f − 300 Hz| > 5 Hz): measured 1.8e-12 (worst at 0.5 Hz,
  // next to the integrator pole at z = 1, where |z − 1| = 3e-4 amplifies the ulps).
  constexpr double kRoundOff = 5e-12;
  EXPECT_LE(max_rel_error(s, grid_with_notch(300), truth, 300, 5), kRoundOff);
  // In the notch, where |H| falls 60× below its neighbours: measured 2.35e-11.  The
  // round-off of the section's coefficients [1, −2r cos θ, r²] moves its zeros by
  // ~2e-15, which is 2e-11 of their 1e-4 distance from the unit circle: the
  // conditioning of the notch itself, not of the realisation.
  constexpr double kNotchRoundOff = 1e-10;
  EXPECT_LE(max_rel_error(s, grid_with_notch(300), truth), kNotchRoundOff);
}

TEST(TransferFunction, NumDenInZAndInZInverse_MatchDirectEvaluation) {
  const Lab lab;
  std::vector<double> num = poly(lab.zeros);
  const std::vector<double> den = poly(lab.poles);
  for (double& v : num) v *= lab.gain;
  const Eigen::VectorXd w = grid_with_notch(300);
  // Descending powers of z: H = num(z) / den(z).
  SisoTf z;
  z.num = num;
  z.den = den;
  const StateSpace sz = realize_siso(z, TfVariable::kZ, kTs);
  EXPECT_EQ(sz.order(), 6);
  // One sixth-order companion form with a pole at 1 and the notch poles at 0.98:
  // the expanded coefficients carry the error (their roots are ill-conditioned,
  // which is why zpk elements are cascaded instead).  Measured 8.5e-10 (z) and
  // 1.5e-9 (z^-1), worst in the notch; 1e-8 leaves margin.
  constexpr double kCompanionRoundOff = 1e-8;
  EXPECT_LE(max_rel_error(sz, w, [&](double x) {
              const Complex q = std::polar(1.0, x * kTs);
              return polyval(num, q) / polyval(den, q);
            }),
            kCompanionRoundOff);
  // The same coefficients read as ascending powers of z^-1 describe z^2 num(z)/den(z)
  // only when deg num = deg den − 2: here H_inv(z) = num(1/z)/den(1/z).
  SisoTf zi;
  zi.num = num;
  zi.den = den;
  const StateSpace si = realize_siso(zi, TfVariable::kZInverse, kTs);
  EXPECT_LE(max_rel_error(si, w, [&](double x) {
              const Complex q = std::polar(1.0, -x * kTs);  // z^-1
              std::vector<double> b(num.rbegin(), num.rend()), a(den.rbegin(), den.rend());
              return polyval(b, q) / polyval(a, q);
            }),
            kCompanionRoundOff);
}

TEST(TransferFunction, Conventions_TfAndFiltOfTheSameNumbersDiffer) {
  SisoTf tf;
  tf.num = {1};
  tf.den = {1, 0.5};
  // tf([1], [1 0.5], Ts) = 1/(z + 0.5): strictly proper, D = 0.
  EXPECT_EQ(realize_siso(tf, TfVariable::kZ, kTs).D(0, 0), 0.0);
  // filt([1], [1 0.5], Ts) = 1/(1 + 0.5 z^-1) = z/(z + 0.5): D = 1.
  EXPECT_EQ(realize_siso(tf, TfVariable::kZInverse, kTs).D(0, 0), 1.0);
  // zpk in z^-1: k (1 − 0.5 z^-1) / (1 − 0.2 z^-1) at z = −1: 2 · 1.5 / 1.2.
  SisoTf zpk;
  zpk.is_zpk = true;
  zpk.zeros = {0.5};
  zpk.poles = {0.2};
  zpk.gain = 2;
  const Eigen::VectorXd nyquist = Eigen::VectorXd::Constant(1, kPi / kTs);
  EXPECT_NEAR(evaluate_response(realize_siso(zpk, TfVariable::kZInverse, kTs), nyquist)[0](0, 0).real(), 2 * 1.5 / 1.2, 1e-14);
  // zpk in z^-1 with more zeros than poles: k (1 − 0.5 z^-1) = 2 − z^-1, at z = −1: 3.
  zpk.poles.clear();
  EXPECT_NEAR(evaluate_response(realize_siso(zpk, TfVariable::kZInverse, kTs), nyquist)[0](0, 0).real(), 3.0, 1e-14);
}

TEST(TransferFunction, Matrix_StacksElementsAndKeepsZeroEntriesZero) {
  SisoTf a, b;
  a.num = {0.1, 0.05};
  a.den = {1, -0.9};
  b.is_zpk = true;
  b.zeros = {Complex(0.3, 0.4), Complex(0.3, -0.4)};
  b.poles = {Complex(0.5, 0.5), Complex(0.5, -0.5), 0.2};
  b.gain = -3;
  const StateSpace s = realize_tf_matrix({a, std::nullopt, b, a}, 2, 2, TfVariable::kZ, kTs);
  EXPECT_EQ(s.order(), 1 + 3 + 1);  // block stacking: not minimal (a appears twice)
  const Eigen::VectorXd w = Eigen::Vector3d(10.0, 3000.0, 20000.0);
  const std::vector<Eigen::MatrixXcd> h = evaluate_response(s, w);
  for (Index k = 0; k < w.size(); ++k) {
    const Complex z = std::polar(1.0, w[k] * kTs);
    const Complex ha = (0.1 * z + 0.05) / (z - 0.9);
    const Complex hb = -3.0 * (z - Complex(0.3, 0.4)) * (z - Complex(0.3, -0.4)) /
                       ((z - Complex(0.5, 0.5)) * (z - Complex(0.5, -0.5)) * (z - 0.2));
    constexpr double kRoundOff = 1e-13;  // low-order elements: a few ulps
    EXPECT_LE(std::abs(h[static_cast<size_t>(k)](0, 0) - ha), kRoundOff * std::abs(ha));
    EXPECT_EQ(h[static_cast<size_t>(k)](0, 1), Complex(0, 0));
    EXPECT_LE(std::abs(h[static_cast<size_t>(k)](1, 0) - hb), kRoundOff * std::abs(hb));
    EXPECT_LE(std::abs(h[static_cast<size_t>(k)](1, 1) - ha), kRoundOff * std::abs(ha));
  }
}

std::string error_of(const SisoTf& tf, TfVariable v) {
  try {
    realize_siso(tf, v, kTs);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(TransferFunction, BadElements_AreRefusedWithTheRuleAndTheFix) {
  SisoTf tf;
  tf.num = {1};
  tf.den = {0, 1, 0.5};
  EXPECT_EQ(error_of(tf, TfVariable::kZ),
            "the denominator's leading coefficient (of z^2) is 0; remove the leading zeros (\"variable\": \"z\" lists "
            "descending powers of z)");
  EXPECT_EQ(error_of(tf, TfVariable::kZInverse).rfind("the denominator's first coefficient (of z^0) is 0", 0), 0u);
  tf.num = {1, 2, 3};
  tf.den = {1, 0.5};
  EXPECT_EQ(error_of(tf, TfVariable::kZ).rfind("the numerator has degree 2 in z but the denominator only 1: the element is improper", 0), 0u);
  SisoTf zpk;
  zpk.is_zpk = true;
  zpk.poles = {Complex(0.5, 0.5), Complex(0.5, -0.4)};
  EXPECT_EQ(error_of(zpk, TfVariable::kZ),
            "pole 1 = [0.5, 0.5] has no complex-conjugate partner; complex poles must come in conjugate pairs (real "
            "coefficients): add [0.5, -0.5]");
  zpk.poles = {0.5};
  zpk.zeros = {0.1, 0.2};
  EXPECT_EQ(error_of(zpk, TfVariable::kZ).rfind("2 zeros but 1 poles: the element is improper", 0), 0u);
}

}  // namespace transfer_function_test
}  // namespace lpvid
