#include "idlib/lti/reduce.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/lti/analysis.h"

namespace lpvid {
namespace {

using Eigen::MatrixXcd;
using Eigen::MatrixXd;

// Rotates rows/columns k, k+1 of T (and columns of U) by a unitary G whose first
// column is the eigenvector of the 2x2 block T[k:k+2, k:k+2] for eigenvalue mu,
// so that afterwards T(k+1,k) = 0 and T(k,k) = mu.
void split_2x2(MatrixXcd& T, MatrixXcd& U, Index k, Complex mu) {
  const Complex a = T(k, k), b = T(k, k + 1), c = T(k + 1, k), d = T(k + 1, k + 1);
  Eigen::Vector2cd x1(b, mu - a), x2(mu - d, c);
  Eigen::Vector2cd x = x1.norm() >= x2.norm() ? x1 : x2;
  const double nx = x.norm();
  if (nx == 0.0) return;  // block is already mu·I
  x /= nx;
  Eigen::Matrix2cd G;
  G << x(0), -std::conj(x(1)), x(1), std::conj(x(0));
  const Index n = T.rows();
  T.middleRows(k, 2) = G.adjoint() * T.middleRows(k, 2);
  T.middleCols(k, 2) = T.middleCols(k, 2) * G;
  U.middleCols(k, 2) = U.middleCols(k, 2) * G;
  (void)n;
  T(k + 1, k) = 0.0;
}

// Real Schur form with the eigenvalue groups it defines (1x1: a real
// eigenvalue; 2x2: a complex pair).
struct SchurGroups {
  MatrixXd T, U;
  std::vector<Index> start, size;  // per group
  std::vector<Complex> value;      // per group: the eigenvalue (Im >= 0 for pairs)
};

SchurGroups real_schur_groups(const MatrixXd& A) {
  Eigen::RealSchur<MatrixXd> rs(A);
  if (rs.info() != Eigen::Success)
    throw NumericalError(fmt::format("Schur form: the QR iteration did not converge for a {}x{} A", A.rows(), A.cols()));
  SchurGroups g;
  g.T = rs.matrixT();
  g.U = rs.matrixU();
  const Index n = A.rows();
  for (Index k = 0; k < n;) {
    if (k + 1 < n && g.T(k + 1, k) != 0.0) {
      const double a = g.T(k, k), b = g.T(k, k + 1), c = g.T(k + 1, k), d = g.T(k + 1, k + 1);
      const double tr = 0.5 * (a + d);
      const Complex disc = std::sqrt(Complex(0.25 * (a - d) * (a - d) + b * c));
      Complex mu = tr + disc;
      if (mu.imag() < 0.0) mu = std::conj(mu);
      g.start.push_back(k);
      g.size.push_back(2);
      g.value.push_back(mu);
      k += 2;
    } else {
      g.start.push_back(k);
      g.size.push_back(1);
      g.value.push_back(Complex(g.T(k, k), 0.0));
      k += 1;
    }
  }
  return g;
}

// Orthonormal real basis (n x r) of the real subspace spanned by the columns of
// a complex n x r matrix whose span is closed under conjugation.
MatrixXd real_basis(const MatrixXcd& V) {
  const Index n = V.rows(), r = V.cols();
  MatrixXd M(n, 2 * r);
  M << V.real(), V.imag();
  Eigen::JacobiSVD<MatrixXd> svd(M, Eigen::ComputeThinU);
  return svd.matrixU().leftCols(r);
}

// Solves T11 X − X T22 = R for upper-triangular T11 (r x r), T22 (q x q).
MatrixXcd solve_triangular_sylvester(const MatrixXcd& T11, const MatrixXcd& T22, const MatrixXcd& R) {
  const Index r = T11.rows(), q = T22.rows();
  MatrixXcd X(r, q);
  for (Index j = 0; j < q; ++j) {
    Eigen::VectorXcd rhs = R.col(j);
    for (Index i = 0; i < j; ++i) rhs += X.col(i) * T22(i, j);
    MatrixXcd M = T11;
    M.diagonal().array() -= T22(j, j);
    X.col(j) = M.triangularView<Eigen::Upper>().solve(rhs);
  }
  return X;
}

// Gramian solves on the complex Schur form A = U T Uᴴ.
//   continuous: T X + X Tᴴ = −F;   discrete: T X Tᴴ − X = −F  (F = Uᴴ Q U)
MatrixXd solve_lyapunov(const MatrixXd& A, const MatrixXd& Q, bool discrete) {
  const Index n = A.rows();
  if (n == 0) return MatrixXd(0, 0);
  Eigen::ComplexSchur<MatrixXd> cs(A);
  if (cs.info() != Eigen::Success)
    throw NumericalError(fmt::format("Gramian: the Schur iteration did not converge for a {}x{} A", n, n));
  const MatrixXcd& T = cs.matrixT();
  const MatrixXcd& U = cs.matrixU();
  const MatrixXcd F = U.adjoint() * Q.cast<Complex>() * U;
  MatrixXcd X = MatrixXcd::Zero(n, n);
  for (Index j = n - 1; j >= 0; --j) {
    Eigen::VectorXcd acc = Eigen::VectorXcd::Zero(n);  // Σ_{k>j} conj(T_jk) x_k
    for (Index k = j + 1; k < n; ++k) acc += std::conj(T(j, k)) * X.col(k);
    MatrixXcd M;
    Eigen::VectorXcd rhs;
    if (discrete) {
      M = std::conj(T(j, j)) * T;
      M.diagonal().array() -= 1.0;
      rhs = -F.col(j) - T * acc;
    } else {
      M = T;
      M.diagonal().array() += std::conj(T(j, j));
      rhs = -F.col(j) - acc;
    }
    X.col(j) = M.triangularView<Eigen::Upper>().solve(rhs);
  }
  MatrixXd P = (U * X * U.adjoint()).real();
  return 0.5 * (P + P.transpose());
}

// Symmetric square root factor L with L Lᵀ ≈ P (negative rounding eigenvalues
// clamped to 0).
MatrixXd psd_factor(const MatrixXd& P) {
  Eigen::SelfAdjointEigenSolver<MatrixXd> es(P);
  const Eigen::VectorXd ev = es.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return es.eigenvectors() * ev.asDiagonal();
}

void check_stable_for(const StateSpace& sys, const char* what) {
  sys.validate();
  if (!is_stable(sys))
    throw InputError(fmt::format("{}: the model is not stable (a pole on or outside the stability boundary); "
                                 "Gramians exist only for stable models, remove the unstable modes first (remove_modes)",
                                 what));
}

// Staircase reduction to the reachable part of (A, B): returns an orthogonal Z
// and the reachable dimension r, with Zᵀ A Z = [[Ar *]; [0 *]], Zᵀ B = [Br; 0].
Index reachable_staircase(const MatrixXd& A0, const MatrixXd& B0, double tol_abs, MatrixXd& Z) {
  const Index n = A0.rows();
  MatrixXd A = A0;
  Z = MatrixXd::Identity(n, n);
  MatrixXd Bsub = B0;  // remaining rows x block columns
  Index offset = 0;
  while (offset < n) {
    const Index rem = n - offset;
    if (Bsub.cols() == 0) break;
    Eigen::JacobiSVD<MatrixXd> svd(Bsub, Eigen::ComputeFullU);
    const Eigen::VectorXd& s = svd.singularValues();
    Index r = 0;
    while (r < s.size() && s[r] > tol_abs) ++r;
    if (r == 0) break;
    const MatrixXd Uf = svd.matrixU();  // rem x rem
    A.bottomRows(rem) = Uf.transpose() * A.bottomRows(rem);
    A.rightCols(rem) = A.rightCols(rem) * Uf;
    Z.rightCols(rem) = Z.rightCols(rem) * Uf;
    offset += r;
    if (offset >= n) break;
    Bsub = A.block(offset, offset - r, n - offset, r);
  }
  return offset;
}

}  // namespace

StateSpace remove_modes(const StateSpace& sys, const Eigen::VectorXcd& targets, Index count) {
  sys.validate();
  const Index n = sys.order();
  if (count < 0 || count > n)
    throw InputError(fmt::format("remove modes: count = {} for a model of order {}; it must be in [0, {}]", count, n, n));
  if (count == 0) return sys;
  if (targets.size() == 0) throw InputError("remove modes: no target eigenvalues given; pass at least one target");
  if (!targets.allFinite()) throw InputError("remove modes: a target is NaN or Inf; targets must be finite");

  SchurGroups g = real_schur_groups(sys.A);
  const size_t ng = g.start.size();
  std::vector<double> dist(ng);
  for (size_t i = 0; i < ng; ++i) {
    double best = INFINITY;
    for (Index t = 0; t < targets.size(); ++t) best = std::min(best, std::abs(g.value[i] - targets[t]));
    dist[i] = best;
  }
  std::vector<size_t> order(ng);
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return dist[a] < dist[b]; });
  std::vector<bool> remove_group(ng, false);
  Index taken = 0;
  for (size_t i : order) {
    if (taken == count) break;
    if (taken + g.size[i] > count) {
      const Complex v = g.value[i];
      throw InputError(fmt::format("remove modes: count = {} would split the complex pair {:.6g}±{:.6g}j from its conjugate; "
                                   "use count = {} or {}",
                                   count, v.real(), v.imag(), count - 1, count + 1));
    }
    remove_group[i] = true;
    taken += g.size[i];
  }
  if (count == n) {
    StateSpace s = sys;
    s.A.resize(0, 0);
    s.B.resize(0, sys.num_inputs());
    s.C.resize(sys.num_outputs(), 0);
    return s;
  }

  // Complex triangular form with per-position removal flags.
  MatrixXcd T = g.T.cast<Complex>();
  MatrixXcd U = g.U.cast<Complex>();
  std::vector<bool> flag(static_cast<size_t>(n), false);
  for (size_t i = 0; i < ng; ++i) {
    if (g.size[i] == 2) split_2x2(T, U, g.start[i], g.value[i]);
    for (Index k = 0; k < g.size[i]; ++k) flag[static_cast<size_t>(g.start[i] + k)] = remove_group[i];
  }
  // Bubble removed eigenvalues to the front (stable order).
  Index front = 0;
  for (Index k = 0; k < n; ++k) {
    if (!flag[static_cast<size_t>(k)]) continue;
    for (Index j = k; j > front; --j) {
      const Complex t11 = T(j - 1, j - 1), t22 = T(j, j);
      if (t11 != t22) {
        split_2x2(T, U, j - 1, t22);
        T(j - 1, j - 1) = t22;
        T(j, j) = t11;
      }
      std::vector<bool>::swap(flag[static_cast<size_t>(j - 1)], flag[static_cast<size_t>(j)]);
    }
    ++front;
  }
  LPVID_ASSERT(front == count);
  const Index r = count, q = n - count;
  const MatrixXcd X = solve_triangular_sylvester(T.topLeftCorner(r, r), T.bottomRightCorner(q, q), -T.topRightCorner(r, q));
  const MatrixXcd V = U.leftCols(r) * X + U.rightCols(q);  // right invariant subspace of the kept eigenvalues
  const MatrixXcd W = U.rightCols(q);                      // left invariant subspace (Wᴴ A = T22 Wᴴ)
  const MatrixXd Vr = real_basis(V), Wr = real_basis(W);
  const Eigen::PartialPivLU<MatrixXd> M(Wr.transpose() * Vr);
  StateSpace out = sys;
  out.A = M.solve(Wr.transpose() * sys.A * Vr);
  out.B = M.solve(Wr.transpose() * sys.B);
  out.C = sys.C * Vr;
  return out;
}

