#include "idlib/sim/platform_sim.h"

#include <fmt/format.h>

#include <cmath>
#include <random>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

Index sample_count(double duration_s, double sample_period_s) {
  return static_cast<Index>(std::llround(duration_s / sample_period_s));
}

void require_std(const Eigen::Vector3d& std_dev, const char* name, const char* units) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(std_dev(i)) || !(std_dev(i) >= 0.0))
      throw InputError(fmt::format("excitation options: {}[{}] = {}; it must be finite and >= 0; give it in {}", name, i,
                                   std_dev(i), units));
}

void check_model(const StateSpace& sys, const char* role, const ExcitationOptions& options) {
  sys.validate();
  if (!sys.is_discrete())
    throw InputError(fmt::format(
        "closed-loop simulation: the {} is continuous (ts = 0); discretise it at sample_period_s = {} s first", role,
        options.sample_period_s));
  if (sys.num_inputs() != 3 || sys.num_outputs() != 3)
    throw InputError(fmt::format("closed-loop simulation: the {} has {} inputs and {} outputs; it must have 3 and 3",
                                 role, sys.num_inputs(), sys.num_outputs()));
  // Relative tolerance: sample periods that agree to 1e-9 come from the same
  // number written with different rounding; anything larger is a different rate.
  constexpr double kSamplePeriodRelTolerance = 1e-9;
  if (std::abs(sys.sample_period_s - options.sample_period_s) > kSamplePeriodRelTolerance * options.sample_period_s)
    throw InputError(fmt::format(
        "closed-loop simulation: the {} has ts = {} s but sample_period_s = {} s; discretise it at the experiment's "
        "sample period",
        role, sys.sample_period_s, options.sample_period_s));
}

// The loop with fixed sizes where the orders are known at compile time
// (NP = 6, NC = 3 for the platform with the PI controller), dynamic otherwise.
template <int NP, int NC>
void run_loop(const StateSpace& plant, const StateSpace& controller, const ExcitationOptions& options,
              Eigen::MatrixXd& data) {
  using MatP = Eigen::Matrix<double, NP, NP>;
  using MatPU = Eigen::Matrix<double, NP, 3>;
  using MatYP = Eigen::Matrix<double, 3, NP>;
  using MatC = Eigen::Matrix<double, NC, NC>;
  using MatCU = Eigen::Matrix<double, NC, 3>;
  using MatYC = Eigen::Matrix<double, 3, NC>;
  using VecP = Eigen::Matrix<double, NP, 1>;
  using VecC = Eigen::Matrix<double, NC, 1>;

  const MatP Ap = plant.A;
  const MatPU Bp = plant.B;
  const MatYP Cp = plant.C;
  const MatC Ac = controller.A;
  const MatCU Bc = controller.B;
  const MatYC Cc = controller.C;
  const Eigen::Matrix3d Dc = controller.D;

  VecP xp = VecP::Zero(plant.order());
  VecP xp_next = VecP::Zero(plant.order());
  VecC xc = VecC::Zero(controller.order());
  VecC xc_next = VecC::Zero(controller.order());

  Eigen::Vector3d v_mask = Eigen::Vector3d::Zero();
  if (options.excited_input < 0)
    v_mask = options.excitation_std;
  else
    v_mask(options.excited_input) = options.excitation_std(options.excited_input);
  const Eigen::Vector3d n_scale = options.sensor_noise_std;
  const bool designed = options.excitation_samples.size() != 0;

  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);

  const Index N = data.rows();
  const double Ts = options.sample_period_s;
  for (Index k = 0; k < N; ++k) {
    Eigen::Vector3d v, n;
    for (int i = 0; i < 3; ++i) v(i) = normal(rng);
    for (int i = 0; i < 3; ++i) n(i) = normal(rng);
    v = designed ? Eigen::Vector3d(options.excitation_samples.row(k).transpose()) : Eigen::Vector3d(v.cwiseProduct(v_mask));
    n = n.cwiseProduct(n_scale);

    const Eigen::Vector3d q_meas = Cp * xp + n;
    const Eigen::Vector3d e = -q_meas;
    const Eigen::Vector3d u = Cc * xc + Dc * e + v;

    data(k, 0) = static_cast<double>(k) * Ts;
    data.block<1, 3>(k, 1) = v.transpose();
    data.block<1, 3>(k, 4) = u.transpose();
    data.block<1, 3>(k, 7) = q_meas.transpose();

    xp_next.noalias() = Ap * xp;
    xp_next.noalias() += Bp * u;
    xc_next.noalias() = Ac * xc;
    xc_next.noalias() += Bc * e;
    xp.swap(xp_next);
    xc.swap(xc_next);
  }
}

}  // namespace

