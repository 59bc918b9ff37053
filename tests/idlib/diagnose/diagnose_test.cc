// diagnose on plant FRDs with a hidden effect: for every effect of the library,
// data simulated from a truth that has the effect (its parameters drawn from the
// documented ranges below, three seeds each) and a start model without it; and
// on data with nothing hidden.  The FRD noise model is that of an H1 estimate:
// complex circular Gaussian error with standard deviation
//   σ_ij = ε · s_ij,  s_ij = sqrt(|P_ii| |P_jj|)
// per real part (the noise of column j comes from the output noise over the
// excitation of input j, so off-diagonal channels carry noise at the scale of the
// diagonal ones, not of their own small size), and the coherence that an H1
// estimate with n_d averages would report for it,
//   γ² = |P̂|² / (|P̂|² + 2 n_d σ²)   ⇔   σ = |P̂| sqrt((1 − γ²) / (2 n_d γ²))
// (idlib/validate/model_error.h), so that significance uses the true noise level.
#include "idlib/diagnose/diagnose.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <random>

#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/models/platform.h"
#include "idlib/physical/evaluate.h"

namespace lpvid {
namespace {

constexpr double kSamplePeriod = 1e-3;  // plant FRDs from 1 kHz experiments (ZOH model)
constexpr double kNoise = 0.01;         // ε: 1 % relative noise per real part (issue 3's "about 1 %")
constexpr double kAverages = 16;        // n_d of the H1 estimate (ModelErrorOptions default)

const Eigen::VectorXd& grid() {
  // 2–2500 rad/s: the rigid-body band and the paper's peaks above 400 rad/s,
  // below Nyquist (3142 rad/s at 1 kHz).
  static const Eigen::VectorXd w = log_frequency_grid(2.0, 2500.0, 120);
  return w;
}

std::vector<FitDataset> noisy_data(const PhysicalModel& truth, const FitOptions& o, std::uint64_t seed,
                                   double noise = kNoise) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01;
  std::vector<FitDataset> out;
  for (double xb : kPaperBeamPositions_m) {
    FrequencyResponse r = target_response(truth, xb, grid(), o);
    r.coherence.resize(r.response.size());
    for (std::size_t k = 0; k < r.response.size(); ++k) {
      Eigen::MatrixXcd& P = r.response[k];
      const Eigen::MatrixXcd exact = P;
      Eigen::MatrixXd coh(3, 3);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          const double s = std::sqrt(std::abs(exact(i, i)) * std::abs(exact(j, j)));
          const double sigma = noise * s;
          P(i, j) += std::complex<double>(sigma * n01(rng), sigma * n01(rng));
          const double a2 = std::norm(P(i, j));
          coh(i, j) = a2 / (a2 + 2.0 * kAverages * sigma * sigma);
        }
      r.coherence[k] = coh;
    }
    out.push_back({xb, r, fmt::format("x_b={}", xb)});
  }
  return out;
}

DiagnoseOptions options() {
  DiagnoseOptions o;
  o.fit.sample_period_s = kSamplePeriod;
  o.model_error.averages = kAverages;
  return o;
}

