// A positioning axis in closed loop (issue 24): a motor driving a ball screw, force ->
// position with a pure integrator, under a PD-type controller with a filtered derivative,
// excited through its setpoint r (e = r - q) about an operating point.  The truth is the
// axis written here (exact ZOH sampling of K / (s (tau s + 1)), derived by hand), simulated
// here by its own recursion with the controller in the loop on the MEASURED position; lpvid
// sees only the CSV log and the model files.  Used by reference_identify_test.cc (identify
// recovers the axis) and compare_model_log_test.cc (compare --log judges a model on it).
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

namespace lpvid::testing::positioning_axis {

inline constexpr double kTs = 1e-3;
inline constexpr int kSamples = 30000;  // 30 s at 1 kHz
// The axis: velocity v' = (K u − v) / τ, position q' = v (mm, V).  ZOH over Ts with
// a = e^(−Ts/τ):  v+ = a v + K (1 − a) u,  q+ = q + τ (1 − a) v + K (Ts − τ (1 − a)) u.
inline constexpr double kGain = 50.0, kTau = 0.02;
// The controller on e = r − q: u = k_p e + k_d ω_f (e − x_f), x_f+ = a_f x_f + (1 − a_f) e
// (a derivative filtered at ω_f): crossover near 100 rad/s.
inline constexpr double kKp = 3.0, kKd = 0.04, kWf = 1000.0;
inline constexpr double kSetpoint = 5.0;       // mm: the operating point before and during the log
inline constexpr double kReferenceStd = 1.0;   // mm, white noise low-passed at 300 rad/s
inline constexpr double kSensorNoise = 0.002;  // mm, white, on the measured position

struct Axis {
  Eigen::Matrix2d A;
  Eigen::Vector2d B;
  Eigen::RowVector2d C{1.0, 0.0};
  Axis() {
    const double a = std::exp(-kTs / kTau);
    A << 1.0, kTau * (1 - a), 0.0, a;
    B << kGain * (kTs - kTau * (1 - a)), kGain * (1 - a);
  }
  std::complex<double> response(double omega) const {
    const std::complex<double> z = std::polar(1.0, omega * kTs);
    const Eigen::Matrix2cd M = z * Eigen::Matrix2cd::Identity() - A.cast<std::complex<double>>();
    return (C.cast<std::complex<double>>() * M.inverse() * B.cast<std::complex<double>>())(0);
  }
};

inline double filter_pole() { return std::exp(-kWf * kTs); }

// Writes dir/{controller.json, truth.json, axis.csv (t, r, u, q, q_true: q without the sensor noise)}.  sensor_noise_scale
// multiplies kSensorNoise (0: the noise-free loop on the same reference, drawn from the
// same random sequence).
inline void write_files(const std::filesystem::path& dir, double sensor_noise_scale = 1.0,
                        const std::string& log_name = "axis.csv") {
  const Axis ax;
  const double af = filter_pole();
  const auto json_matrix = [](std::initializer_list<std::initializer_list<double>> rows) {
    nlohmann::json m = nlohmann::json::array();
    for (const auto& r : rows) m.push_back(std::vector<double>(r));
    return m;
  };
  std::ofstream(dir / "controller.json")
      << nlohmann::json{{"type", "state_space"}, {"ts", kTs},
                        {"A", json_matrix({{af}})}, {"B", json_matrix({{1 - af}})},
                        {"C", json_matrix({{-kKd * kWf}})}, {"D", json_matrix({{kKp + kKd * kWf}})},
                        {"inputs", {"e"}}, {"outputs", {"u"}}}
             .dump();
  std::ofstream(dir / "truth.json")
      << nlohmann::json{{"type", "state_space"}, {"ts", kTs},
                        {"A", json_matrix({{ax.A(0, 0), ax.A(0, 1)}, {ax.A(1, 0), ax.A(1, 1)}})},
                        {"B", json_matrix({{ax.B(0)}, {ax.B(1)}})}, {"C", json_matrix({{1.0, 0.0}})},
                        {"D", json_matrix({{0.0}})}, {"inputs", {"u"}}, {"outputs", {"q"}}}
             .dump();
  // The closed loop must be stable for the experiment to exist.
  Eigen::Matrix3d Acl;
  const double d = kKp + kKd * kWf;
  Acl.topLeftCorner<2, 2>() = ax.A - d * ax.B * ax.C;
  Acl.topRightCorner<2, 1>() = -kKd * kWf * ax.B;
  Acl.bottomLeftCorner<1, 2>() = -(1 - af) * ax.C;
  Acl(2, 2) = af;
  ASSERT_LT(Acl.eigenvalues().cwiseAbs().maxCoeff(), 1.0);
  std::mt19937_64 rng(20261129);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double alp = std::exp(-300.0 * kTs), gain = kReferenceStd * std::sqrt((1 + alp) / (1 - alp));
  Eigen::Vector2d x(kSetpoint, 0.0);  // at rest at the setpoint: the PD holds it with u = 0
  double xf = 0.0, lp = 0.0;
  std::ofstream f(dir / log_name);
  f << "t,r,u,q,q_true\n";
  f.precision(17);
  for (int k = 0; k < kSamples; ++k) {
    lp = alp * lp + (1 - alp) * gain * normal(rng);
    const double r = kSetpoint + lp;
    const double q = (ax.C * x)(0) + sensor_noise_scale * kSensorNoise * normal(rng);
    const double e = r - q;
    const double u = d * e - kKd * kWf * xf;
    f << k * kTs << ',' << r << ',' << u << ',' << q << ',' << (ax.C * x)(0) << '\n';
    xf = af * xf + (1 - af) * e;
    x = ax.A * x + ax.B * u;
  }
}

}  // namespace lpvid::testing::positioning_axis
