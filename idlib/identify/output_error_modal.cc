// The separable, modal form of the output-error refinement (output_error.h), for models
// whose full Jacobian would not fit: many outputs (the DaISy steel subframe: 28
// accelerometers, 8523 samples, order 20 — 2.6·10⁸ entries in the full form).
//
// Two changes of coordinates make it small:
// - A in real modal form, one 1 × 1 block λ = tanh(a) per real pole and one 2 × 2 block
//   ρ [cos φ  sin φ; −sin φ  cos φ], ρ = 1 / (1 + e^(−a)), per complex pair: n numbers, and
//   every pole inside the unit circle by construction (the logs of an open-loop
//   experiment ran a stable plant);
// - C, D and the offsets enter ŷ linearly and are eliminated by least squares for every θ
//   (variable projection, Golub & Pereyra 1973; Kaufman's Jacobian (I − P_Φ) ∂Φ/∂θ Θ̂),
//   so θ = [modal A; B; x_e(0)] holds n (1 + m + E) numbers.
// A state of a block depends only on its block, so each ∂X/∂θ_j has one or two non-zero
// columns and the Jacobian costs O(N p (k + 2)) per parameter, k = n (+ m) + E regressors.
//
// The covariance of [vec A; vec B; vec C] is the sandwich over record segments of the full
// problem (θ and the eliminated C, D, offsets), assembled from blocks without the
// N p × (P + p k) Jacobian, on the complement of the modal form's similarity directions
// (a real state's scale, a complex block's scale and rotation).
#include <ceres/ceres.h>
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "idlib/core/error.h"
#include "idlib/identify/output_error.h"
#include "idlib/identify/output_error_detail.h"
#include "idlib/lti/analysis.h"

