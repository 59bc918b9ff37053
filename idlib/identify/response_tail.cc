#include "idlib/identify/response_tail.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/lti/interconnect.h"

namespace lpvid {

namespace {
// A mode whose |λ|^L is below this has left less than 1e-12 of itself beyond the
// horizon: below double round-off of the response it came from.
constexpr double kNegligibleTail = 1e-12;
// Above this eigenvector condition number the modal simulation loses more than
// ~8 digits: simulate the full state instead.
constexpr double kMaxModalCondition = 1e8;
}  // namespace

Eigen::MatrixXd closed_loop_response_beyond(const StateSpace& plant, const StateSpace& controller,
                                            const Eigen::Ref<const Eigen::MatrixXd>& excitation, Index lag) {
  plant.validate();
  controller.validate();
  if (lag < 1) throw InputError(fmt::format("response beyond the horizon: lag {} < 1", lag));
  if (excitation.cols() != plant.num_inputs())
    throw InputError(fmt::format("response beyond the horizon: {} excitation columns for {} plant inputs",
                                 excitation.cols(), plant.num_inputs()));
  const StateSpace loop = closed_loop_output(plant, controller);
  const Index N = loop.order(), T = excitation.rows(), p = loop.num_outputs();
  Eigen::MatrixXd y = Eigen::MatrixXd::Zero(T, p);
  if (T <= lag || N == 0) return y;
  const Eigen::EigenSolver<Eigen::MatrixXd> es(loop.A);
  const Eigen::MatrixXcd V = es.eigenvectors();
  const Eigen::MatrixXcd Vi = V.inverse();
  const double cond = V.norm() * Vi.norm();
  if (es.info() == Eigen::Success && std::isfinite(cond) && cond < kMaxModalCondition) {
    const Eigen::VectorXcd lam = es.eigenvalues();
    std::vector<Index> keep;
    std::vector<double> weight;  // 2 for one of a complex pair (the other dropped), 1 for a real mode
    for (Index a = 0; a < N; ++a) {
      if (std::pow(std::abs(lam(a)), static_cast<double>(lag)) < kNegligibleTail) continue;
      if (lam(a).imag() < 0.0) continue;
      keep.push_back(a);
      weight.push_back(lam(a).imag() > 0.0 ? 2.0 : 1.0);
    }
    if (keep.empty()) return y;
    const Index K = static_cast<Index>(keep.size());
    Eigen::VectorXcd l(K);
    Eigen::MatrixXcd b(K, loop.num_inputs()), c(p, K);
    const Eigen::MatrixXcd Bm = Vi * loop.B.cast<Complex>(), Cm = loop.C.cast<Complex>() * V;
    for (Index a = 0; a < K; ++a) {
      const Index i = keep[static_cast<std::size_t>(a)];
      l(a) = lam(i);
      b.row(a) = Bm.row(i);
      c.col(a) = Cm.col(i) * std::pow(lam(i), static_cast<double>(lag)) * weight[static_cast<std::size_t>(a)];
    }
    Eigen::VectorXcd xi = Eigen::VectorXcd::Zero(K);
    for (Index t = 0; t + lag < T; ++t) {  // xi = modal state at time t
      y.row(t + lag) = (c * xi).real().transpose();
      xi = l.cwiseProduct(xi) + b * excitation.row(t).transpose();
    }
    return y;
  }
  const Eigen::MatrixXd CAL = loop.C * [&] {
    Eigen::MatrixXd r = Eigen::MatrixXd::Identity(N, N), base = loop.A;
    for (Index e = lag; e > 0; e >>= 1) {
      if (e & 1) r = r * base;
      base = base * base;
    }
    return r;
  }();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(N);
  for (Index t = 0; t + lag < T; ++t) {
    y.row(t + lag) = (CAL * x).transpose();
    x = loop.A * x + loop.B * excitation.row(t).transpose();
  }
  return y;
}

}  // namespace lpvid
