#include "idlib/sim/analyzer.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <random>

#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"

namespace lpvid {
namespace {

Index block_samples(const AnalyzerOptions& o) {
  return static_cast<Index>(
      std::llround(o.integration_s / (static_cast<double>(o.averages) * o.sample_period_s)));
}

void check_model(const StateSpace& sys, const char* role, const AnalyzerOptions& o) {
  sys.validate();
  if (!sys.is_discrete())
    throw InputError(fmt::format("analyzer: the {} is continuous (ts = 0); discretise it at sample_period_s = {} s first",
                                 role, o.sample_period_s));
  if (sys.num_inputs() != 3 || sys.num_outputs() != 3)
    throw InputError(fmt::format("analyzer: the {} has {} inputs and {} outputs; it must have 3 and 3", role,
                                 sys.num_inputs(), sys.num_outputs()));
  // Same rule as platform_sim.cc: periods equal to 1e-9 are one number rounded twice.
  constexpr double kSamplePeriodRelTolerance = 1e-9;
  if (std::abs(sys.sample_period_s - o.sample_period_s) > kSamplePeriodRelTolerance * o.sample_period_s)
    throw InputError(fmt::format(
        "analyzer: the {} has ts = {} s but sample_period_s = {} s; discretise it at the analyzer's sample period", role,
        sys.sample_period_s, o.sample_period_s));
}

}  // namespace

void AnalyzerOptions::validate() const {
  if (!std::isfinite(sample_period_s) || !(sample_period_s > 0.0))
    throw InputError(fmt::format("analyzer options: sample_period_s = {}; it must be finite and > 0", sample_period_s));
  if (omega_rad_s.size() == 0)
    throw InputError("analyzer options: omega_rad_s is empty; give the sweep's frequencies in rad/s");
  const double nyquist = std::numbers::pi / sample_period_s;
  for (Index k = 0; k < omega_rad_s.size(); ++k) {
    const double w = omega_rad_s(k);
    if (!std::isfinite(w) || !(w > 0.0) || !(w < nyquist))
      throw InputError(fmt::format(
          "analyzer options: omega_rad_s[{}] = {}; every frequency must be finite, > 0 and below the Nyquist frequency "
          "{:.6g} rad/s",
          k, w, nyquist));
    if (k > 0 && !(w > omega_rad_s(k - 1)))
      throw InputError(fmt::format("analyzer options: omega_rad_s[{}] = {} is not above omega_rad_s[{}] = {}; the sweep "
                                   "must be strictly increasing",
                                   k, w, k - 1, omega_rad_s(k - 1)));
  }
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(excitation_amplitude(i)) || !(excitation_amplitude(i) > 0.0))
      throw InputError(fmt::format(
          "analyzer options: excitation_amplitude[{}] = {}; it must be finite and > 0 (N·m, N·m, N)", i,
          excitation_amplitude(i)));
    if (!std::isfinite(sensor_noise_std(i)) || !(sensor_noise_std(i) >= 0.0))
      throw InputError(fmt::format("analyzer options: sensor_noise_std[{}] = {}; it must be finite and >= 0 (rad, rad, m)",
                                   i, sensor_noise_std(i)));
  }
  if (averages < 2)
    throw InputError(fmt::format("analyzer options: averages = {}; it must be >= 2 (one block has coherence 1)", averages));
  if (!std::isfinite(integration_s) || !(integration_s > 0.0) || block_samples(*this) < 1)
    throw InputError(fmt::format(
        "analyzer options: integration_s = {}; it must be finite and long enough for {} blocks of at least one sample "
        "({} s each)",
        integration_s, averages, sample_period_s));
}

AnalyzerMeasurement measure_sensitivity(const StateSpace& discrete_plant, const StateSpace& discrete_controller,
                                        const AnalyzerOptions& options) {
  options.validate();
  check_model(discrete_plant, "plant", options);
  check_model(discrete_controller, "controller", options);
  const Eigen::VectorXd& w = options.omega_rad_s;
  const Index F = w.size();
  const Index K = options.averages;
  const double block_n = static_cast<double>(block_samples(options));
  const std::vector<Eigen::MatrixXcd> S = evaluate_response(closed_loop_input_sensitivity(discrete_plant, discrete_controller), w);
  const std::vector<Eigen::MatrixXcd> C = evaluate_response(discrete_controller, w);

  AnalyzerMeasurement m;
  const std::vector<std::string> outputs = {"u1", "u2", "u3"}, inputs = {"v1", "v2", "v3"};
  for (FrequencyResponse* r : {&m.sensitivity, &m.exact_sensitivity}) {
    r->omega_rad_s = w;
    r->output_names = outputs;
    r->input_names = inputs;
  }
  m.exact_sensitivity.response = S;
  m.sensitivity.response.assign(static_cast<std::size_t>(F), Eigen::MatrixXcd::Zero(3, 3));
  m.sensitivity.coherence.assign(static_cast<std::size_t>(F), Eigen::MatrixXd::Zero(3, 3));
  m.sensitivity.flagged.assign(static_cast<std::size_t>(F), false);

  // Correlation of white noise of per-sample std σ over N_b samples with
  // (2/N_b) e^{-jωnTs}: E|ñ|² = 4σ²/N_b, split equally between real and imaginary
  // parts (circular for ω away from 0 and Nyquist, which validate() excludes).
  const Eigen::Vector3d part_std = options.sensor_noise_std * std::sqrt(2.0 / block_n);
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (Index j = 0; j < 3; ++j) {
    const double a = options.excitation_amplitude(j);
    for (Index k = 0; k < F; ++k) {
      const std::size_t kk = static_cast<std::size_t>(k);
      const Eigen::MatrixXcd SC = S[kk] * C[kk];
      Eigen::Vector3cd sum = Eigen::Vector3cd::Zero();
      Eigen::Vector3d power = Eigen::Vector3d::Zero();
      for (Index b = 0; b < K; ++b) {
        Eigen::Vector3cd n;
        for (Index l = 0; l < 3; ++l) {
          const double re = normal(rng), im = normal(rng);
          n(l) = Complex(re, im) * part_std(l);
        }
        const Eigen::Vector3cd u = S[kk].col(j) * a - SC * n;
        sum += u;
        power += u.cwiseAbs2();
      }
      m.sensitivity.response[kk].col(j) = sum / (static_cast<double>(K) * a);
      for (Index i = 0; i < 3; ++i)
        m.sensitivity.coherence[kk](i, j) =
            power(i) > 0.0 ? std::min(1.0, std::norm(sum(i)) / (static_cast<double>(K) * power(i))) : 0.0;
    }
  }

  m.relative_noise.resize(F);
  const double inv_a2 = options.excitation_amplitude.cwiseInverse().squaredNorm();
  for (Index k = 0; k < F; ++k) {
    const std::size_t kk = static_cast<std::size_t>(k);
    const Eigen::MatrixXcd SCs = S[kk] * C[kk] * options.sensor_noise_std.cast<Complex>().asDiagonal();
    m.relative_noise(k) =
        2.0 * SCs.norm() * std::sqrt(inv_a2) / (std::sqrt(block_n * static_cast<double>(K)) * S[kk].norm());
  }
  m.mean_relative_noise = m.relative_noise.mean();
  return m;
}

}  // namespace lpvid
