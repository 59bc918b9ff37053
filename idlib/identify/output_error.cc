#include "idlib/identify/output_error.h"

#include <ceres/ceres.h>
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "idlib/core/error.h"
#include "idlib/identify/output_error_detail.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"
#include "idlib/signal/correlation.h"

namespace lpvid {

void OutputErrorOptions::validate() const {
  if (max_iterations < 1) throw InputError(fmt::format("output error: max_iterations {} must be >= 1", max_iterations));
  if (!(max_jacobian_entries > 0))
    throw InputError(fmt::format("output error: max_jacobian_entries {} must be > 0", max_jacobian_entries));
  if (min_segment_samples < 1)
    throw InputError(fmt::format("output error: min_segment_samples {} must be >= 1", min_segment_samples));
}

namespace {

using RowJac = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// θ's layout (column-major blocks), in the scaled channels ũ = u / s_u, ỹ = y / s_y.
// nk: the controller's order in closed loop (0 open loop); each experiment's initial state,
// when free, is the loop's, [x(0); x_K(0)], nx = n + nk numbers.
struct Layout {
  Index n = 0, m = 0, p = 0, E = 0, nk = 0, nx = 0;
  bool free_d = false;
  Index oA = 0, oB = 0, oC = 0, oD = 0, oX = 0, oO = 0, P = 0;
  bool free_x0 = true;
  Layout(Index n_, Index m_, Index p_, Index E_, bool d, bool x0, Index nk_ = 0)
      : n(n_), m(m_), p(p_), E(E_), nk(nk_), nx(n_ + nk_), free_d(d), free_x0(x0) {
    oB = n * n;
    oC = oB + n * m;
    oD = oC + p * n;
    oX = oD + (free_d ? p * m : 0);
    oO = oX + (free_x0 ? nx * E : 0);
    P = oO + p * E;  // an output offset per experiment
  }
};

// The known controller in the scaled channels (ũ = u / s_u, q̃ = q / s_y): e = −q,
// x_K(t+1) = A_K x_K + B_K e, u = C_K x_K + D_K e + v.
struct OeLoop {
  Eigen::MatrixXd Ak, Bk, Ck, Dk;
};

struct Data {
  std::vector<Eigen::MatrixXd> u, y;  // scaled, as logged: N_e × m, N_e × p
  std::vector<Eigen::VectorXd> weight;  // OutputErrorOptions::residual_weights (empty: none)
  Index rows = 0;                       // Σ N_e
  // The residual's weight at sample t of experiment e.
  double w(Index e, Index t) const { return weight.empty() ? 1.0 : weight[static_cast<std::size_t>(e)](t); }
};

class OeProblem {
 public:
  OeProblem(const Layout& l, const Data& d, const Eigen::MatrixXd& D_fixed, const OeLoop* loop = nullptr)
      : l_(l), d_(d), D_fixed_(D_fixed), loop_(loop) {}
  Index residuals() const { return d_.rows * l_.p; }