namespace lpvid {

namespace output_error_modal {

using RowJac = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// A start pole at or beyond the unit circle starts just inside it.
constexpr double kMaxStartRadius = 0.9995;
// Poles are kept within ρ_max = exp(−1 / (kSlowestDecayRecords N)), N the longest record: a
// time constant of ten records is as good as none on these logs.  Real logs pull poles
// there (the DaISy steel subframe: a drift and a 98 Hz line drive a real pole and a mode
// onto the unit circle, where the fit is 66 % and the start's 6 %); the bound keeps such a
// model stable, and the reason counts the poles that sit on it.
constexpr double kSlowestDecayRecords = 10.0;
// A modal basis worse conditioned than this (nearly repeated poles, a Jordan block) is not
// used: the modal coordinates would amplify rounding by as much.
constexpr double kMaxModalCondition = 1e8;

double sigmoid(double a) { return 1.0 / (1.0 + std::exp(-a)); }
double logit(double r) { return std::log(r / (1.0 - r)); }

struct Block {
  Index start = 0;  // first state
  bool complex = false;
};

struct Layout {
  Index n = 0, m = 0, p = 0, E = 0;
  bool free_d = false, free_x0 = true;
  std::vector<Block> blocks;
  Index oB = 0, oX = 0, P = 0;  // θ = [a (n); vec B (n m); x_e(0) (n E)]
  Index k = 0;                  // regressors: x (n), u (m when D is free), one per experiment
  double rho_max = 1.0;         // largest pole radius
  Index block_of_state(Index i) const {
    for (std::size_t b = blocks.size(); b-- > 0;)
      if (blocks[b].start <= i) return static_cast<Index>(b);
    return 0;
  }
};

// The 1 × 1 or 2 × 2 block of block b and its derivatives by its one or two numbers.
struct BlockMatrices {
  Eigen::Matrix2d M, dM0, dM1;
};
BlockMatrices block_matrices(const Block& b, const double* a, double rho_max) {
  BlockMatrices r;
  r.M.setZero();
  r.dM0.setZero();
  r.dM1.setZero();
  if (!b.complex) {
    const double t = std::tanh(a[0]);
    r.M(0, 0) = rho_max * t;
    r.dM0(0, 0) = rho_max * (1.0 - t * t);
    return r;
  }
  const double sg = sigmoid(a[0]), rho = rho_max * sg, drho = rho * (1.0 - sg), c = std::cos(a[1]), s = std::sin(a[1]);
  r.M << rho * c, rho * s, -rho * s, rho * c;
  r.dM0 << drho * c, drho * s, -drho * s, drho * c;
  r.dM1 << -rho * s, rho * c, -rho * c, -rho * s;
  return r;
}

Eigen::MatrixXd modal_a(const Layout& l, const double* theta) {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(l.n, l.n);
  for (const Block& b : l.blocks) {
    const Index w = b.complex ? 2 : 1;
    A.block(b.start, b.start, w, w) = block_matrices(b, theta + b.start, l.rho_max).M.topLeftCorner(w, w);
  }
  return A;
}

struct Data {
  std::vector<Eigen::MatrixXd> u, y;  // scaled
  Eigen::MatrixXd Y;                  // all records stacked, N × p
  std::vector<Index> first_row;       // of each experiment
  Index rows = 0;
};

// One evaluation: the states, the regressors, the eliminated coefficients and the residual.
struct Eval {
  Eigen::MatrixXd X, Phi, Theta, R;  // N × n, N × k, k × p, N × p (R = Φ Θ − Y)
  Eigen::MatrixXd Q;                 // N × rank: orthonormal basis of range(Φ)
  bool ok = false;
};

Eval evaluate(const Layout& l, const Data& d, const double* theta) {
  Eval ev;
  const Index n = l.n, m = l.m;
  const Eigen::MatrixXd A = modal_a(l, theta);
  const Eigen::Map<const Eigen::MatrixXd> B(theta + l.oB, n, m);
  ev.X.resize(d.rows, n);
  ev.Phi = Eigen::MatrixXd::Zero(d.rows, l.k);
  Eigen::VectorXd x(n), xn(n);
  for (Index e = 0; e < l.E; ++e) {
    const Eigen::MatrixXd& u = d.u[static_cast<std::size_t>(e)];
    const Index r0 = d.first_row[static_cast<std::size_t>(e)];
    if (l.free_x0)
      x = Eigen::Map<const Eigen::VectorXd>(theta + l.oX + n * e, n);
    else
      x.setZero();
    for (Index t = 0; t < u.rows(); ++t) {
      ev.X.row(r0 + t) = x.transpose();
      xn.noalias() = A * x + B * u.row(t).transpose();
      x.swap(xn);
    }
    if (l.free_d) ev.Phi.block(r0, n, u.rows(), m) = u;
    ev.Phi.block(r0, l.k - l.E + e, u.rows(), 1).setOnes();
  }
  if (!ev.X.allFinite()) return ev;
  ev.Phi.leftCols(n) = ev.X;
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(ev.Phi);
  ev.Theta = qr.solve(d.Y);
  const Index rank = qr.rank();
  ev.Q = qr.householderQ() * Eigen::MatrixXd::Identity(d.rows, rank);
  ev.R = ev.Phi * ev.Theta - d.Y;
  ev.ok = ev.Theta.allFinite() && ev.R.allFinite();
  return ev;
}

// ∂X/∂θ_j: the rows of every record, the columns of θ_j's block (one or two).
struct Sensitivity {
  Index col = 0, width = 1;
  Eigen::MatrixXd S;  // N × width
};

std::vector<Sensitivity> sensitivities(const Layout& l, const Data& d, const double* theta, const Eigen::MatrixXd& X) {
  const Index n = l.n;
  std::vector<Sensitivity> out(static_cast<std::size_t>(l.P));
  std::vector<BlockMatrices> bm;
  for (const Block& b : l.blocks) bm.push_back(block_matrices(b, theta + b.start, l.rho_max));
  // Parameter j's block and the forcing of ∂x_b(t+1) = M_b ∂x_b(t) + f(t).
  for (Index j = 0; j < l.P; ++j) {
    Index state = 0;
    if (j < l.oB) {
      state = j;
    } else if (j < l.oX) {
      state = (j - l.oB) % n;
    } else {
      state = (j - l.oX) % n;
    }
    const Index bi = l.block_of_state(state);
    const Block& b = l.blocks[static_cast<std::size_t>(bi)];
    const Index w = b.complex ? 2 : 1;
    const Eigen::Matrix2d& M = bm[static_cast<std::size_t>(bi)].M;
    Sensitivity& s = out[static_cast<std::size_t>(j)];
    s.col = b.start;
    s.width = w;
    s.S = Eigen::MatrixXd::Zero(d.rows, w);
    for (Index e = 0; e < l.E; ++e) {
      const Index r0 = d.first_row[static_cast<std::size_t>(e)];
      const Eigen::MatrixXd& u = d.u[static_cast<std::size_t>(e)];
      Eigen::Vector2d dx = Eigen::Vector2d::Zero();
      if (j >= l.oX) {
        if ((j - l.oX) / n != e) continue;  // another record's initial state
        dx(state - b.start) = 1.0;
      }
      for (Index t = 0; t < u.rows(); ++t) {
        s.S.row(r0 + t) = dx.head(w).transpose();
        Eigen::Vector2d f = Eigen::Vector2d::Zero();
        if (j < l.oB) {
          const Eigen::Matrix2d& dM = (j == b.start) ? bm[static_cast<std::size_t>(bi)].dM0 : bm[static_cast<std::size_t>(bi)].dM1;
          f.head(w) = dM.topLeftCorner(w, w) * X.row(r0 + t).segment(b.start, w).transpose();
        } else if (j < l.oX) {
          f(state - b.start) = u(t, (j - l.oB) / n);
        }
        const Eigen::Vector2d next = M * dx + f;
        dx = next;
        if (w == 1) dx(1) = 0.0;
      }
    }
  }
  return out;
}

class CostFn final : public ceres::CostFunction {
 public:
  CostFn(const Layout& l, const Data& d) : l_(l), d_(d) {
    set_num_residuals(static_cast<int>(d.rows * l.p));
    mutable_parameter_block_sizes()->push_back(static_cast<int32_t>(l.P));
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const Eval ev = evaluate(l_, d_, parameters[0]);
    if (!ev.ok) return false;
    const Index N = d_.rows, p = l_.p;
    Eigen::Map<RowJac>(residuals, N, p) = ev.R;  // row t holds the p residuals of sample t
    if (jacobians == nullptr || jacobians[0] == nullptr) return true;
    Eigen::Map<RowJac> J(jacobians[0], N * p, l_.P);
    const std::vector<Sensitivity> sens = sensitivities(l_, d_, parameters[0], ev.X);
    Eigen::MatrixXd M(N, p);
    for (Index j = 0; j < l_.P; ++j) {
      const Sensitivity& s = sens[static_cast<std::size_t>(j)];
      M.noalias() = s.S * ev.Theta.middleRows(s.col, s.width);
      M.noalias() -= ev.Q * (ev.Q.transpose() * M);
      if (!M.allFinite()) return false;
      for (Index t = 0; t < N; ++t) J.block(t * p, j, p, 1) = M.row(t).transpose();
    }
    return true;
  }

