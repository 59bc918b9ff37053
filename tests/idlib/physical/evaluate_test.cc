#include "idlib/physical/evaluate.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>

#include "idlib/core/error.h"
#include "idlib/lti/discretize.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/physical/mechanical/mechanical_base.h"
#include "idlib/physical/platform/platform_base.h"
#include "idlib/plants/platform/platform.h"
#include "tests/support/two_mass_axis.h"

namespace lpvid {
namespace evaluate_test {

// Responses computed two ways in double precision from the same matrices:
// round-off only (condition of jωI - A at the lowest frequency is ~1e4).
constexpr double kRoundOff = 1e-10;
// Two different ZOH matrix exponentials (Eigen's Padé vs our Taylor): both
// accurate to ~1e-15 relative in e^{A Ts}; the response near the rigid-body
// poles amplifies that by the resolvent's condition (~1e3 at 1 kHz).
constexpr double kTwoExponentials = 1e-9;

const Eigen::VectorXd& grid() {
  static const Eigen::VectorXd w = log_frequency_grid(1.0, 2500.0, 60);
  return w;
}

// The physical model with the physics of PlatformParameters::defaults() (rod
// twist, J_psitheta, beam gravity): what the simulator's platform_model computes.
PhysicalModel lpvid_defaults() { return platform_defaults_model(); }

double max_rel_diff(const std::vector<Eigen::MatrixXcd>& a, const std::vector<Eigen::MatrixXcd>& b) {
  double worst = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k)
    worst = std::max(worst, (a[k] - b[k]).norm() / b[k].norm());
  return worst;
}

TEST(PhysicalEvaluate, DefaultModelEqualsPlatformModelAtEveryPaperPosition) {
  const PhysicalModel m = lpvid_defaults();
  for (double xb : kPaperBeamPositions_m) {
    const StateSpace truth = platform_model(PlatformParameters::defaults(), xb);
    EXPECT_LT(max_rel_diff(physical_response(m, xb, grid()), evaluate_response(truth, grid())), kRoundOff) << xb;
    const PhysicalStateSpace ss = physical_state_space(m, xb);
    EXPECT_EQ(ss.system.order(), 6);
    EXPECT_EQ(ss.input_delay_s, std::vector<double>(3, 0.0));
  }
}

TEST(PhysicalEvaluate, BareModelEqualsPlatformWithoutTheSwitchableTerms) {
  PlatformParameters p = PlatformParameters::defaults();
  p.k_torque_high_Nm_per_rad = 0.0;
  p.J_psitheta_kgm2 = 0.0;
  p.gravity_m_per_s2 = 0.0;
  const StateSpace truth = platform_model(p, 0.05);
  EXPECT_LT(max_rel_diff(physical_response(PhysicalModel::bare("platform"), 0.05, grid()),
                         evaluate_response(truth, grid())),
            kRoundOff);
}

TEST(PhysicalEvaluate, BendingScalesAndCouplingAndStiffnessCentreEnterKAsDocumented) {
  PhysicalModel m = PhysicalModel::bare("platform");
  m.add_effect("com_offset");
  m.parameter("bending_scale_psi").value = 1.4;
  m.parameter("bending_scale_theta").value = 0.7;
  m.parameter("bending_coupling").value = 0.2;
  m.parameter("stiffness_centre_x_m").value = 0.01;
  m.parameter("stiffness_centre_y_m").value = -0.02;
  const PlatformIndices L(m);
  const Eigen::VectorXd p = m.values();
  double M[3][3], D[3][3], K[3][3];
  platform_matrices<double>(L, p.data(), 0.0, M, D, K);
  const double kb = 1.5 * p(m.index_of("k_torque_low_Nm_per_rad"));  // three rods 120° apart
  const double kl = p(m.index_of("k_linear_N_per_m"));
  Eigen::Matrix3d expected;
  // K = diag-scaled bending + coupling·kb + k_linear a aᵀ, a = (e_y, e_x, 1)
  const Eigen::Vector3d a(-0.02, 0.01, 1.0);
  expected << 1.4 * kb, 0.2 * kb, 0, 0.2 * kb, 0.7 * kb, 0, 0, 0, 0;
  expected += kl * a * a.transpose();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(K[i][j], expected(i, j), 1e-9 * kl) << i << j;
}

TEST(PhysicalEvaluate, ComOffsetEntersTheMassMatrixAsPlatformModelDoes) {
  PhysicalModel m = lpvid_defaults();
  m.parameter("com_x_m").value = 0.01;
  m.parameter("com_y_m").value = -0.008;
  PlatformParameters p = PlatformParameters::defaults();
  p.com_x_m = 0.01;
  p.com_y_m = -0.008;
  EXPECT_LT(max_rel_diff(physical_response(m, -0.1, grid()), evaluate_response(platform_model(p, -0.1), grid())),
            kRoundOff);
}

TEST(PhysicalEvaluate, ZohResponseMatchesLtiDiscretizeAndFrequencyResponse) {
  const PhysicalModel m = lpvid_defaults();
  const double ts = 1e-3;
  const StateSpace d = discretize_zoh(platform_model(PlatformParameters::defaults(), 0.1), ts);
  EXPECT_LT(max_rel_diff(physical_response(m, 0.1, grid(), ts), evaluate_response(d, grid())), kTwoExponentials);
  const PhysicalStateSpace ss = physical_state_space(m, 0.1, ts);
  EXPECT_LT(max_rel_diff(evaluate_response(ss.system, grid()), evaluate_response(d, grid())), kTwoExponentials);
}

// Continuous time: e^{-jω tau} exactly; sampled: exactly z^-k for a whole number
// of samples (fractional delays: FractionalDelayStateSpaceEqualsTheSampledResponse
// and tests/idlib/physical/independent_plant_test.cc).
TEST(PhysicalEvaluate, InputDelayIsPhaseMinusOmegaTauExactlyInContinuousTimeAndForWholeSamples) {
  const PhysicalModel base = lpvid_defaults();
  for (const auto& [ts, tau] : {std::pair{0.0, 1.7e-3}, std::pair{1e-3, 2e-3}}) {
    PhysicalModel m = base;
    m.add_effect("input_delay");
    m.parameter("input_delay_s").value = tau;
    const auto a = physical_response(m, 0.0, grid(), ts);
    const auto b = physical_response(base, 0.0, grid(), ts);
    for (std::size_t k = 0; k < a.size(); ++k) {
      const double w = grid()(static_cast<Index>(k));
      EXPECT_LT((a[k] - b[k] * std::exp(Complex(0, -w * tau))).norm() / b[k].norm(), kRoundOff);
    }
  }
}

TEST(PhysicalEvaluate, DiscreteDelayStatesRealiseWholeSampleDelays) {
  PhysicalModel m = lpvid_defaults();
  m.add_effect("input_delay");
  const double ts = 1e-3;
  m.parameter("input_delay_s").value = 2 * ts;
  const PhysicalStateSpace ss = physical_state_space(m, 0.0, ts);
  EXPECT_EQ(ss.delay_samples, 2);
  EXPECT_EQ(ss.system.order(), 6 + 2 * 3);
  EXPECT_LT(max_rel_diff(evaluate_response(ss.system, grid()), physical_response(m, 0.0, grid(), ts)), kTwoExponentials);
}

TEST(PhysicalEvaluate, ActuatorLagAddsPolesAtMinusOneOverTauAndItsFactor) {
  const PhysicalModel base = lpvid_defaults();
  PhysicalModel m = base;
  m.add_effect("actuator_lag");
  const double tau = 2e-3;
  m.parameter("actuator_time_constant_s").value = tau;
  const PhysicalStateSpace ss = physical_state_space(m, 0.0);
  ASSERT_EQ(ss.system.order(), 9);
  const Eigen::VectorXcd poles = ss.system.A.eigenvalues();
  int at_lag = 0;
  // Eigenvalues of a triangular block: exact up to round-off of 1/tau = 500.
  for (Index i = 0; i < poles.size(); ++i) at_lag += std::abs(poles(i) - Complex(-1.0 / tau, 0.0)) < 1e-9 * 500 ? 1 : 0;
  EXPECT_EQ(at_lag, 3);
  const auto a = physical_response(m, 0.0, grid());
  const auto b = physical_response(base, 0.0, grid());
  for (std::size_t k = 0; k < a.size(); ++k) {
    const double w = grid()(static_cast<Index>(k));
    EXPECT_LT((a[k] - b[k] / Complex(1.0, w * tau)).norm() / b[k].norm(), kRoundOff);
  }
}

TEST(PhysicalEvaluate, GainErrorScalesTheInputColumns) {
  const PhysicalModel base = lpvid_defaults();
  PhysicalModel m = base;
  m.add_effect("gain_error");
  m.parameter("gain_z").value = 1.5;
  m.parameter("gain_psi").value = 0.9;
  const auto a = physical_response(m, 0.1, grid());
  const auto b = physical_response(base, 0.1, grid());
  const Eigen::Vector3d g(0.9, 1.0, 1.5);
  for (std::size_t k = 0; k < a.size(); ++k)
    EXPECT_LT((a[k] - b[k] * g.cast<Complex>().asDiagonal()).norm() / b[k].norm(), kRoundOff);
}

TEST(PhysicalEvaluate, StructuralModeAddsItsCollocatedSecondOrderTerm) {
  const PhysicalModel base = lpvid_defaults();
  PhysicalModel m = base;
  m.add_effect("structural_mode");
  const double wm = 800.0, zeta = 0.03;
  m.parameter("mode_frequency_rad_s").value = wm;
  m.parameter("mode_damping").value = zeta;
  const Eigen::Vector3d phi(1.0, 1.0, 0.3);  // library defaults
  const auto a = physical_response(m, 0.0, grid());
  const auto b = physical_response(base, 0.0, grid());
  for (std::size_t k = 0; k < a.size(); ++k) {
    const double w = grid()(static_cast<Index>(k));
    const Complex den(wm * wm - w * w, 2 * zeta * wm * w);
    const Eigen::MatrixXcd expected = b[k] + (phi * phi.transpose()).cast<Complex>() / den;
    EXPECT_LT((a[k] - expected).norm() / expected.norm(), kRoundOff);
  }
}

TEST(PhysicalEvaluate, RodTwistAndGravityChangeOnlyTheTiltStiffness) {
  const PhysicalModel bare = PhysicalModel::bare("platform");
  PhysicalModel m = bare;
  m.add_effect("rod_twist");
  m.add_effect("beam_gravity");
  m.parameter("twist_stiffness_theta_Nm_per_rad").value = 450.0;  // differently on psi and theta
  Eigen::MatrixXd A0, B0, C0, D0, A1, B1, C1, D1;
  const ModelLayout l0(bare), l1(m);
  ASSERT_TRUE(build_continuous<double>(l0, bare.values().data(), 0.0, A0, B0, C0, D0));
  ASSERT_TRUE(build_continuous<double>(l1, m.values().data(), 0.0, A1, B1, C1, D1));
  const PlatformParameters d = PlatformParameters::defaults();
  const double grav = d.beam_height_m * d.beam_mass_kg * d.gravity_m_per_s2;
  const Eigen::Matrix3d M = mass_matrix(platform_parameters(bare), 0.0);
  Eigen::Matrix3d dK = Eigen::Matrix3d::Zero();
  dK(0, 0) = 300.0 - grav;
  dK(1, 1) = 450.0 - grav;
  EXPECT_LT((A1.block(3, 0, 3, 3) - A0.block(3, 0, 3, 3) + M.inverse() * dK).norm(), kRoundOff * A0.norm());
  EXPECT_EQ(B1, B0);
}

// User-defined building blocks act exactly as their transfer functions say.
TEST(PhysicalEvaluate, UserDefinedBlocksMultiplyTheirChannelByTheirTransferFunction) {
  const PhysicalModel base = lpvid_defaults();
  PhysicalModel m = base;
  EffectInfo e;
  e.name = "blocks";
  e.parameters = {{"lag_s", "s", 2e-3, 1e-6, 1, true},        {"wp", "rad/s", 700, 1, 1e4, true},
                  {"zp", "1", 0.05, 1e-4, 1, true},           {"wz", "rad/s", 900, 1, 1e4, true},
                  {"zz", "1", 0.2, 1e-4, 1, true},            {"c_psi_z", "m/rad", 0.03, -1, 1, true},
                  {"tau_z", "s", 1.3e-3, 0, 0.1, true}};
  e.blocks = {{BlockKind::kFirstOrder, BlockSide::kOutput, {"z"}, {"lag_s"}},
              {BlockKind::kResonance, BlockSide::kOutput, {"theta"}, {"wp", "zp", "wz", "zz"}},
              {BlockKind::kCoupling, BlockSide::kOutput, {"psi", "z"}, {"c_psi_z"}},
              {BlockKind::kDelay, BlockSide::kInput, {"F_z"}, {"tau_z"}}};
  m.define_effect(e);
  m.add_effect("blocks");
  const auto a = physical_response(m, 0.05, grid());
  const auto b = physical_response(base, 0.05, grid());
  for (std::size_t k = 0; k < a.size(); ++k) {
    const double w = grid()(static_cast<Index>(k));
    const Complex s(0, w);
    Eigen::MatrixXcd expected = b[k];
    expected.col(2) *= std::exp(-s * 1.3e-3);                                              // delay on F_z
    expected.row(1) *= (700.0 * 700.0 / (900.0 * 900.0)) * (s * s + 2 * 0.2 * 900.0 * s + 900.0 * 900.0) /
                       (s * s + 2 * 0.05 * 700.0 * s + 700.0 * 700.0);                     // theta resonance
    // output blocks act in the order listed: the lag on z, then z += 0.03 psi
    expected.row(2) = expected.row(2) / (1.0 + s * 2e-3) + 0.03 * expected.row(0);
    EXPECT_LT((a[k] - expected).norm() / expected.norm(), kRoundOff) << w;
  }
}

// The sampled response with a fractional delay equals the state space that
// simulates it (registers and b_old), and differs from e^{-jω tau} times the
// plain ZOH (which is exact only for whole samples).
TEST(PhysicalEvaluate, FractionalDelayStateSpaceEqualsTheSampledResponse) {
  PhysicalModel m = lpvid_defaults();
  m.add_effect("input_delay");
  const double ts = 1e-3, tau = 1.4e-3;
  m.parameter("input_delay_s").value = tau;
  const PhysicalStateSpace ss = physical_state_space(m, 0.0, ts);
  EXPECT_EQ(ss.delay_samples, 1);
  EXPECT_EQ(ss.system.order(), 6 + 2 * 3);  // registers u[k-1], u[k-2]
  EXPECT_LT(max_rel_diff(evaluate_response(ss.system, grid()), physical_response(m, 0.0, grid(), ts)),
            kTwoExponentials);
  // The factor form e^{-jω tau} × ZOH is not the sampled system: its error grows
  // with ω (measured 3.2e-4 at 400 rad/s and 9.1e-3 at 1000 rad/s for 0.4 of a
  // sample at 1 kHz), far above round-off (1e-10) and, above ~500 rad/s, above an
  // analyzer's noise.
  const Eigen::VectorXd w2 = (Eigen::VectorXd(2) << 400.0, 1000.0).finished();
  const auto e = physical_response(m, 0.0, w2, ts);
  const auto p = physical_response(lpvid_defaults(), 0.0, w2, ts);
  double rel[2];
  for (int k = 0; k < 2; ++k) rel[k] = (e[k] - p[k] * std::exp(Complex(0, -w2(k) * tau))).norm() / e[k].norm();
  std::printf("factor form vs exact fractional delay: %.2e at 400 rad/s, %.2e at 1000 rad/s\n", rel[0], rel[1]);
  EXPECT_GT(rel[0], 1e-4);
  EXPECT_GT(rel[1], 1e-3);
}

TEST(PhysicalEvaluate, BeamOutsideTheStrokeIsInputError) {
  EXPECT_THROW(physical_response(lpvid_defaults(), 0.3, grid()), InputError);
  EXPECT_THROW(physical_state_space(lpvid_defaults(), 0.0, -1.0), InputError);
}

// The framework knows no base by name (docs/architecture.md): each base's BaseInfo
// carries the check of its own operating point, which check_schedule calls.
TEST(PhysicalEvaluate, EachBaseChecksItsOwnOperatingPoint) {
  const auto message = [](const PhysicalModel& m, double s) {
    try {
      check_schedule(m, s);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const PhysicalModel platform = PhysicalModel::bare("platform"), stage = PhysicalModel::bare("stage6");
  EXPECT_EQ(message(platform, 0.1), "");
  EXPECT_NE(message(platform, 0.2).find("outside the stroke |x_b| <= beam_stroke_m = 0.15 m"), std::string::npos);
  EXPECT_EQ(message(stage, 5e-4), "");
  EXPECT_NE(message(stage, 0.01).find("hover height z_0 = 0.01 m"), std::string::npos);
  // a user's base without a scheduling variable: none needed, and any finite value passes
  const PhysicalModel axis = PhysicalModel::bare(make_mechanical_base(two_mass_axis::axis()));
  ASSERT_TRUE(axis.base_info().schedule_name.empty());
  EXPECT_EQ(message(axis, std::nan("")), "");
  EXPECT_EQ(message(axis, 3.0), "");
  EXPECT_NE(message(axis, INFINITY).find("is not finite"), std::string::npos);
  // and each compiles its own indices into the layout
  EXPECT_TRUE(ModelLayout(platform).platform.has_value());
  EXPECT_TRUE(ModelLayout(stage).stage6.has_value());
  EXPECT_TRUE(ModelLayout(axis).mechanical.has_value());
  EXPECT_FALSE(ModelLayout(axis).platform.has_value());
}

}  // namespace evaluate_test
}  // namespace lpvid
