// The user-described base "mechanical" (idlib/physical/mechanical/mechanical_base.h)
// against an independent oracle (tests/support/two_mass_axis.h: the response solved
// directly in the frequency domain by Cramer's rule, where the library assembles a
// state space and evaluates C (jwI − A)⁻¹ B).
#include "idlib/physical/mechanical/mechanical_base.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <complex>

#include "idlib/core/error.h"
#include "idlib/physical/evaluate.h"
#include "tests/support/two_mass_axis.h"

namespace lpvid {
namespace mechanical_base_test {

using ::testing::HasSubstr;

using two_mass_axis::AxisValues;
using two_mass_axis::axis;
using two_mass_axis::ex;
using two_mass_axis::oracle;
using two_mass_axis::par;
using two_mass_axis::values_of;

TEST(MechanicalBase, ResponseEqualsTheDirectFrequencyDomainSolution) {
  const PhysicalModel m = PhysicalModel::bare(make_mechanical_base(axis()));
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(40, 1.0, 3000.0);
  const auto P = physical_response(m, 0.0, w, 0.0);
  const AxisValues v = values_of(m);
  for (Index k = 0; k < w.size(); ++k) {
    ASSERT_EQ(P[static_cast<std::size_t>(k)].rows(), 2);
    ASSERT_EQ(P[static_cast<std::size_t>(k)].cols(), 1);
    const Eigen::Vector2cd want = oracle(v, w(k));
    // 1e-9 relative: both are exact solutions of the same linear equations in double
    // precision; the state-space route loses a few digits in the inverse of M.
    EXPECT_LT((P[static_cast<std::size_t>(k)].col(0) - want).norm(), 1e-9 * want.norm()) << w(k);
  }
}

TEST(MechanicalBase, ModeAndDelayEffectsApplyUnchanged) {
  PhysicalModel m = PhysicalModel::bare(make_mechanical_base(axis()));
  m.add_effect("structural_mode");
  m.add_effect("input_delay");
  m.parameter("mode_frequency_rad_s").value = 1500.0;
  m.parameter("mode_damping").value = 0.03;
  m.parameter("mode_shape_x_m").value = 0.2;
  m.parameter("mode_shape_x_l").value = -0.1;
  m.parameter("input_delay_s").value = 2e-4;
  // the mode's shape units follow the DOFs' (m here), not the outputs'
  EXPECT_EQ(m.parameter("mode_shape_x_m").unit, "1/kg^0.5");
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(30, 10.0, 4000.0);
  const auto P = physical_response(m, 0.0, w, 0.0);
  const AxisValues v = values_of(m);
  for (Index k = 0; k < w.size(); ++k) {
    const Eigen::Vector2cd want = oracle(v, w(k), 0.2, -0.1, 1500.0, 0.03, 2e-4);
    EXPECT_LT((P[static_cast<std::size_t>(k)].col(0) - want).norm(), 1e-9 * want.norm()) << w(k);
  }
}

TEST(MechanicalBase, VelocityAndAccelerationSensorsAreJwAndMinusW2TimesPosition) {
  MechanicalDescription d = axis();
  d.outputs[0].derivative = 1;  // a velocity sensor on the carriage
  d.outputs[1].derivative = 2;  // an accelerometer on the load (direct feedthrough)
  PhysicalModel m = PhysicalModel::bare(make_mechanical_base(d));
  m.add_effect("structural_mode");
  m.parameter("mode_frequency_rad_s").value = 1500.0;
  m.parameter("mode_damping").value = 0.03;
  m.parameter("mode_shape_x_m").value = 0.2;
  m.parameter("mode_shape_x_l").value = -0.1;
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(30, 10.0, 4000.0);
  const auto P = physical_response(m, 0.0, w, 0.0);
  const AxisValues v = values_of(m);
  for (Index k = 0; k < w.size(); ++k) {
    const Eigen::Vector2cd q = oracle(v, w(k), 0.2, -0.1, 1500.0, 0.03);
    const std::complex<double> vel = std::complex<double>(0.0, w(k)) * q(0), acc = -w(k) * w(k) * q(1);
    const Eigen::MatrixXcd& p = P[static_cast<std::size_t>(k)];
    EXPECT_LT(std::abs(p(0, 0) - vel), 1e-9 * std::abs(vel)) << w(k);
    EXPECT_LT(std::abs(p(1, 0) - acc), 1e-9 * std::abs(acc)) << w(k);
  }
  // an accelerometer sees the force at once: the state space has a feedthrough
  const PhysicalStateSpace ss = physical_state_space(m, 0.0, 0.0);
  EXPECT_NE(ss.system.D(1, 0), 0.0);
  EXPECT_EQ(ss.system.D(0, 0), 0.0);
}

TEST(MechanicalBase, SampledResponseApproachesTheContinuousOneWellBelowNyquist) {
  const PhysicalModel m = PhysicalModel::bare(make_mechanical_base(axis()));
  const PhysicalStateSpace ss = physical_state_space(m, 0.0, 1e-4);
  EXPECT_EQ(ss.system.order(), 4);
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(5, 5.0, 50.0);
  const auto Pd = physical_response(m, 0.0, w, 1e-4);
  const AxisValues v = values_of(m);
  for (Index k = 0; k < w.size(); ++k) {
    const Eigen::Vector2cd want = oracle(v, w(k));
    // ZOH: the sampled response is the continuous one times e^{-jwT/2} to first
    // order, |1 − e^{-jwT/2}| <= wT/2 = 2.5e-3 at 50 rad/s, 10 kHz
    EXPECT_LT((Pd[static_cast<std::size_t>(k)].col(0) - want).norm(), 3e-3 * want.norm()) << w(k);
  }
}

TEST(MechanicalBase, LinearExpressionsParseAndPrintBack) {
  const LinearExpression e = parse_linear_expression(" 2.5e-1*a_b - c + 3 + d*2 ");
  ASSERT_EQ(e.size(), 4u);
  EXPECT_DOUBLE_EQ(e[0].coefficient, 0.25);
  EXPECT_EQ(e[0].parameter, "a_b");
  EXPECT_DOUBLE_EQ(e[1].coefficient, -1.0);
  EXPECT_EQ(e[2].parameter, "");
  EXPECT_DOUBLE_EQ(e[2].coefficient, 3.0);
  EXPECT_DOUBLE_EQ(e[3].coefficient, 2.0);
  const LinearExpression back = parse_linear_expression(linear_expression_text(e));
  ASSERT_EQ(back.size(), e.size());
  for (std::size_t k = 0; k < e.size(); ++k) {
    EXPECT_EQ(back[k].coefficient, e[k].coefficient);
    EXPECT_EQ(back[k].parameter, e[k].parameter);
  }
  EXPECT_THAT([] { parse_linear_expression("m*k"); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("not linear")));
  EXPECT_THAT([] { parse_linear_expression("m k"); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("at character 3")));
  EXPECT_THAT([] { parse_linear_expression(""); }, ::testing::ThrowsMessage<InputError>(HasSubstr("empty")));
  EXPECT_THAT([] { parse_linear_expression("2*"); }, ::testing::ThrowsMessage<InputError>(HasSubstr("'*'")));
}

TEST(MechanicalBase, BadDescriptionsAreRefusedWithWhatToDo) {
  auto refused = [](const MechanicalDescription& d, const std::string& what) {
    EXPECT_THAT([&] { make_mechanical_base(d); }, ::testing::ThrowsMessage<InputError>(HasSubstr(what))) << what;
  };
  MechanicalDescription d = axis();
  d.mass[0][1] = ex("0.1*m_load_kg");
  refused(d, "not symmetric");
  d = axis();
  d.mass[0][0] = ex("m_carriage_kg - m_load_kg");
  refused(d, "not positive definite");
  d = axis();
  d.stiffness[0][0] = ex("k_spring");
  refused(d, "'k_spring', which is not a declared parameter");
  d = axis();
  d.parameters.push_back(par("unused_kg", "kg", 1.0, 0.0, 2.0, false));
  refused(d, "no matrix uses it");
  d = axis();
  d.input_map = {{ex("k_f_N_per_A")}};
  refused(d, "\"input_map\" has 1 rows; it must be 2×1");
  d = axis();
  d.outputs.push_back({"enc", "m"});
  refused(d, "named twice");
  d = axis();
  d.dofs.clear();
  refused(d, "0 DOFs");
  // a library base named without its description
  EXPECT_THAT([] { PhysicalModel::bare(std::string("mechanical")); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("--from DESCRIPTION.json")));
}

}  // namespace mechanical_base_test
}  // namespace lpvid