double uniform(std::mt19937_64& rng, double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
double signed_uniform(std::mt19937_64& rng, double lo, double hi) {
  return (std::bernoulli_distribution(0.5)(rng) ? 1.0 : -1.0) * uniform(rng, lo, hi);
}

// The truth with `effect` and the start model without it.  Parameter ranges
// (documented in docs/effects.md, "Ranges used by the tests"):
struct Case {
  PhysicalModel truth, start;
};
Case hidden(const std::string& effect, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  PhysicalModel base = PhysicalModel::default_platform();  // rod_twist, com_offset, beam_gravity on
  base.parameter("com_x_m").value = 0.004;
  base.parameter("com_y_m").value = -0.003;
  Case c;
  if (effect == "structural_mode" || effect == "input_delay" || effect == "actuator_lag" || effect == "gain_error") {
    c.start = base;
    c.truth = base;
    c.truth.add_effect(effect);
    if (effect == "structural_mode") {
      c.truth.parameter("mode_frequency_rad_s").value = uniform(rng, 600.0, 1500.0);
      c.truth.parameter("mode_damping").value = uniform(rng, 0.01, 0.05);
      c.truth.parameter("mode_shape_psi").value = signed_uniform(rng, 1.0, 3.0);
      c.truth.parameter("mode_shape_theta").value = signed_uniform(rng, 1.0, 3.0);
      c.truth.parameter("mode_shape_z").value = signed_uniform(rng, 0.2, 0.6);
    } else if (effect == "input_delay") {
      c.truth.parameter("input_delay_s").value = uniform(rng, 3e-4, 1.5e-3);
    } else if (effect == "actuator_lag") {
      c.truth.parameter("actuator_time_constant_s").value = uniform(rng, 3e-4, 2e-3);
    } else {
      // One DOF with a gain error of 10–50 % (eq 9's printed z row is +50 %), the others ±3 %.
      const char* names[3] = {"gain_psi", "gain_theta", "gain_z"};
      const int pick = std::uniform_int_distribution<int>(0, 2)(rng);
      for (int j = 0; j < 3; ++j)
        c.truth.parameter(names[j]).value = j == pick ? 1.0 + signed_uniform(rng, 0.1, 0.5) : 1.0 + uniform(rng, -0.03, 0.03);
    }
  } else if (effect == "rod_twist") {
    c.truth = base;
    c.truth.parameter("k_torque_high_Nm_per_rad").value = uniform(rng, 100.0, 300.0);
    c.start = without_effect(c.truth, effect);
  } else if (effect == "com_offset") {
    c.truth = base;
    c.truth.parameter("com_x_m").value = signed_uniform(rng, 0.003, 0.01);
    c.truth.parameter("com_y_m").value = signed_uniform(rng, 0.003, 0.01);
    c.truth.parameter("J_psitheta_kgm2").value = signed_uniform(rng, 5e-4, 2e-3);
    c.start = without_effect(c.truth, effect);
  } else if (effect == "beam_gravity") {
    // The gravity stiffness -z_b m_b g equals a softer rod on both tilts, so it is
    // separable only when the rod stiffness is known: the start holds
    // k_torque_high fixed at its (true) design value.  A raised, heavy beam:
    // z_b 0.2–0.3 m, m_b 2–3 kg, i.e. 4–9 N·m/rad against ~345 N·m/rad of rods.
    c.truth = base;
    c.truth.parameter("beam_height_m").value = uniform(rng, 0.2, 0.3);
    c.truth.parameter("beam_mass_kg").value = uniform(rng, 2.0, 3.0);
    c.truth.parameter("k_torque_high_Nm_per_rad").free = false;
    c.start = without_effect(c.truth, effect);
  }
  // The start is the truth without the effect, its free values 20 % off.
  int k = 0;
  for (auto& p : c.start.parameters)
    if (p.free) p.value = std::clamp(p.value * (k++ % 2 == 0 ? 1.2 : 0.8), p.lower, p.upper);
  return c;
}

class HiddenEffect : public ::testing::TestWithParam<std::string> {};

TEST_P(HiddenEffect, DiagnoseNamesItFirstAndAddingItLowersTheErrorTenfoldOrToTheNoiseFloor) {
  const std::string effect = GetParam();
  for (std::uint64_t seed : {11u, 12u, 13u}) {
    SCOPED_TRACE(fmt::format("{} seed {}", effect, seed));
    const Case c = hidden(effect, seed);
    const DiagnoseOptions o = options();
    const auto data = noisy_data(c.truth, o.fit, 1000 + seed);
    const Diagnosis d = diagnose(c.start, data, o);
    ASSERT_FALSE(d.ranked.empty());
    std::string table;
    for (const auto& r : d.ranked) table += fmt::format("{} ΔBIC {:.1f} err {:.4g}; ", r.effect, r.delta_bic, r.error);
    EXPECT_EQ(d.ranked.front().effect, effect) << table;
    EXPECT_TRUE(d.explained) << table;
    // The noise floor: the error of the truth's own structure fitted to the same data.
    const double floor = fit_error(fit_physical_model(c.truth, data, o.fit));
    const double after = d.ranked.front().error;
    EXPECT_TRUE(after <= d.baseline_error / 10.0 || after <= 1.5 * floor)
        << "before " << d.baseline_error << " after " << after << " floor " << floor;
  }
}

INSTANTIATE_TEST_SUITE_P(Library, HiddenEffect,
                         ::testing::Values("structural_mode", "input_delay", "actuator_lag", "gain_error", "rod_twist",
                                           "com_offset", "beam_gravity"));

TEST(Diagnose, NothingHiddenReportsNothingSignificantInAtLeastNineOfTenSeeds) {
  int quiet = 0;
  std::string log;
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    PhysicalModel truth = PhysicalModel::default_platform();
    truth.parameter("com_x_m").value = 0.004;
    truth.parameter("com_y_m").value = -0.003;
    const DiagnoseOptions o = options();
    const Diagnosis d = diagnose(truth, noisy_data(truth, o.fit, 500 + seed), o);
    if (!d.explained) ++quiet;
    log += fmt::format("seed {}: best {} ΔBIC {:.1f}\n", seed, d.ranked.front().effect, d.ranked.front().delta_bic);
  }
  EXPECT_GE(quiet, 9) << log;
}