  // residuals (N p) and, when jac != nullptr, the row-major N p × P Jacobian.
  bool evaluate(const double* theta, double* out, double* jac) const {
    if (loop_ != nullptr) return evaluate_loop(theta, out, jac);
    const Index n = l_.n, m = l_.m, p = l_.p, P = l_.P;
    const Eigen::Map<const Eigen::MatrixXd> A(theta + l_.oA, n, n), B(theta + l_.oB, n, m), C(theta + l_.oC, p, n);
    const Eigen::MatrixXd D = l_.free_d ? Eigen::Map<const Eigen::MatrixXd>(theta + l_.oD, p, m).eval() : D_fixed_;
    Eigen::Map<Eigen::VectorXd> r(out, residuals());
    std::optional<Eigen::Map<RowJac>> J;
    if (jac != nullptr) J.emplace(jac, residuals(), P);
    Eigen::VectorXd x(n), xn(n);
    Eigen::MatrixXd dX, dXn;
    Index row = 0;
    for (Index e = 0; e < l_.E; ++e) {
      const Eigen::MatrixXd& u = d_.u[static_cast<std::size_t>(e)];
      const Eigen::MatrixXd& y = d_.y[static_cast<std::size_t>(e)];
      if (l_.free_x0)
        x = Eigen::Map<const Eigen::VectorXd>(theta + l_.oX + n * e, n);
      else
        x.setZero();
      if (J) {
        dX = Eigen::MatrixXd::Zero(n, P);
        if (l_.free_x0) dX.block(0, l_.oX + n * e, n, n).setIdentity();
      }
      for (Index t = 0; t < u.rows(); ++t, row += p) {
        const Eigen::VectorXd ut = u.row(t).transpose();
        r.segment(row, p) = C * x + D * ut + Eigen::Map<const Eigen::VectorXd>(theta + l_.oO + p * e, p) -
                            y.row(t).transpose();
        if (!d_.weight.empty()) r.segment(row, p) *= d_.w(e, t);
        if (J) {
          auto Jt = J->middleRows(row, p);
          Jt.noalias() = C * dX;
          for (Index i = 0; i < p; ++i) Jt(i, l_.oO + p * e + i) += 1.0;
          for (Index j = 0; j < n; ++j)
            for (Index i = 0; i < p; ++i) Jt(i, l_.oC + i + p * j) += x(j);
          if (l_.free_d)
            for (Index j = 0; j < m; ++j)
              for (Index i = 0; i < p; ++i) Jt(i, l_.oD + i + p * j) += ut(j);
          if (!d_.weight.empty()) Jt *= d_.w(e, t);
          dXn.noalias() = A * dX;
          for (Index j = 0; j < n; ++j)
            for (Index i = 0; i < n; ++i) dXn(i, l_.oA + i + n * j) += x(j);
          for (Index j = 0; j < m; ++j)
            for (Index i = 0; i < n; ++i) dXn(i, l_.oB + i + n * j) += ut(j);
          dX.swap(dXn);
        }
        xn.noalias() = A * x + B * ut;
        x.swap(xn);
      }
      if (!x.allFinite()) return false;  // the model diverged on this record: not a usable point
    }
    return r.allFinite();
  }

 private:
  // Closed loop: the plant (A, B, C; D = 0) in its loop with the controller, driven by the
  // excitation v (d_.u).  Forward sensitivities of the loop's state: with J_q = C dX +
  // ∂C·x the output's, de = −J_q, du = C_K dX_K + D_K de, dX⁺ = A dX + ∂A·x + B du + ∂B·u,
  // dX_K⁺ = A_K dX_K + B_K de.
  bool evaluate_loop(const double* theta, double* out, double* jac) const {
    const Index n = l_.n, m = l_.m, p = l_.p, P = l_.P, nk = l_.nk;
    const Eigen::Map<const Eigen::MatrixXd> A(theta + l_.oA, n, n), B(theta + l_.oB, n, m), C(theta + l_.oC, p, n);
    const OeLoop& K = *loop_;
    Eigen::Map<Eigen::VectorXd> r(out, residuals());
    std::optional<Eigen::Map<RowJac>> J;
    if (jac != nullptr) J.emplace(jac, residuals(), P);
    Eigen::VectorXd x(n), xn(n), xk(nk), xkn(nk), q(p), u(m), e(p);
    Eigen::MatrixXd dX, dXn, dK, dKn, Jq, dU;
    Index row = 0;
    for (Index ex = 0; ex < l_.E; ++ex) {
      const Eigen::MatrixXd& v = d_.u[static_cast<std::size_t>(ex)];
      const Eigen::MatrixXd& y = d_.y[static_cast<std::size_t>(ex)];
      if (l_.free_x0) {
        x = Eigen::Map<const Eigen::VectorXd>(theta + l_.oX + l_.nx * ex, n);
        xk = Eigen::Map<const Eigen::VectorXd>(theta + l_.oX + l_.nx * ex + n, nk);
      } else {
        x.setZero();
        xk.setZero();
      }
      if (J) {
        dX = Eigen::MatrixXd::Zero(n, P);
        dK = Eigen::MatrixXd::Zero(nk, P);
        if (l_.free_x0) {
          dX.block(0, l_.oX + l_.nx * ex, n, n).setIdentity();
          dK.block(0, l_.oX + l_.nx * ex + n, nk, nk).setIdentity();
        }
      }
      const Eigen::Map<const Eigen::VectorXd> offset(theta + l_.oO + p * ex, p);
      for (Index t = 0; t < v.rows(); ++t, row += p) {
        q.noalias() = C * x;
        r.segment(row, p) = q + offset - y.row(t).transpose();
        if (!d_.weight.empty()) r.segment(row, p) *= d_.w(ex, t);
        e = -q;
        u.noalias() = K.Ck * xk + K.Dk * e;
        u += v.row(t).transpose();
        if (J) {
          Jq.noalias() = C * dX;
          for (Index j = 0; j < n; ++j)
            for (Index i = 0; i < p; ++i) Jq(i, l_.oC + i + p * j) += x(j);
          auto Jt = J->middleRows(row, p);
          Jt = Jq;
          for (Index i = 0; i < p; ++i) Jt(i, l_.oO + p * ex + i) += 1.0;
          if (!d_.weight.empty()) Jt *= d_.w(ex, t);
          dU.noalias() = K.Ck * dK;
          dU.noalias() -= K.Dk * Jq;
          dXn.noalias() = A * dX;
          dXn.noalias() += B * dU;
          for (Index j = 0; j < n; ++j)
            for (Index i = 0; i < n; ++i) dXn(i, l_.oA + i + n * j) += x(j);
          for (Index j = 0; j < m; ++j)
            for (Index i = 0; i < n; ++i) dXn(i, l_.oB + i + n * j) += u(j);
          dKn.noalias() = K.Ak * dK;
          dKn.noalias() -= K.Bk * Jq;
          dX.swap(dXn);
          dK.swap(dKn);
        }
        xn.noalias() = A * x + B * u;
        xkn.noalias() = K.Ak * xk + K.Bk * e;
        x.swap(xn);
        xk.swap(xkn);
      }
      if (!x.allFinite() || !xk.allFinite()) return false;
    }
    return r.allFinite();
  }

