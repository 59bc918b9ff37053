// Fitting a user-described mechanical base: the two-mass axis of
// tests/support/two_mass_axis.h, its data from the independent oracle there (not from
// the library's own evaluation), its design values off the truth by 20–40 %.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <random>

#include "idlib/fit/fit.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/physical/mechanical/mechanical_base.h"
#include "tests/support/two_mass_axis.h"

namespace lpvid {
namespace mechanical_fit_test {

using two_mass_axis::AxisValues;
using two_mass_axis::axis;
using two_mass_axis::oracle;

// The truth the data come from: 30 % heavier load, 20 % softer coupling, more
// coupling damping, less guide friction than the design (the description's values).
constexpr AxisValues kTruth{2.0, 6.5, 1.6e5, 55.0, 24.0, 12.0};

FitDataset oracle_data(double noise, unsigned seed) {
  FitDataset d;
  d.label = "two-mass oracle";
  d.response.omega_rad_s = log_frequency_grid(5.0, 3000.0, 150);
  d.response.input_names = {"i"};
  d.response.output_names = {"enc", "load"};
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (Index k = 0; k < d.response.omega_rad_s.size(); ++k) {
    const Eigen::Vector2cd p = oracle(kTruth, d.response.omega_rad_s(k));
    Eigen::MatrixXcd h(2, 1);
    for (int i = 0; i < 2; ++i)
      h(i, 0) = p(i) * (1.0 + noise * Complex(n01(rng), n01(rng)) / std::sqrt(2.0));
    d.response.response.push_back(h);
  }
  return d;
}

// The estimate named `name` (fails the test when the fit has none).
const ParameterEstimate* estimate_named(const FitResult& r, const std::string& name) {
  const auto it = std::find_if(r.parameters.begin(), r.parameters.end(),
                               [&](const ParameterEstimate& p) { return p.name == name; });
  EXPECT_NE(it, r.parameters.end()) << name;
  return it == r.parameters.end() ? nullptr : &*it;
}

TEST(MechanicalFit, RecoversTheAxisFromTheOraclesResponse) {
  const PhysicalModel start = PhysicalModel::bare(make_mechanical_base(axis()));
  FitOptions o;  // continuous data, plant target
  const FitResult r = fit_physical_model(start, {oracle_data(0.0, 1)}, o);
  const std::pair<const char*, double> want[] = {{"m_carriage_kg", kTruth.mc},
                                                 {"m_load_kg", kTruth.ml},
                                                 {"k_coupling_N_per_m", kTruth.k},
                                                 {"c_coupling_Ns_per_m", kTruth.c},
                                                 {"c_guide_Ns_per_m", kTruth.cg}};
  for (const auto& nv : want) {
    const std::string name = nv.first;
    const double value = nv.second;
    const ParameterEstimate* it = estimate_named(r, name);
    if (it == nullptr) continue;
    // noise-free data of the model's own structure: the fit's own convergence
    // (relative cost 1e-12 or better) bounds the error far below 1e-4
    EXPECT_NEAR(it->estimate, value, 1e-4 * value) << name;
  }
  for (const auto& c : r.channels) EXPECT_LT(c.relative_rms_error, 1e-6) << c.output << "/" << c.input;
}

TEST(MechanicalFit, NoisyEstimatesLieWithinThreeReportedSigma) {
  const PhysicalModel start = PhysicalModel::bare(make_mechanical_base(axis()));
  FitOptions o;
  o.noise.noise_level = 0.01;  // the data's stated relative rms error
  const FitResult r = fit_physical_model(start, {oracle_data(0.01, 7)}, o);
  const std::pair<const char*, double> want[] = {{"m_load_kg", kTruth.ml}, {"k_coupling_N_per_m", kTruth.k},
                                                 {"c_coupling_Ns_per_m", kTruth.c}, {"c_guide_Ns_per_m", kTruth.cg}};
  for (const auto& nv : want) {
    const std::string name = nv.first;
    const double value = nv.second;
    const ParameterEstimate* it = estimate_named(r, name);
    if (it == nullptr) continue;
    ASSERT_GT(it->std_error, 0.0) << name;
    // 3 sigma: a single draw (seed 7) of a Gaussian estimate lies inside with 99.7 %
    EXPECT_LT(std::abs(it->estimate - value), 3.0 * it->std_error) << name << " " << it->estimate << " ± " << it->std_error;
  }
}

}  // namespace mechanical_fit_test
}  // namespace lpvid