TEST(Diagnose, AnEffectOutsideTheLibraryIsReportedAsNotExplainedWithTheResidualDescribed) {
  // A second-order actuator roll-off is not in the library... but actuator_lag
  // would absorb part of it; use instead a notch-free sensor resonance on z only
  // (an extra output filter), which no library effect reproduces: a lightly damped
  // second-order section multiplying the z row.
  PhysicalModel truth = PhysicalModel::default_platform();
  const DiagnoseOptions o = options();
  auto data = noisy_data(truth, o.fit, 77);
  const double wn = 900.0, zeta = 0.03;
  for (auto& d : data)
    for (std::size_t k = 0; k < d.response.response.size(); ++k) {
      const std::complex<double> s(0.0, d.response.omega_rad_s(static_cast<Index>(k)));
      const std::complex<double> f = wn * wn / (s * s + 2.0 * zeta * wn * s + wn * wn);
      d.response.response[k].row(2) *= f;
    }
  const Diagnosis d = diagnose(truth, data, o);
  std::string table;
  for (const auto& r : d.ranked) table += fmt::format("{} ΔBIC {:.1f} err {:.4g}; ", r.effect, r.delta_bic, r.error);
  std::size_t bands = 0;
  for (const auto& s : d.baseline_failures) bands += s.size();
  EXPECT_GT(bands, 0u);
  // Either nothing is significant, or the best candidate leaves failing bands behind:
  // never a confident claim that the residual is explained.
  if (d.explained) {
    std::size_t left = 0;
    for (const auto& s : d.remaining_failures) left += s.size();
    EXPECT_GT(left, 0u) << table;
  }
}

TEST(Diagnose, RejectsUnknownOrPresentCandidates) {
  const PhysicalModel m = PhysicalModel::default_platform();
  DiagnoseOptions o = options();
  const auto data = noisy_data(m, o.fit, 3);
  o.candidates = {"warp_drive"};
  EXPECT_THROW(diagnose(m, data, o), InputError);
  o.candidates = {"rod_twist"};
  EXPECT_THROW(diagnose(m, data, o), InputError);
}

TEST(Diagnose, WithoutEffectDropsItsParametersAndKeepsTheRest) {
  PhysicalModel m = PhysicalModel::default_platform();
  m.parameter("J_psi_kgm2").value = 0.07;
  const PhysicalModel w = without_effect(m, "com_offset");
  EXPECT_FALSE(w.has_effect("com_offset"));
  EXPECT_LT(w.index_of("com_x_m"), 0);
  EXPECT_DOUBLE_EQ(w.parameter("J_psi_kgm2").value, 0.07);
  EXPECT_THROW(without_effect(w, "com_offset"), InputError);
}

}  // namespace
}  // namespace lpvid