  const Layout& l_;
  const Data& d_;
  const Eigen::MatrixXd& D_fixed_;
  const OeLoop* loop_;
};

class CeresOe final : public ceres::CostFunction {
 public:
  explicit CeresOe(const OeProblem& problem, Index parameters) : problem_(problem) {
    set_num_residuals(static_cast<int>(problem.residuals()));
    mutable_parameter_block_sizes()->push_back(static_cast<int32_t>(parameters));
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    return problem_.evaluate(parameters[0], residuals, jacobians != nullptr ? jacobians[0] : nullptr);
  }

 private:
  const OeProblem& problem_;
};

// Orthonormal basis of the complement of the similarity directions at θ:
// T ↦ (T A − A T, T B, −C T, 0, T x_e(0)) for the n² elementary T.
Eigen::MatrixXd gauge_complement(const Layout& l, const Eigen::VectorXd& theta) {
  const Index n = l.n, m = l.m, p = l.p;
  const Eigen::Map<const Eigen::MatrixXd> A(theta.data() + l.oA, n, n), B(theta.data() + l.oB, n, m),
      C(theta.data() + l.oC, p, n);
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(l.P, n * n);
  for (Index a = 0; a < n; ++a)
    for (Index b = 0; b < n; ++b) {
      Eigen::MatrixXd T = Eigen::MatrixXd::Zero(n, n);
      T(a, b) = 1.0;
      const Eigen::MatrixXd dA = T * A - A * T, dB = T * B, dC = -C * T;
      auto g = G.col(a + n * b);
      g.segment(l.oA, n * n) = Eigen::Map<const Eigen::VectorXd>(dA.data(), n * n);
      g.segment(l.oB, n * m) = Eigen::Map<const Eigen::VectorXd>(dB.data(), n * m);
      g.segment(l.oC, p * n) = Eigen::Map<const Eigen::VectorXd>(dC.data(), p * n);
      if (l.free_x0)
        for (Index e = 0; e < l.E; ++e) g.segment(l.oX + l.nx * e, n) = T * theta.segment(l.oX + l.nx * e, n);
    }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(G);
  const Index rank = qr.rank();
  const Eigen::MatrixXd Q = qr.householderQ();
  return Q.rightCols(l.P - rank);
}

}  // namespace

namespace output_error_detail {

void check_arguments(const std::vector<ExperimentView>& experiments, const StateSpace& start,
                     const OutputErrorOptions& options) {
  options.validate();
  start.validate();
  if (!start.is_discrete()) throw InputError("output error: the start model must be discrete");
  if (experiments.empty()) throw InputError("output error: no experiments");
  const Index m = start.num_inputs(), p = start.num_outputs();
  for (const auto& e : experiments)
    if (e.excitation.cols() != m || e.output.cols() != p || e.excitation.rows() != e.output.rows())
      throw InputError(fmt::format("output error: a log is {} x {} / {} x {} but the model is {} -> {}",
                                   e.excitation.rows(), e.excitation.cols(), e.output.rows(), e.output.cols(), m, p));
}

ChannelScales channel_scales(const std::vector<ExperimentView>& experiments) {
  const Index m = experiments.front().excitation.cols(), p = experiments.front().output.cols();
  ChannelScales s{Eigen::VectorXd::Zero(m), Eigen::VectorXd::Zero(p)};
  Index rows = 0;
  for (const auto& e : experiments) {
    s.su += (e.excitation.rowwise() - e.excitation.colwise().mean()).colwise().squaredNorm().transpose();
    s.sy += (e.output.rowwise() - e.output.colwise().mean()).colwise().squaredNorm().transpose();
    rows += e.excitation.rows();
  }
  s.su = (s.su / static_cast<double>(rows)).cwiseSqrt();
  s.sy = (s.sy / static_cast<double>(rows)).cwiseSqrt();
  for (Index j = 0; j < m; ++j)
    if (!(s.su(j) > 0)) s.su(j) = 1;
  for (Index i = 0; i < p; ++i)
    if (!(s.sy(i) > 0)) s.sy(i) = 1;
  return s;
}

ceres::Solver::Options solver_options(int max_iterations) {
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = max_iterations;
  so.function_tolerance = 1e-10;
  so.gradient_tolerance = 1e-14;
  so.parameter_tolerance = 1e-12;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.num_threads = 1;
  return so;
}

Index sandwich_segment_length(const Eigen::Ref<const Eigen::MatrixXd>& residual, Index min_segment_samples) {
  const Index rows = residual.rows();
  const Index longest = std::max(min_segment_samples, rows / kMinSandwichSegments);
  const Index shortest = std::min(longest, std::max(min_segment_samples, rows / kMaxSandwichSegments));
  if (shortest >= longest) return longest;
  // Lags up to the longest segment's share: a τ beyond it asks for the longest anyway.
  const Index max_lag = std::min<Index>(rows - 1, static_cast<Index>(std::ceil(static_cast<double>(longest) / kSegmentsPerTau)));
  double tau = 1.0;
  for (Index i = 0; i < residual.cols(); ++i) {
    const std::vector<Eigen::MatrixXd> R = autocorrelation(residual.col(i), max_lag);
    const double r0 = R[0](0, 0);
    if (!(r0 > 0.0)) continue;
    double t = 1.0;
    for (Index k = 1; k <= max_lag; ++k) {
      const double rho = R[static_cast<std::size_t>(k)](0, 0) / r0;
      if (!(rho > 0.0)) break;
      t += 2.0 * rho;
    }
    tau = std::max(tau, t);
  }
  const auto want = static_cast<Index>(std::ceil(kSegmentsPerTau * tau));
  return std::clamp(want, shortest, longest);
}

}  // namespace output_error_detail

namespace {

// The covariance of an accepted refinement at θ (scaled channels), on the gauge complement:
// the sandwich over record segments (res.covariance of [vec A; vec B; vec C] unscaled,
// res.feedthrough_variance, res.replicates).
void sandwich_covariance(const OeProblem& problem, const Layout& l, const Eigen::VectorXd& theta,
                         const Eigen::VectorXd& su, const Eigen::VectorXd& sy, Index rows,
                         const OutputErrorOptions& options, OutputErrorResult& res) {
  const Index n = l.n, m = l.m, p = l.p;
  const bool free_d = l.free_d;
  Eigen::VectorXd r(res.residuals);
  RowJac J(res.residuals, l.P);
  problem.evaluate(theta.data(), r.data(), J.data());
  const Eigen::MatrixXd Q = gauge_complement(l, theta);
  const Eigen::MatrixXd JQ = J * Q;
  const Eigen::MatrixXd H = JQ.transpose() * JQ;
  const Eigen::MatrixXd Hinv = H.completeOrthogonalDecomposition().pseudoInverse();
  const Index seg = output_error_detail::sandwich_segment_length(
      Eigen::Map<const Eigen::MatrixXd>(r.data(), p, rows).transpose(), options.min_segment_samples);
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(Q.cols(), Q.cols());
  Index segments = 0;
  for (Index start_row = 0; start_row < rows; start_row += seg) {
    const Index len = std::min(seg, rows - start_row);
    const Eigen::VectorXd g = JQ.middleRows(start_row * p, len * p).transpose() * r.segment(start_row * p, len * p);
    S += g * g.transpose();
    ++segments;
  }
  Eigen::MatrixXd cov_z;
  if (segments >= 2) {
    cov_z = Hinv * S * Hinv * (static_cast<double>(segments) / static_cast<double>(segments - 1));
    res.replicates = segments;
  } else {
    const double dof = static_cast<double>(std::max<Index>(1, res.residuals - Q.cols()));
    cov_z = Hinv * (res.cost / dof);
  }
  const Eigen::MatrixXd cov_theta = Q * cov_z * Q.transpose();  // scaled coordinates
  // Unscale: A as is, B(i,j) / s_u(j), C(i,j) s_y(i), D(i,j) s_y(i) / s_u(j).
  const Index nabc = n * n + n * m + p * n;
  Eigen::VectorXd t = Eigen::VectorXd::Ones(nabc);
  for (Index j = 0; j < m; ++j)
    for (Index i = 0; i < n; ++i) t(l.oB + i + n * j) = 1.0 / su(j);
  for (Index j = 0; j < n; ++j)
    for (Index i = 0; i < p; ++i) t(l.oC + i + p * j) = sy(i);
  res.covariance = t.asDiagonal() * cov_theta.topLeftCorner(nabc, nabc) * t.asDiagonal();
  res.feedthrough_variance = Eigen::MatrixXd::Zero(p, m);
  if (free_d)
    for (Index j = 0; j < m; ++j)
      for (Index i = 0; i < p; ++i)
        res.feedthrough_variance(i, j) =
            cov_theta(l.oD + i + p * j, l.oD + i + p * j) * sy(i) * sy(i) / (su(j) * su(j));
}

OutputErrorResult with_reason(OutputErrorResult r, std::string reason) {
  r.reason = std::move(reason);
  return r;
}

// Whether `options` weighs the residuals; refuses weights that do not fit the records.
bool checked_weights(const std::vector<ExperimentView>& experiments, const OutputErrorOptions& options) {
  const auto& w = options.residual_weights;
  if (w.empty()) return false;
  if (w.size() != experiments.size())
    throw InputError(fmt::format("output error: {} residual weights for {} experiments", w.size(), experiments.size()));
  for (std::size_t e = 0; e < experiments.size(); ++e)
    if (w[e].size() != experiments[e].excitation.rows() || !(w[e].array() >= 0.0).all())
      throw InputError(fmt::format("output error: experiment {}'s residual weights: {} values >= 0 needed for {} samples",
                                   e + 1, w[e].size(), experiments[e].excitation.rows()));
  return true;
}

// The full form, open loop (controller nullptr) or in the loop with the known controller.
OutputErrorResult refine_full(const std::vector<ExperimentView>& experiments, const StateSpace& start,
                              const StateSpace* controller, const OutputErrorOptions& options) {
  output_error_detail::check_arguments(experiments, start, options);
  const Index n = start.order(), m = start.num_inputs(), p = start.num_outputs();
  const auto E = static_cast<Index>(experiments.size());
  if (controller != nullptr) {
    controller->validate();
    if (controller->num_inputs() != p || controller->num_outputs() != m || !controller->is_discrete() ||
        std::abs(controller->sample_period_s - start.sample_period_s) > 1e-9 * start.sample_period_s)
      throw InputError(fmt::format("output error: the controller is {} -> {} at {:g} s but the plant is {} -> {} at "
                                   "{:g} s; give the controller that maps the plant's outputs to its inputs at its rate",
                                   controller->num_inputs(), controller->num_outputs(), controller->sample_period_s, m,
                                   p, start.sample_period_s));
    if (!start.D.isZero(0.0))
      throw InputError("output error in closed loop: the start has a direct feedthrough (a sampled plant inside a loop "
                       "has none)");
  }
  OutputErrorResult res;
  res.model = start;
  const bool free_d = controller == nullptr && !start.D.isZero(0.0);
  const Index nk = controller != nullptr ? controller->order() : 0;
  const Layout l(n, m, p, E, free_d, options.estimate_initial_states, nk);
  Data d;
  for (const auto& e : experiments) d.rows += e.excitation.rows();
  res.parameters = l.P;
  res.residuals = d.rows * p;
  if (n == 0) {
    res.reason = "not refined: the model has no states";
    return res;
  }
  if (static_cast<double>(res.residuals) * static_cast<double>(l.P) > options.max_jacobian_entries &&
      controller != nullptr) {
    res.reason = fmt::format("not refined: its Jacobian would hold {:.3g} entries ({} residuals x {} parameters), "
                             "above {:.3g} (records this long leave the structured fit little to gain)",
                             static_cast<double>(res.residuals) * static_cast<double>(l.P), res.residuals, l.P,
                             options.max_jacobian_entries);
    return res;
  }
  const bool weighted = checked_weights(experiments, options);
  d.weight = options.residual_weights;
  if (static_cast<double>(res.residuals) * static_cast<double>(l.P) > kMaxOutputErrorJacobianEntries) {
    if (weighted) return with_reason(res, "not refined: its Jacobian is too large for the full form, and the modal "
                                           "form has no weights");
    OutputErrorResult modal = refine_output_error_modal(experiments, start, options);
    modal.form_reason = fmt::format("the full form's Jacobian would hold {:.3g} entries ({} residuals x {} "
                                    "parameters), above {:.3g}",
                                    static_cast<double>(res.residuals) * static_cast<double>(l.P), res.residuals, l.P,
                                    kMaxOutputErrorJacobianEntries);
    return modal;
  }
  const auto [su, sy] = output_error_detail::channel_scales(experiments);
  // u as logged (zero before the record, as the Markov estimate takes it); the output's
  // offset is a parameter per experiment (its intercept), started at the mean.
  for (const auto& e : experiments) {
    d.u.push_back(e.excitation * su.cwiseInverse().asDiagonal());
    d.y.push_back(e.output * sy.cwiseInverse().asDiagonal());
  }
  const Eigen::MatrixXd Bs = start.B * su.asDiagonal(), Cs = sy.cwiseInverse().asDiagonal() * start.C,
                        Ds = sy.cwiseInverse().asDiagonal() * start.D * su.asDiagonal();
  Eigen::VectorXd theta = Eigen::VectorXd::Zero(l.P);
  theta.segment(l.oA, n * n) = Eigen::Map<const Eigen::VectorXd>(start.A.data(), n * n);
  theta.segment(l.oB, n * m) = Eigen::Map<const Eigen::VectorXd>(Bs.data(), n * m);
  theta.segment(l.oC, p * n) = Eigen::Map<const Eigen::VectorXd>(Cs.data(), p * n);
  if (free_d) theta.segment(l.oD, p * m) = Eigen::Map<const Eigen::VectorXd>(Ds.data(), p * m);
  for (Index e = 0; e < E; ++e) theta.segment(l.oO + p * e, p) = d.y[static_cast<std::size_t>(e)].colwise().mean().transpose();
  OeLoop loop;
  if (controller != nullptr) {
    loop.Ak = controller->A;
    loop.Bk = controller->B * sy.asDiagonal();
    loop.Ck = su.cwiseInverse().asDiagonal() * controller->C;
    loop.Dk = su.cwiseInverse().asDiagonal() * controller->D * sy.asDiagonal();
  }
  const OeProblem problem(l, d, Ds, controller != nullptr ? &loop : nullptr);
  Eigen::VectorXd r(res.residuals);
  if (!problem.evaluate(theta.data(), r.data(), nullptr)) {
    res.reason = "not refined: the start model diverges on the logs";
    return res;
  }
  res.start_cost = r.squaredNorm();
  // Initial states first (linear least squares with the model fixed), so that LM starts
  // from the model's best transient and not from rest.
  {
    RowJac J(res.residuals, l.P);
    problem.evaluate(theta.data(), r.data(), J.data());
    const Index first = l.free_x0 ? l.oX : l.oO;
    const Eigen::MatrixXd Jx = J.rightCols(l.P - first);
    theta.tail(l.P - first) -= Jx.colPivHouseholderQr().solve(r);
    problem.evaluate(theta.data(), r.data(), nullptr);
    res.start_cost = r.squaredNorm();  // the start with its best offsets (and initial states)
  }

  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem cp(po);
  cp.AddResidualBlock(new CeresOe(problem, l.P), nullptr, theta.data());
  const ceres::Solver::Options so = output_error_detail::solver_options(options.max_iterations);
  ceres::Solver::Summary summary;
  ceres::Solve(so, &cp, &summary);
  res.iterations = static_cast<int>(summary.iterations.size());
  if (!summary.IsSolutionUsable() || !problem.evaluate(theta.data(), r.data(), nullptr)) {
    res.reason = fmt::format("not refined: the solver found no usable point ({})", summary.message);
    return res;
  }
  res.cost = r.squaredNorm();
  StateSpace refined = start;
  refined.A = Eigen::Map<const Eigen::MatrixXd>(theta.data() + l.oA, n, n);
  refined.B = Eigen::Map<const Eigen::MatrixXd>(theta.data() + l.oB, n, m) * su.cwiseInverse().asDiagonal();
  refined.C = sy.asDiagonal() * Eigen::Map<const Eigen::MatrixXd>(theta.data() + l.oC, p, n);
  if (free_d)
    refined.D = sy.asDiagonal() * Eigen::Map<const Eigen::MatrixXd>(theta.data() + l.oD, p, m) * su.cwiseInverse().asDiagonal();
  const bool converged = summary.termination_type == ceres::CONVERGENCE;
  if (controller != nullptr) {
    // The plant may be unstable (a levitated stage); its loop with the controller ran stable.
    const StateSpace loop_model = closed_loop_output(refined, *controller);
    if (!is_stable(loop_model)) {
      res.reason = fmt::format("not refined: the output-error optimum closes an unstable loop with the controller "
                               "(spectral radius {:.6g}) and the logs ran a stable one; the start is kept",
                               poles(loop_model).cwiseAbs().maxCoeff());
      return res;
    }
  } else if (!is_stable(refined) && weighted) {
    return with_reason(res, "not refined: the output-error optimum is unstable and the stable (modal) form has no "
                            "weights");
  } else if (!is_stable(refined)) {
    // The modal form keeps every pole inside the unit circle by construction: its optimum
    // is the best stable model (or, with poles on its bound, says the logs cannot tell).
    OutputErrorResult modal = refine_output_error_modal(experiments, start, options);
    if (modal.accepted) {
      modal.form_reason = fmt::format("the full form's optimum is unstable (spectral radius {:.6g})",
                                      poles(refined).cwiseAbs().maxCoeff());
      modal.reason = fmt::format("{}; {}", modal.form_reason, modal.reason);
      return modal;
    }
    res.reason = fmt::format("not refined: the output-error optimum is unstable (spectral radius {:.6g}) and the "
                             "logs ran a stable plant, and the stable (modal) form did not help ({}); the start is kept",
                             poles(refined).cwiseAbs().maxCoeff(), modal.reason);
    return res;
  }
  if (!(res.cost < res.start_cost)) {
    res.reason = "not refined: output error did not lower the simulation error";
    return res;
  }
  sandwich_covariance(problem, l, theta, su, sy, d.rows, options, res);
  res.model = refined;
  res.accepted = true;
  res.reason = fmt::format("output error (simulation error on the logs{}, Levenberg-Marquardt, {} iterations{}): the "
                           "normalised squared error fell from {:.6g} to {:.6g}; {}",
                           controller != nullptr ? " of the loop with the controller" : "", res.iterations,
                           converged ? "" : ", stopped before convergence", res.start_cost, res.cost,
                           controller != nullptr ? "the loop stable" : "stable");
  return res;
}

}  // namespace

OutputErrorResult refine_output_error(const std::vector<ExperimentView>& experiments, const StateSpace& start,
                                      const OutputErrorOptions& options) {
  return refine_full(experiments, start, nullptr, options);
}

OutputErrorResult refine_output_error_closed_loop(const std::vector<ExperimentView>& experiments,
                                                  const StateSpace& start, const StateSpace& controller,
                                                  const OutputErrorOptions& options) {
  return refine_full(experiments, start, &controller, options);
}

SimulatedOutput simulate_with_fitted_start(const StateSpace& model, const Eigen::Ref<const Eigen::MatrixXd>& u,
                                           const Eigen::Ref<const Eigen::MatrixXd>& y, bool fit_initial_states) {
  model.validate();
  const Index n = model.order(), m = model.num_inputs(), p = model.num_outputs();
  if (u.cols() != m || y.cols() != p || u.rows() != y.rows())
    throw InputError(fmt::format("simulation fit: a log is {} x {} / {} x {} but the model is {} -> {}", u.rows(),
                                 u.cols(), y.rows(), y.cols(), m, p));
  const Index N = u.rows();
  SimulatedOutput out;
  Eigen::MatrixXd yhat = simulate_discrete(model, u);
  if (!yhat.allFinite()) return out;
  // The misfit's least-squares correction: a constant per output (the Markov estimate's
  // intercept) and, when asked, the free response F_t x(0), F_t = C A^t — by the normal
  // equations of the p + n unknowns, accumulated over time (O(N p n²), no N p × (p + n)
  // matrix held).
  const Index k = p + (fit_initial_states ? n : 0);
  Eigen::MatrixXd OtO = Eigen::MatrixXd::Zero(k, k), row(p, k);
  Eigen::VectorXd Otr = Eigen::VectorXd::Zero(k);
  Eigen::MatrixXd F = model.C;  // p × n
  const Eigen::MatrixXd misfit = y - yhat;
  row.leftCols(p).setIdentity();
  for (Index t = 0; t < N; ++t) {
    if (k > p) {
      row.rightCols(n) = F;
      F = F * model.A;
    }
    OtO.noalias() += row.transpose() * row;
    Otr.noalias() += row.transpose() * misfit.row(t).transpose();
  }
  if (!OtO.allFinite()) return out;
  const Eigen::VectorXd c = OtO.completeOrthogonalDecomposition().solve(Otr);
  F = model.C;
  for (Index t = 0; t < N; ++t) {
    Eigen::VectorXd corr = c.head(p);
    if (k > p) {
      corr += F * c.tail(n);
      F = F * model.A;
    }
    yhat.row(t) += corr.transpose();
  }
  if (!yhat.allFinite()) return out;
  out.predicted = std::move(yhat);
  out.offsets = c.head(p);
  out.initial_state = k > p ? Eigen::VectorXd(c.tail(n)) : Eigen::VectorXd::Zero(n);
  return out;
}

Eigen::VectorXd simulation_fit_percent(const StateSpace& model, const std::vector<ExperimentView>& experiments,
                                       bool fit_initial_states) {
  const Index p = model.num_outputs();
  Eigen::VectorXd err = Eigen::VectorXd::Zero(p), spread = Eigen::VectorXd::Zero(p);
  for (const auto& e : experiments) {
    const SimulatedOutput s = simulate_with_fitted_start(model, e.excitation, e.output, fit_initial_states);
    if (s.predicted.size() == 0) return {};
    const Eigen::MatrixXd& y = e.output;
    err += (y - s.predicted).colwise().squaredNorm().transpose();
    spread += (y.rowwise() - y.colwise().mean()).colwise().squaredNorm().transpose();
  }
  Eigen::VectorXd fit(p);
  for (Index i = 0; i < p; ++i) fit(i) = 100.0 * (1.0 - std::sqrt(err(i) / spread(i)));
  return fit;
}

}  // namespace lpvid