void ExcitationOptions::validate() const {
  if (!std::isfinite(sample_period_s) || !(sample_period_s > 0.0))
    throw InputError(fmt::format(
        "excitation options: sample_period_s = {}; it must be finite and > 0; give the sample period in s (1 kHz = 1e-3)",
        sample_period_s));
  if (!std::isfinite(duration_s) || !(duration_s > 0.0))
    throw InputError(
        fmt::format("excitation options: duration_s = {}; it must be finite and > 0; give the record length in s",
                    duration_s));
  const double samples = std::round(duration_s / sample_period_s);
  if (!(samples >= 1.0) || !(samples <= kMaxSamples))
    throw InputError(fmt::format(
        "excitation options: duration_s = {} at sample_period_s = {} gives {} samples; it must give 1 to {} "
        "samples; check both units (seconds)",
        duration_s, sample_period_s, samples, kMaxSamples));
  if (excited_input < -1 || excited_input > 2)
    throw InputError(fmt::format(
        "excitation options: excited_input = {}; it must be 0, 1 or 2 (one plant input) or -1 (all three at once)",
        excited_input));
  require_std(excitation_std, "excitation_std", "the plant input's units (N·m, N·m, N)");
  require_std(sensor_noise_std, "sensor_noise_std", "the output's units (rad, rad, m)");
  if (excitation_samples.size() != 0) {
    if (excitation_samples.cols() != 3 || static_cast<double>(excitation_samples.rows()) > kMaxSamples ||
        !excitation_samples.allFinite())
      throw InputError(fmt::format(
          "excitation options: excitation_samples is {} x {}; it must be N x 3 (v1..v3), N <= {}, every entry finite",
          excitation_samples.rows(), excitation_samples.cols(), kMaxSamples));
    return;  // excited_input and excitation_std do not apply
  }
  for (int i = 0; i < 3; ++i) {
    const bool excited = excited_input == -1 || excited_input == i;
    if (excited && !(excitation_std(i) > 0.0))
      throw InputError(fmt::format(
          "excitation options: excitation_std[{}] = 0 but input {} is excited (excited_input = {}); give it a positive "
          "standard deviation",
          i, i, excited_input));
  }
}

SimulatedLog simulate_excitation(const StateSpace& discrete_plant, const StateSpace& discrete_controller,
                                 const ExcitationOptions& options) {
  options.validate();
  check_model(discrete_plant, "plant", options);
  check_model(discrete_controller, "controller", options);
  if (!discrete_plant.D.isZero(0.0))
    throw InputError(fmt::format(
        "closed-loop simulation: the plant's D is non-zero (largest |D| = {}); the loop needs a strictly proper plant "
        "(D = 0), as a ZOH-discretised mechanical model is",
        discrete_plant.D.cwiseAbs().maxCoeff()));

  const Index N = options.excitation_samples.size() != 0 ? options.excitation_samples.rows()
                                                         : sample_count(options.duration_s, options.sample_period_s);
  SimulatedLog log;
  log.names = {"t", "v1", "v2", "v3", "u1", "u2", "u3", "q1", "q2", "q3"};
  log.data.resize(N, 10);
  if (discrete_plant.order() == 6 && discrete_controller.order() == 3)
    run_loop<6, 3>(discrete_plant, discrete_controller, options, log.data);
  else
    run_loop<Eigen::Dynamic, Eigen::Dynamic>(discrete_plant, discrete_controller, options, log.data);
  return log;
}

}  // namespace lpvid