StateSpace minimal_realization(const StateSpace& sys, double tolerance) {
  sys.validate();
  if (!(tolerance > 0.0 && tolerance < 1.0))
    throw InputError(fmt::format("minimal realization: tolerance = {}; it must be in (0, 1) (relative to the model's norms)", tolerance));
  const Index n = sys.order();
  if (n == 0) return sys;
  // Reachable part.
  MatrixXd Z;
  const double tol_c = tolerance * std::max({sys.A.norm(), sys.B.norm(), 1e-300});
  const Index rc = reachable_staircase(sys.A, sys.B, tol_c, Z);
  MatrixXd A = (Z.transpose() * sys.A * Z).topLeftCorner(rc, rc);
  MatrixXd B = (Z.transpose() * sys.B).topRows(rc);
  MatrixXd C = (sys.C * Z).leftCols(rc);
  // Observable part of the reachable part (dual staircase on Aᵀ, Cᵀ).
  const double tol_o = tolerance * std::max({A.norm(), C.norm(), 1e-300});
  MatrixXd Zo;
  const Index ro = reachable_staircase(A.transpose(), C.transpose(), tol_o, Zo);
  StateSpace out = sys;
  out.A = (Zo.transpose() * A * Zo).topLeftCorner(ro, ro);
  out.B = (Zo.transpose() * B).topRows(ro);
  out.C = (C * Zo).leftCols(ro);
  return out;
}