 private:
  const Layout& l_;
  const Data& d_;
};

// θ's layout for `start` on these logs (everything but the modal blocks, modal_basis),
// and the records' rows.
void lay_out(const std::vector<ExperimentView>& experiments, const StateSpace& start, const OutputErrorOptions& options,
             Layout& l, Data& d) {
  const Index n = start.order(), m = start.num_inputs(), p = start.num_outputs();
  const auto E = static_cast<Index>(experiments.size());
  l.n = n;
  l.m = m;
  l.p = p;
  l.E = E;
  l.free_d = !start.D.isZero(0.0);
  l.free_x0 = options.estimate_initial_states;
  l.oB = n;
  l.oX = l.oB + n * m;
  l.P = l.oX + (l.free_x0 ? n * E : 0);
  l.k = n + (l.free_d ? m : 0) + E;
  for (const auto& e : experiments) {
    d.first_row.push_back(d.rows);
    d.rows += e.excitation.rows();
  }
}

// Real modal basis of the start: T⁻¹ A T block diagonal (l.blocks), and the start's modal
// parameters a0.  Returns why the start cannot be refined in modal form ("": it can).
std::string modal_basis(const StateSpace& start, Layout& l, Eigen::MatrixXd& T, Eigen::VectorXd& a0) {
  const Index n = l.n;
  const Eigen::EigenSolver<Eigen::MatrixXd> es(start.A);
  if (es.info() != Eigen::Success) return "not refined: the start's eigenvalues could not be computed";
  const Eigen::VectorXcd lam = es.eigenvalues();
  const Eigen::MatrixXcd V = es.eigenvectors();
  T.resize(n, n);
  a0.resize(n);
  {
    std::vector<bool> used(static_cast<std::size_t>(n), false);
    Index col = 0;
    for (Index i = 0; i < n; ++i) {
      if (used[static_cast<std::size_t>(i)]) continue;
      used[static_cast<std::size_t>(i)] = true;
      const double tol = 1e-9 * std::max(1.0, std::abs(lam(i)));
      if (std::abs(lam(i).imag()) <= tol) {
        l.blocks.push_back({col, false});
        T.col(col) = V.col(i).real();
        const double r = std::clamp(lam(i).real(), -kMaxStartRadius * l.rho_max, kMaxStartRadius * l.rho_max);
        a0(col) = std::atanh(r / l.rho_max);
        ++col;
        continue;
      }
      // its conjugate
      Index partner = -1;
      for (Index j = i + 1; j < n; ++j)
        if (!used[static_cast<std::size_t>(j)] && std::abs(lam(j) - std::conj(lam(i))) <= 1e-6 * std::max(1.0, std::abs(lam(i))) &&
            (partner < 0 || std::abs(lam(j) - std::conj(lam(i))) < std::abs(lam(partner) - std::conj(lam(i)))))
          partner = j;
      if (partner < 0 || col + 2 > n) return "not refined: the start's complex poles do not come in conjugate pairs";
      used[static_cast<std::size_t>(partner)] = true;
      const Complex z = lam(i).imag() > 0 ? lam(i) : std::conj(lam(i));
      const Eigen::VectorXcd v = lam(i).imag() > 0 ? Eigen::VectorXcd(V.col(i)) : Eigen::VectorXcd(V.col(i).conjugate());
      l.blocks.push_back({col, true});
      T.col(col) = v.real();
      T.col(col + 1) = v.imag();
      const double r = std::min(std::abs(z), kMaxStartRadius * l.rho_max);
      a0(col) = logit(r / l.rho_max);
      a0(col + 1) = std::arg(z);
      col += 2;
    }
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> tsvd(T);
  const double cond = tsvd.singularValues()(0) / tsvd.singularValues()(n - 1);
  if (!(cond < kMaxModalCondition))
    return fmt::format("not refined: the start's modal basis is too ill-conditioned ({:.3g}: nearly repeated "
                       "poles)",
                       cond);
  return "";
}

// The scaled records (d.u, d.y, d.Y), the start's θ (modal parameters a0, B and the initial
// states in the modal basis T) and the start's cost as refine_output_error measures it:
// its own C and D, the offsets (and initial states) by least squares.
double start_point(const std::vector<ExperimentView>& experiments, const StateSpace& start, const Layout& l,
                   const Eigen::VectorXd& a0, const Eigen::PartialPivLU<Eigen::MatrixXd>& Tlu,
                   const Eigen::VectorXd& su, const Eigen::VectorXd& sy, Data& d, Eigen::VectorXd& theta) {
  const Index n = l.n, m = l.m, p = l.p, E = l.E;
  d.Y.resize(d.rows, p);
  for (Index e = 0; e < E; ++e) {
    const auto& ex = experiments[static_cast<std::size_t>(e)];
    d.u.push_back(ex.excitation * su.cwiseInverse().asDiagonal());
    d.y.push_back(ex.output * sy.cwiseInverse().asDiagonal());
    d.Y.middleRows(d.first_row[static_cast<std::size_t>(e)], ex.output.rows()) = d.y.back();
  }
  double start_cost = 0.0;
  theta = Eigen::VectorXd::Zero(l.P);
  theta.head(n) = a0;
  const Eigen::MatrixXd Bm = Tlu.solve(start.B * su.asDiagonal());
  theta.segment(l.oB, n * m) = Eigen::Map<const Eigen::VectorXd>(Bm.data(), n * m);
  for (Index e = 0; e < E; ++e) {
    const auto& ex = experiments[static_cast<std::size_t>(e)];
    const SimulatedOutput s = simulate_with_fitted_start(start, ex.excitation, ex.output, l.free_x0);
    if (s.predicted.size() == 0) {
      start_cost = std::numeric_limits<double>::infinity();
      continue;
    }
    start_cost += ((ex.output - s.predicted) * sy.cwiseInverse().asDiagonal()).squaredNorm();
    if (l.free_x0) theta.segment(l.oX + n * e, n) = Tlu.solve(s.initial_state);
  }
  return start_cost;
}

// The full problem φ = [θ; Θ(:,1); ...; Θ(:,p)] at the optimum: ∂R/∂θ_j with Θ fixed
// (a[j], N × p) and the Gauss-Newton matrix H, assembled from blocks.
struct FullProblem {
  std::vector<Eigen::MatrixXd> a;
  Eigen::MatrixXd H;
};
FullProblem full_problem(const Layout& l, const Data& d, const Eigen::VectorXd& theta, const Eval& ev) {
  const Index p = l.p, k = l.k, Pn = l.P, Pf = Pn + p * k;
  FullProblem fp;
  const std::vector<Sensitivity> sens = sensitivities(l, d, theta.data(), ev.X);
  std::vector<Eigen::MatrixXd>& a = fp.a;
  a.resize(static_cast<std::size_t>(Pn));  // ∂R/∂θ_j with Θ fixed: N × p
  for (Index j = 0; j < Pn; ++j) {
    const Sensitivity& s = sens[static_cast<std::size_t>(j)];
    a[static_cast<std::size_t>(j)] = s.S * ev.Theta.middleRows(s.col, s.width);
  }
  Eigen::MatrixXd& H = fp.H;
  H = Eigen::MatrixXd::Zero(Pf, Pf);
  const Eigen::MatrixXd PtP = ev.Phi.transpose() * ev.Phi;
  for (Index j = 0; j < Pn; ++j) {
    const Eigen::MatrixXd& aj = a[static_cast<std::size_t>(j)];
    for (Index q = 0; q <= j; ++q) H(j, q) = H(q, j) = (aj.array() * a[static_cast<std::size_t>(q)].array()).sum();
    const Eigen::MatrixXd Pa = ev.Phi.transpose() * aj;  // k × p
    for (Index i = 0; i < p; ++i) {
      H.block(Pn + i * k, j, k, 1) = Pa.col(i);
      H.block(j, Pn + i * k, 1, k) = Pa.col(i).transpose();
    }
  }
  for (Index i = 0; i < p; ++i) H.block(Pn + i * k, Pn + i * k, k, k) = PtP;
  return fp;
}

// Similarity directions of the modal form in φ: a real state's scale; a complex block's
// scale and rotation (B's rows and x(0) by T, C's columns by −T).  One column each.
Eigen::MatrixXd similarity_directions(const Layout& l, const Eigen::VectorXd& theta, const Eval& ev) {
  const Index n = l.n, m = l.m, p = l.p, E = l.E, k = l.k, Pn = l.P, Pf = Pn + p * k;
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(Pf, n);
  Index g = 0;
  const Eigen::Map<const Eigen::MatrixXd> Bt(theta.data() + l.oB, n, m);
  for (const Block& b : l.blocks) {
    const Index w = b.complex ? 2 : 1;
    std::vector<Eigen::Matrix2d> Ts;
    Ts.push_back(Eigen::Matrix2d::Identity());
    if (b.complex) Ts.push_back((Eigen::Matrix2d() << 0, 1, -1, 0).finished());
    for (const Eigen::Matrix2d& Tb : Ts) {
      const Eigen::MatrixXd Tw = Tb.topLeftCorner(w, w);
      const Eigen::MatrixXd dB = Tw * Bt.middleRows(b.start, w);
      for (Index c = 0; c < m; ++c)
        for (Index r = 0; r < w; ++r) G(l.oB + b.start + r + n * c, g) = dB(r, c);
      if (l.free_x0)
        for (Index e = 0; e < E; ++e)
          G.block(l.oX + n * e + b.start, g, w, 1) = Tw * theta.segment(l.oX + n * e + b.start, w);
      const Eigen::MatrixXd dCt = -(ev.Theta.middleRows(b.start, w).transpose() * Tw).transpose();  // w × p
      for (Index i = 0; i < p; ++i) G.block(Pn + i * k + b.start, g, w, 1) = dCt.col(i);
      ++g;
    }
  }
  return G.leftCols(g);
}

// [vec A; vec B; vec C] of the refined model as linear functions of φ (the Jacobian of the
// map, at θ).
Eigen::MatrixXd abc_map(const Layout& l, const Eigen::VectorXd& theta, const Eigen::VectorXd& su,
                        const Eigen::VectorXd& sy) {
  const Index n = l.n, m = l.m, p = l.p, k = l.k, Pn = l.P, Pf = Pn + p * k;
  const Index nabc = n * n + n * m + p * n;
  Eigen::MatrixXd Mmap = Eigen::MatrixXd::Zero(nabc, Pf);
  for (const Block& b : l.blocks) {
    const Index w = b.complex ? 2 : 1;
    const BlockMatrices bm = block_matrices(b, theta.data() + b.start, l.rho_max);
    for (Index c = 0; c < w; ++c)
      for (Index r = 0; r < w; ++r) {
        const Index e = (b.start + r) + n * (b.start + c);
        Mmap(e, b.start) = bm.dM0(r, c);
        if (b.complex) Mmap(e, b.start + 1) = bm.dM1(r, c);
      }
  }
  for (Index c = 0; c < m; ++c)
    for (Index i = 0; i < n; ++i) Mmap(n * n + i + n * c, l.oB + i + n * c) = 1.0 / su(c);
  for (Index j = 0; j < n; ++j)
    for (Index i = 0; i < p; ++i) Mmap(n * n + n * m + i + p * j, Pn + i * k + j) = sy(i);
  return Mmap;
}

// Sandwich covariance of the full problem φ over record segments, on the complement of
// the similarity directions; res.covariance ([vec A; vec B; vec C]), res.replicates and
// res.feedthrough_variance from it.
void sandwich_covariance(const Layout& l, const Data& d, const Eigen::VectorXd& theta, const Eval& ev,
                         const Eigen::VectorXd& su, const Eigen::VectorXd& sy, const OutputErrorOptions& options,
                         OutputErrorResult& res) {
  const Index m = l.m, p = l.p, n = l.n;
  const Index N = d.rows, k = l.k, Pn = l.P, Pf = Pn + p * k;
  const FullProblem fp = full_problem(l, d, theta, ev);
  const std::vector<Eigen::MatrixXd>& a = fp.a;
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> gqr(similarity_directions(l, theta, ev));
  const Eigen::MatrixXd Qg = gqr.householderQ();
  const Eigen::MatrixXd Qc = Qg.rightCols(Pf - gqr.rank());
  const Eigen::MatrixXd Hz = Qc.transpose() * fp.H * Qc;
  const Eigen::MatrixXd Hinv = Hz.completeOrthogonalDecomposition().pseudoInverse();
  const Index seg = output_error_detail::sandwich_segment_length(ev.R, options.min_segment_samples);
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(Pf, Pf);
  Index segments = 0;
  for (Index r0 = 0; r0 < N; r0 += seg) {
    const Index len = std::min(seg, N - r0);
    Eigen::VectorXd gs(Pf);
    const auto Rs = ev.R.middleRows(r0, len);
    for (Index j = 0; j < Pn; ++j) gs(j) = (a[static_cast<std::size_t>(j)].middleRows(r0, len).array() * Rs.array()).sum();
    const Eigen::MatrixXd PR = ev.Phi.middleRows(r0, len).transpose() * Rs;  // k × p
    for (Index i = 0; i < p; ++i) gs.segment(Pn + i * k, k) = PR.col(i);
    S += gs * gs.transpose();
    ++segments;
  }
  Eigen::MatrixXd cov_z;
  if (segments >= 2) {
    cov_z = Hinv * (Qc.transpose() * S * Qc) * Hinv * (static_cast<double>(segments) / static_cast<double>(segments - 1));
    res.replicates = segments;
  } else {
    cov_z = Hinv * (res.cost / static_cast<double>(std::max<Index>(1, res.residuals - Qc.cols())));
  }
  const Eigen::MatrixXd cov_phi = Qc * cov_z * Qc.transpose();
  const Eigen::MatrixXd Mmap = abc_map(l, theta, su, sy);
  res.covariance = Mmap * cov_phi * Mmap.transpose();
  res.feedthrough_variance = Eigen::MatrixXd::Zero(p, m);
  if (l.free_d)
    for (Index c = 0; c < m; ++c)
      for (Index i = 0; i < p; ++i) {
        const Index e = Pn + i * k + n + c;
        res.feedthrough_variance(i, c) = cov_phi(e, e) * sy(i) * sy(i) / (su(c) * su(c));
      }
}

OutputErrorResult refine(const std::vector<ExperimentView>& experiments, const StateSpace& start,
                         const OutputErrorOptions& options) {
  output_error_detail::check_arguments(experiments, start, options);
  const Index n = start.order(), m = start.num_inputs(), p = start.num_outputs();
  OutputErrorResult res;
  res.model = start;
  res.form = "modal";
  Layout l;
  Data d;
  lay_out(experiments, start, options, l, d);
  res.parameters = l.P;
  res.residuals = d.rows * p;
  Index longest = 0;
  for (const auto& e : experiments) longest = std::max(longest, e.excitation.rows());
  l.rho_max = std::exp(-1.0 / (kSlowestDecayRecords * static_cast<double>(std::max<Index>(1, longest))));
  if (n == 0) {
    res.reason = "not refined: the model has no states";
    return res;
  }
  if (static_cast<double>(res.residuals) * static_cast<double>(l.P) > kMaxOutputErrorJacobianEntries) {
    res.reason = fmt::format("not refined: even in modal form with C and D eliminated, the output-error Jacobian "
                             "would hold {:.3g} entries ({} residuals x {} parameters), above the {:.3g} this "
                             "refinement allows",
                             static_cast<double>(res.residuals) * static_cast<double>(l.P), res.residuals, l.P,
                             kMaxOutputErrorJacobianEntries);
    return res;
  }
  if (d.rows <= l.k + 1) {
    res.reason = "not refined: the logs are too short for the output map's least squares";
    return res;
  }
  Eigen::MatrixXd T;
  Eigen::VectorXd a0;
  res.reason = modal_basis(start, l, T, a0);
  if (!res.reason.empty()) return res;
  const Eigen::PartialPivLU<Eigen::MatrixXd> Tlu(T);
  // Channel scales as in refine_output_error: each output counts alike.
  const auto [su, sy] = output_error_detail::channel_scales(experiments);
  Eigen::VectorXd theta;
  res.start_cost = start_point(experiments, start, l, a0, Tlu, su, sy, d, theta);
  if (!evaluate(l, d, theta.data()).ok) {
    res.reason = "not refined: the start model diverges on the logs";
    return res;
  }

  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem cp(po);
  cp.AddResidualBlock(new CostFn(l, d), nullptr, theta.data());
  const ceres::Solver::Options so = output_error_detail::solver_options(options.max_iterations);
  ceres::Solver::Summary summary;
  ceres::Solve(so, &cp, &summary);
  res.iterations = static_cast<int>(summary.iterations.size());
  const Eval ev = evaluate(l, d, theta.data());
  if (!summary.IsSolutionUsable() || !ev.ok) {
    res.reason = fmt::format("not refined: the solver found no usable point ({})", summary.message);
    return res;
  }
  res.cost = ev.R.squaredNorm();
  const bool converged = summary.termination_type == ceres::CONVERGENCE;
  StateSpace refined = start;
  refined.A = modal_a(l, theta.data());
  refined.B = Eigen::Map<const Eigen::MatrixXd>(theta.data() + l.oB, n, m) * su.cwiseInverse().asDiagonal();
  refined.C = sy.asDiagonal() * ev.Theta.topRows(n).transpose();
  refined.D = l.free_d ? Eigen::MatrixXd(sy.asDiagonal() * ev.Theta.middleRows(n, m).transpose() *
                                         su.cwiseInverse().asDiagonal())
                       : Eigen::MatrixXd::Zero(p, m);
  if (!is_stable(refined)) {
    res.reason = fmt::format("not refined: the output-error optimum is on the unit circle (spectral radius {:.6g})",
                             poles(refined).cwiseAbs().maxCoeff());
    return res;
  }
  if (!(res.cost < res.start_cost)) {
    res.reason = "not refined: output error did not lower the simulation error";
    return res;
  }

  // Sandwich covariance of the full problem φ = [θ; Θ(:,1); ...; Θ(:,p)] from blocks.
  sandwich_covariance(l, d, theta, ev, su, sy, options, res);
  res.model = refined;
  res.accepted = true;
  Index on_bound = 0;
  for (const Complex& z : poles(refined))
    if (std::abs(z) > l.rho_max * (1.0 - 1e-6)) ++on_bound;
  res.poles_on_bound = on_bound;
  res.reason = fmt::format("output error in modal form with C and D eliminated (variable projection; "
                           "Levenberg-Marquardt, {} iterations{}): the normalised squared error fell from {:.6g} to "
                           "{:.6g}; stable{}",
                           res.iterations, converged ? "" : ", stopped before convergence", res.start_cost, res.cost,
                           on_bound == 0
                               ? std::string()
                               : fmt::format(", but {} pole(s) sit at the bound |z| = {:.7g} (a time constant of {:g} "
                                             "records): the logs cannot tell them from undamped or integrating "
                                             "ones (a drift, or a line in the outputs)",
                                             on_bound, l.rho_max, kSlowestDecayRecords));
  return res;
}

}  // namespace output_error_modal

OutputErrorResult refine_output_error_modal(const std::vector<ExperimentView>& experiments, const StateSpace& start,
                                            const OutputErrorOptions& options) {
  if (!options.residual_weights.empty())
    throw InputError("output error in modal form: residual weights are not supported (refine_output_error has them)");
  return output_error_modal::refine(experiments, start, options);
}

}  // namespace lpvid
