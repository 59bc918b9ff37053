#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>

#include "idlib/core/error.h"
#include "idlib/lti/discretize.h"
#include "idlib/plants/platform/platform.h"
#include "idlib/sim/platform_sim.h"
#include "tests/idlib/plants/closed_loop_test_util.h"

namespace lpvid {
namespace platform_sim_test {

constexpr std::uint64_t kSimSeed = 7;
constexpr std::uint64_t kOtherSeed = 8;

std::string error_text(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "<no InputError>";
}

struct Loop {
  StateSpace plant, controller;
};
Loop paper_loop(double xb, double Ts) {
  const auto p = PlatformParameters::defaults();
  return {discretize_zoh(platform_model(p, xb), Ts), discrete_pi_controller(default_pi_gains(p), Ts)};
}

ExcitationOptions short_options(double Ts, double duration_s, int excited_input) {
  ExcitationOptions o;
  o.sample_period_s = Ts;
  o.duration_s = duration_s;
  o.excited_input = excited_input;
  o.seed = kSimSeed;
  return o;
}

double column_std(const Eigen::MatrixXd& data, Index col) {
  const Eigen::VectorXd c = data.col(col);
  return std::sqrt((c.array() - c.mean()).square().sum() / static_cast<double>(c.size() - 1));
}

TEST(SimulateExcitation, SameSeedGivesBitIdenticalLogAndOtherSeedDiffers) {
  const Loop loop = paper_loop(kBeamRight_m, 1e-3);
  ExcitationOptions o = short_options(1e-3, 5.0, -1);
  const SimulatedLog a = simulate_excitation(loop.plant, loop.controller, o);
  const SimulatedLog b = simulate_excitation(loop.plant, loop.controller, o);
  ASSERT_EQ(a.data.rows(), 5000);
  EXPECT_TRUE((a.data.array() == b.data.array()).all());
  o.seed = kOtherSeed;
  const SimulatedLog c = simulate_excitation(loop.plant, loop.controller, o);
  EXPECT_FALSE((a.data.rightCols(9).array() == c.data.rightCols(9).array()).any());
}

TEST(SimulateExcitation, LogHasDocumentedColumnsAndTimeBase) {
  const Loop loop = paper_loop(kBeamMiddle_m, 1e-4);
  const SimulatedLog log = simulate_excitation(loop.plant, loop.controller, short_options(1e-4, 0.1, 2));
  EXPECT_EQ(log.names, (std::vector<std::string>{"t", "v1", "v2", "v3", "u1", "u2", "u3", "q1", "q2", "q3"}));
  ASSERT_EQ(log.data.rows(), 1000);
  ASSERT_EQ(log.data.cols(), 10);
  for (Index k = 0; k < log.data.rows(); ++k) EXPECT_EQ(log.data(k, 0), static_cast<double>(k) * 1e-4);
}

TEST(SimulateExcitation, OnlyTheChosenInputIsExcitedWithItsStd) {
  const Loop loop = paper_loop(kBeamLeft_m, 1e-3);
  const ExcitationOptions defaults;
  for (const int j : {0, 1, 2}) {
    const SimulatedLog log = simulate_excitation(loop.plant, loop.controller, short_options(1e-3, 20.0, j));
    for (int i = 0; i < 3; ++i) {
      if (i == j) {
        // 20000 samples: the sample std has relative std 1/sqrt(2N) = 0.5 %; 3 % is 6 sigma.
        EXPECT_NEAR(column_std(log.data, 1 + i) / defaults.excitation_std(i), 1.0, 0.03) << "input " << i;
      } else {
        EXPECT_EQ(log.data.col(1 + i).cwiseAbs().maxCoeff(), 0.0) << "input " << i << " excited " << j;
      }
    }
  }
  // All three at once: independent sequences (|sample correlation| ~ 1/sqrt(N) = 0.7 %; 5 % is 7 sigma).
  const SimulatedLog all = simulate_excitation(loop.plant, loop.controller, short_options(1e-3, 20.0, -1));
  const Eigen::MatrixXd v = all.data.middleCols(1, 3);
  const Eigen::MatrixXd centred = v.rowwise() - v.colwise().mean();
  const Eigen::Matrix3d cov = centred.transpose() * centred;
  for (int i = 0; i < 3; ++i)
    for (int k = i + 1; k < 3; ++k)
      EXPECT_LT(std::abs(cov(i, k)) / std::sqrt(cov(i, i) * cov(k, k)), 0.05) << i << "," << k;
}

TEST(SimulateExcitation, NoiseFreeLogEqualsConvolutionWithClosedLoopImpulseResponse) {
  for (const double Ts : {1e-3, 1e-4}) {
    const Loop loop = paper_loop(kBeamRight_m, Ts);
    constexpr Index kSamples = 400;
    ExcitationOptions o = short_options(Ts, static_cast<double>(kSamples) * Ts, -1);
    o.sensor_noise_std.setZero();
    const SimulatedLog log = simulate_excitation(loop.plant, loop.controller, o);
    ASSERT_EQ(log.data.rows(), kSamples);
    const Eigen::MatrixXd v = log.data.middleCols(1, 3);

    // Markov parameters of the closed loop v -> q (g_q) and v -> u (g_u), from the matrices.
    const auto cl = testing::close_loop(loop.plant, loop.controller);
    std::vector<Eigen::Matrix3d> g_q(kSamples), g_u(kSamples);
    Eigen::MatrixXd AkB = cl.B;
    g_q[0].setZero();
    g_u[0] = cl.Du;
    for (Index k = 1; k < kSamples; ++k) {
      g_q[static_cast<std::size_t>(k)] = cl.Cq * AkB;
      g_u[static_cast<std::size_t>(k)] = cl.Cu * AkB;
      AkB = cl.A * AkB;
    }
    double q_scale = 0.0, u_scale = 0.0, q_err = 0.0, u_err = 0.0;
    for (Index k = 0; k < kSamples; ++k) {
      Eigen::Vector3d q = Eigen::Vector3d::Zero(), u = Eigen::Vector3d::Zero();
      for (Index i = 0; i <= k; ++i) {
        q += g_q[static_cast<std::size_t>(i)] * v.row(k - i).transpose();
        u += g_u[static_cast<std::size_t>(i)] * v.row(k - i).transpose();
      }
      q_scale = std::max(q_scale, q.cwiseAbs().maxCoeff());
      u_scale = std::max(u_scale, u.cwiseAbs().maxCoeff());
      q_err = std::max(q_err, (log.data.block<1, 3>(k, 7).transpose() - q).cwiseAbs().maxCoeff());
      u_err = std::max(u_err, (log.data.block<1, 3>(k, 4).transpose() - u).cwiseAbs().maxCoeff());
    }
    // Two evaluation orders of the same sums of ~400 terms: rounding ~1e-13 relative.
    constexpr double kConvolutionRelTolerance = 1e-10;
    EXPECT_GT(q_scale, 0.0);
    EXPECT_LT(q_err, kConvolutionRelTolerance * q_scale) << "Ts = " << Ts;
    EXPECT_LT(u_err, kConvolutionRelTolerance * u_scale) << "Ts = " << Ts;
  }
}

TEST(SimulateExcitation, SensorNoiseEntersTheMeasurementWithItsStd) {
  const Loop loop = paper_loop(kBeamMiddle_m, 1e-3);
  ExcitationOptions o = short_options(1e-3, 20.0, 0);
  const SimulatedLog noisy = simulate_excitation(loop.plant, loop.controller, o);
  o.sensor_noise_std.setZero();
  const SimulatedLog clean = simulate_excitation(loop.plant, loop.controller, o);
  // Same seed: identical excitation, whatever the noise setting.
  EXPECT_TRUE((noisy.data.middleCols(1, 3).array() == clean.data.middleCols(1, 3).array()).all());
  // Δq = (I - T) n with T the complementary sensitivity; its bandwidth (~100 rad/s)
  // is a few % of the 3142 rad/s Nyquist band, so std(Δq) ≈ std(n).  10 % covers
  // the feedback share and the 0.5 % sampling spread.
  const Eigen::MatrixXd dq = noisy.data.rightCols(3) - clean.data.rightCols(3);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(column_std(dq, i) / ExcitationOptions().sensor_noise_std(i), 1.0, 0.10) << "output " << i;
}

TEST(SimulateExcitation, GeneralOrderLoopAgreesWithFixedSizeLoop) {
  const Loop loop = paper_loop(kBeamLeft_m, 1e-3);
  // The same controller with one extra decoupled, stable state (order 4): the
  // simulator takes its dynamic-size path, the output must not change.
  StateSpace big = loop.controller;
  big.A = Eigen::MatrixXd::Zero(4, 4);
  big.A.topLeftCorner(3, 3) = loop.controller.A;
  big.A(3, 3) = 0.5;
  big.B = Eigen::MatrixXd::Zero(4, 3);
  big.B.topRows(3) = loop.controller.B;
  big.B(3, 0) = 1.0;
  big.C = Eigen::MatrixXd::Zero(3, 4);
  big.C.leftCols(3) = loop.controller.C;
  const ExcitationOptions o = short_options(1e-3, 2.0, -1);
  const SimulatedLog fixed = simulate_excitation(loop.plant, loop.controller, o);
  const SimulatedLog dynamic = simulate_excitation(loop.plant, big, o);
  // Same arithmetic in a different summation order: rounding only.
  EXPECT_LT((fixed.data - dynamic.data).cwiseAbs().maxCoeff(), 1e-12 * fixed.data.cwiseAbs().maxCoeff());
}

TEST(SimulateExcitationErrors, OptionsNameTheBrokenRule) {
  ExcitationOptions o;
  o.excited_input = 3;
  EXPECT_EQ(error_text([&] { o.validate(); }),
            "excitation options: excited_input = 3; it must be 0, 1 or 2 (one plant input) or -1 (all three at once)");
  o = ExcitationOptions();
  o.excited_input = -1;
  o.excitation_std(1) = 0.0;
  EXPECT_EQ(error_text([&] { o.validate(); }),
            "excitation options: excitation_std[1] = 0 but input 1 is excited (excited_input = -1); give it a "
            "positive standard deviation");
  o = ExcitationOptions();
  o.duration_s = 1e-5;
  EXPECT_EQ(error_text([&] { o.validate(); }),
            "excitation options: duration_s = 1e-05 at sample_period_s = 0.001 gives 0 samples; it must give 1 to "
            "50000000 samples; check both units (seconds)");
  o = ExcitationOptions();
  o.sensor_noise_std(2) = -1e-7;
  EXPECT_EQ(error_text([&] { o.validate(); }),
            "excitation options: sensor_noise_std[2] = -1e-07; it must be finite and >= 0; give it in the output's "
            "units (rad, rad, m)");
}

TEST(SimulateExcitationErrors, ModelsMustBeDiscreteStrictlyProperAndAtTheSameRate) {
  const Loop loop = paper_loop(kBeamMiddle_m, 1e-3);
  const ExcitationOptions o = short_options(1e-3, 1.0, 0);
  const StateSpace continuous = platform_model(PlatformParameters::defaults(), 0.0);
  EXPECT_EQ(error_text([&] { simulate_excitation(continuous, loop.controller, o); }),
            "closed-loop simulation: the plant is continuous (ts = 0); discretise it at sample_period_s = 0.001 s "
            "first");
  const Loop fast = paper_loop(kBeamMiddle_m, 1e-4);
  EXPECT_EQ(error_text([&] { simulate_excitation(loop.plant, fast.controller, o); }),
            "closed-loop simulation: the controller has ts = 0.0001 s but sample_period_s = 0.001 s; discretise it at "
            "the experiment's sample period");
  StateSpace with_d = loop.plant;
  with_d.D(0, 0) = 0.25;
  EXPECT_EQ(error_text([&] { simulate_excitation(with_d, loop.controller, o); }),
            "closed-loop simulation: the plant's D is non-zero (largest |D| = 0.25); the loop needs a strictly proper "
            "plant (D = 0), as a ZOH-discretised mechanical model is");
  StateSpace two_out = loop.plant;
  two_out.C.conservativeResize(2, Eigen::NoChange);
  two_out.D.conservativeResize(2, Eigen::NoChange);
  two_out.output_names.clear();
  EXPECT_EQ(error_text([&] { simulate_excitation(two_out, loop.controller, o); }),
            "closed-loop simulation: the plant has 3 inputs and 2 outputs; it must have 3 and 3");
}

}  // namespace platform_sim_test
}  // namespace lpvid