Gramians gramians(const StateSpace& stable_sys) {
  check_stable_for(stable_sys, "Gramians");
  const bool disc = stable_sys.is_discrete();
  Gramians g;
  g.controllability = solve_lyapunov(stable_sys.A, stable_sys.B * stable_sys.B.transpose(), disc);
  g.observability = solve_lyapunov(stable_sys.A.transpose(), stable_sys.C.transpose() * stable_sys.C, disc);
  return g;
}

Eigen::VectorXd hankel_singular_values(const StateSpace& stable_discrete_or_continuous) {
  const Gramians g = gramians(stable_discrete_or_continuous);
  if (stable_discrete_or_continuous.order() == 0) return Eigen::VectorXd(0);
  const MatrixXd Lp = psd_factor(g.controllability), Lq = psd_factor(g.observability);
  Eigen::JacobiSVD<MatrixXd> svd(Lq.transpose() * Lp);
  return svd.singularValues();
}

StateSpace balanced_truncation(const StateSpace& stable_sys, Index order) {
  const Index n = stable_sys.order();
  if (order < 0 || order > n)
    throw InputError(fmt::format("balanced truncation: order = {} for a model of order {}; it must be in [0, {}]", order, n, n));
  const Gramians g = gramians(stable_sys);
  StateSpace out = stable_sys;
  if (order == 0) {
    out.A.resize(0, 0);
    out.B.resize(0, stable_sys.num_inputs());
    out.C.resize(stable_sys.num_outputs(), 0);
    return out;
  }
  const MatrixXd Lp = psd_factor(g.controllability), Lq = psd_factor(g.observability);
  Eigen::JacobiSVD<MatrixXd> svd(Lq.transpose() * Lp, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::VectorXd& s = svd.singularValues();
  if (!(s[order - 1] > 0.0))
    throw InputError(fmt::format("balanced truncation: Hankel singular value {} is 0, the model has fewer than {} reachable and "
                                 "observable states; use a smaller order or minimal_realization",
                                 order, order));
  const Eigen::VectorXd is = s.head(order).cwiseSqrt().cwiseInverse();
  const MatrixXd Tl = is.asDiagonal() * svd.matrixU().leftCols(order).transpose() * Lq.transpose();
  const MatrixXd Tr = Lp * svd.matrixV().leftCols(order) * is.asDiagonal();
  out.A = Tl * stable_sys.A * Tr;
  out.B = Tl * stable_sys.B;
  out.C = stable_sys.C * Tr;
  return out;
}

}  // namespace lpvid
