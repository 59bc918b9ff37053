#include "idlib/physical/evaluate.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>

#include "idlib/core/error.h"
#include "idlib/lti/discretize.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/models/platform.h"

namespace lpvid {
namespace {

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

double max_rel_diff(const std::vector<Eigen::MatrixXcd>& a, const std::vector<Eigen::MatrixXcd>& b) {
  double worst = 0.0;
  for (std::size_t k = 0; k < a.size(); ++k)
    worst = std::max(worst, (a[k] - b[k]).norm() / b[k].norm());
  return worst;
}

TEST(PhysicalEvaluate, DefaultModelEqualsPlatformModelAtEveryPaperPosition) {
  const PhysicalModel m = PhysicalModel::default_platform();
  for (double xb : kPaperBeamPositions_m) {
    const StateSpace truth = platform_model(PlatformParameters::defaults(), xb);
    EXPECT_LT(max_rel_diff(physical_response(m, xb, grid()), evaluate_response(truth, grid())), kRoundOff) << xb;
    const PhysicalStateSpace ss = physical_state_space(m, xb);
    EXPECT_EQ(ss.system.order(), 6);
    EXPECT_EQ(ss.input_delay_s, 0.0);
  }
}

TEST(PhysicalEvaluate, BareModelEqualsPlatformWithoutTheSwitchableTerms) {
  PlatformParameters p = PlatformParameters::defaults();
  p.k_torque_high_Nm_per_rad = 0.0;
  p.J_psitheta_kgm2 = 0.0;
  p.gravity_m_per_s2 = 0.0;
  const StateSpace truth = platform_model(p, 0.05);
  EXPECT_LT(max_rel_diff(physical_response(PhysicalModel::bare_platform(), 0.05, grid()), evaluate_response(truth, grid())),
            kRoundOff);
}

TEST(PhysicalEvaluate, ComOffsetEntersTheMassMatrixAsPlatformModelDoes) {
  PhysicalModel m = PhysicalModel::default_platform();
  m.parameter("com_x_m").value = 0.01;
  m.parameter("com_y_m").value = -0.008;
  PlatformParameters p = PlatformParameters::defaults();
  p.com_x_m = 0.01;
  p.com_y_m = -0.008;
  EXPECT_LT(max_rel_diff(physical_response(m, -0.1, grid()), evaluate_response(platform_model(p, -0.1), grid())),
            kRoundOff);
}

TEST(PhysicalEvaluate, ZohResponseMatchesLtiDiscretizeAndFrequencyResponse) {
  const PhysicalModel m = PhysicalModel::default_platform();
  const double ts = 1e-3;
  const StateSpace d = discretize_zoh(platform_model(PlatformParameters::defaults(), 0.1), ts);
  EXPECT_LT(max_rel_diff(physical_response(m, 0.1, grid(), ts), evaluate_response(d, grid())), kTwoExponentials);
  const PhysicalStateSpace ss = physical_state_space(m, 0.1, ts);
  EXPECT_LT(max_rel_diff(evaluate_response(ss.system, grid()), evaluate_response(d, grid())), kTwoExponentials);
}

TEST(PhysicalEvaluate, InputDelayIsPhaseMinusOmegaTauExactly) {
  const PhysicalModel base = PhysicalModel::default_platform();
  PhysicalModel m = base;
  m.add_effect("input_delay");
  const double tau = 1.7e-3;
  m.parameter("input_delay_s").value = tau;
  for (double ts : {0.0, 1e-3}) {
    const auto a = physical_response(m, 0.0, grid(), ts);
    const auto b = physical_response(base, 0.0, grid(), ts);
    for (std::size_t k = 0; k < a.size(); ++k) {
      const double w = grid()(static_cast<Index>(k));
      EXPECT_LT((a[k] - b[k] * std::exp(Complex(0, -w * tau))).norm() / b[k].norm(), kRoundOff);
    }
  }
}

TEST(PhysicalEvaluate, DiscreteDelayStatesRealiseWholeSampleDelays) {
  PhysicalModel m = PhysicalModel::default_platform();
  m.add_effect("input_delay");
  const double ts = 1e-3;
  m.parameter("input_delay_s").value = 2 * ts;
  const PhysicalStateSpace ss = physical_state_space(m, 0.0, ts);
  EXPECT_EQ(ss.delay_samples, 2);
  EXPECT_EQ(ss.system.order(), 6 + 2 * 3);
  EXPECT_LT(max_rel_diff(evaluate_response(ss.system, grid()), physical_response(m, 0.0, grid(), ts)), kTwoExponentials);
}

TEST(PhysicalEvaluate, ActuatorLagAddsPolesAtMinusOneOverTauAndItsFactor) {
  const PhysicalModel base = PhysicalModel::default_platform();
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
  const PhysicalModel base = PhysicalModel::default_platform();
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
  const PhysicalModel base = PhysicalModel::default_platform();
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
  PhysicalModel m = PhysicalModel::bare_platform();
  m.add_effect("rod_twist");
  m.add_effect("beam_gravity");
  Eigen::MatrixXd A0, B0, C0, D0, A1, B1, C1, D1;
  const ModelLayout l0(PhysicalModel::bare_platform()), l1(m);
  ASSERT_TRUE(build_continuous<double>(l0, PhysicalModel::bare_platform().values().data(), 0.0, A0, B0, C0, D0));
  ASSERT_TRUE(build_continuous<double>(l1, m.values().data(), 0.0, A1, B1, C1, D1));
  const PlatformParameters d = PlatformParameters::defaults();
  // Three rods 120° apart: K_tilt += 1.5·k_high·I; gravity −z_b m_b g on both tilts.
  const double dk = 1.5 * d.k_torque_high_Nm_per_rad - d.beam_height_m * d.beam_mass_kg * d.gravity_m_per_s2;
  const Eigen::Matrix3d M = mass_matrix(to_platform_parameters(PhysicalModel::bare_platform()), 0.0);
  Eigen::Matrix3d dK = Eigen::Matrix3d::Zero();
  dK(0, 0) = dK(1, 1) = dk;
  EXPECT_LT((A1.block(3, 0, 3, 3) - A0.block(3, 0, 3, 3) + M.inverse() * dK).norm(), kRoundOff * A0.norm());
  EXPECT_EQ(B1, B0);
}

TEST(PhysicalEvaluate, BeamOutsideTheStrokeIsInputError) {
  EXPECT_THROW(physical_response(PhysicalModel::default_platform(), 0.3, grid()), InputError);
  EXPECT_THROW(physical_state_space(PhysicalModel::default_platform(), 0.0, -1.0), InputError);
}

}  // namespace
}  // namespace lpvid
