#include "idlib/identify/plant_fit.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "idlib/core/parallel.h"

namespace lpvid {
namespace {

using Eigen::MatrixXcd;
using Eigen::MatrixXd;
using Eigen::VectorXcd;
using Eigen::VectorXd;

// Divided differences of λ^L are taken from the closed form (λ_a^L − λ_b^L)/(λ_a − λ_b)
// unless the two eigenvalues are this close (relative), where the confluent limit
// L λ^(L−1) is accurate to O(L |λ_a − λ_b|) · round-off instead of cancelling.
constexpr double kConfluentRelative = 1e-9;
// Above this condition number of the eigenvector matrix of A_cl the eigen route for
// d(A_cl^L) loses more than ~6 of 16 digits; the exact block-triangular powers are
// used instead ([[A, E], [0, A]]^L has L(A, E) in its corner).
constexpr double kMaxEigenvectorCondition = 1e10;
// Levenberg–Marquardt damping: initial value, bounds and factors (Marquardt's scaling
// by the diagonal of the normal matrix makes μ dimensionless).
constexpr double kInitialDamping = 1e-4;
constexpr double kMinDamping = 1e-20;
constexpr double kMaxDamping = 1e10;
constexpr double kDampingDown = 10.0;
constexpr double kDampingUp = 10.0;
// Gauge directions: singular values of the tangent matrix below this fraction of the
// largest are treated as zero (a plant with repeated structure has fewer of them).
constexpr double kGaugeRankTolerance = 1e-10;
// Eigenvalues of the reduced normal matrix below this fraction of the largest are
// dropped in the covariance (unidentifiable combinations get no finite variance).
constexpr double kCovarianceRankTolerance = 1e-14;
// Model::evaluate runs its bins as this many tasks (idlib/core/parallel.h; two cores on
// the reference machine), each at least kMinBinsPerChunk bins (below that the hand-off
// costs about as much as the bins).  Fixed numbers: the sums do not depend on the machine.
constexpr Index kEvaluateChunks = 2;
constexpr Index kMinBinsPerChunk = 32;

struct Loop {  // closed loop in scaled coordinates
  MatrixXd A, B, C;
};

struct Scaled {
  MatrixXd A, B, C;       // plant (scaled)
  MatrixXd Ak, Bk, Ck, Dk;  // controller (scaled)
};

Loop close(const MatrixXd& A, const MatrixXd& B, const MatrixXd& C, const Scaled& k) {
  const Index n = A.rows(), nk = k.Ak.rows(), N = n + nk, m = B.cols(), p = C.rows();
  Loop l;
  l.A.setZero(N, N);
  l.A.topLeftCorner(n, n) = A - B * k.Dk * C;
  l.A.topRightCorner(n, nk) = B * k.Ck;
  l.A.bottomLeftCorner(nk, n) = -k.Bk * C;
  l.A.bottomRightCorner(nk, nk) = k.Ak;
  l.B.setZero(N, m);
  l.B.topRows(n) = B;
  l.C.setZero(p, N);
  l.C.leftCols(n) = C;
  return l;
}

MatrixXd matrix_power(MatrixXd base, Index e) {
  MatrixXd r = MatrixXd::Identity(base.rows(), base.cols());
  while (e > 0) {
    if (e & 1) r = r * base;
    e >>= 1;
    if (e > 0) base = base * base;
  }
  return r;
}

// LU with partial pivoting of a small complex matrix in place (P Z = L U, L unit lower,
// swaps in LAPACK's order), pivots chosen by |Re| + |Im| (LAPACK's cabs1; no hypot), and
// the two solves the evaluation needs: X = Z⁻¹ B and Y = C Z⁻¹.  Written out because
// Eigen's PartialPivLU on these 6-20-state matrices spends most of its time in hypot,
// complex division and temporaries (measured: ~40 % of a plant fit).
class SmallLu {
 public:
  void factor(MatrixXcd& a) {
    const Index N = a.rows();
    piv_.resize(static_cast<std::size_t>(N));
    inv_diag_.resize(N);
    for (Index k = 0; k < N; ++k) {
      Index r = k;
      double best = -1.0;
      for (Index i = k; i < N; ++i) {
        const double v = std::abs(a(i, k).real()) + std::abs(a(i, k).imag());
        if (v > best) best = v, r = i;
      }
      piv_[static_cast<std::size_t>(k)] = r;
      if (r != k) a.row(k).swap(a.row(r));
      const Complex d = a(k, k);
      const double d2 = d.real() * d.real() + d.imag() * d.imag();
      const Complex inv = d2 > 0.0 ? Complex(d.real() / d2, -d.imag() / d2) : Complex(INFINITY, 0.0);
      inv_diag_(k) = inv;
      for (Index i = k + 1; i < N; ++i) a(i, k) *= inv;
      for (Index j = k + 1; j < N; ++j) {
        const Complex akj = a(k, j);
        for (Index i = k + 1; i < N; ++i) a(i, j) -= a(i, k) * akj;
      }
    }
    lu_ = &a;
  }
  // x = Z⁻¹ b (b overwritten with x).
  void solve_right(MatrixXcd& b) const {
    const MatrixXcd& a = *lu_;
    const Index N = a.rows();
    for (Index k = 0; k < N; ++k)
      if (piv_[static_cast<std::size_t>(k)] != k) b.row(k).swap(b.row(piv_[static_cast<std::size_t>(k)]));
    for (Index c = 0; c < b.cols(); ++c) {
      for (Index k = 0; k < N; ++k)  // L
        for (Index i = k + 1; i < N; ++i) b(i, c) -= a(i, k) * b(k, c);
      for (Index k = N - 1; k >= 0; --k) {  // U
        b(k, c) *= inv_diag_(k);
        for (Index i = 0; i < k; ++i) b(i, c) -= a(i, k) * b(k, c);
      }
    }
  }
  // y = c Z⁻¹ (c overwritten with y): y P⁻¹ L U = c.
  void solve_left(MatrixXcd& c) const {
    const MatrixXcd& a = *lu_;
    const Index N = a.rows();
    for (Index r = 0; r < c.rows(); ++r) {
      for (Index j = 0; j < N; ++j) {  // w' U = c
        Complex s = c(r, j);
        for (Index k = 0; k < j; ++k) s -= c(r, k) * a(k, j);
        c(r, j) = s * inv_diag_(j);
      }
      for (Index j = N - 1; j >= 0; --j) {  // w L = w'
        Complex s = c(r, j);
        for (Index k = j + 1; k < N; ++k) s -= c(r, k) * a(k, j);
        c(r, j) = s;
      }
    }
    for (Index k = N - 1; k >= 0; --k)  // y = w P
      if (piv_[static_cast<std::size_t>(k)] != k) c.col(k).swap(c.col(piv_[static_cast<std::size_t>(k)]));
  }

 private:
  const MatrixXcd* lu_ = nullptr;
  std::vector<Index> piv_;
  VectorXcd inv_diag_;
};

// Everything an evaluation needs from θ.
class Model {
 public:
  Model(const MarkovBins& data, const Scaled& k, Index n) : data_(data), k_(k), n_(n) {
    p_ = data.response.front().rows();
    m_ = data.response.front().cols();
    N_ = n + k.Ak.rows();
    np_ = n * n + n * m_ + p_ * n;
  }
  Index num_params() const { return np_; }

  void unpack(const VectorXd& t, MatrixXd& A, MatrixXd& B, MatrixXd& C) const {
    A = Eigen::Map<const MatrixXd>(t.data(), n_, n_);
    B = Eigen::Map<const MatrixXd>(t.data() + n_ * n_, n_, m_);
    C = Eigen::Map<const MatrixXd>(t.data() + n_ * n_ + n_ * m_, p_, n_);
  }
  VectorXd pack(const MatrixXd& A, const MatrixXd& B, const MatrixXd& C) const {
    VectorXd t(np_);
    t << Eigen::Map<const VectorXd>(A.data(), A.size()), Eigen::Map<const VectorXd>(B.data(), B.size()),
        Eigen::Map<const VectorXd>(C.data(), C.size());
    return t;
  }

  // Cost V(θ); with jac, also JᵀJ and Jᵀr (J = ∂r/∂θ, r = Ĝ − H).  spectral_radius
  // of the closed loop is returned through rho.
  // With reps (per replicate, per bin: a perturbation δĜ of the data, scaled as the data),
  // also rep_grads.col(s) = Jᵀ W δĜ_s (the gradient term a perturbation adds), np × S.
  double evaluate(const VectorXd& theta, bool jac, MatrixXd* JtJ, VectorXd* Jtr, double& rho,
                  const std::vector<std::vector<MatrixXcd>>* reps = nullptr, MatrixXd* rep_grads = nullptr) const;

 private:
  // Only the (α, β) pairs of the basis columns enter evaluate's Gram sums (Gu's row α,
  // Gv's row β): α < n with every β (group 0), n ≤ α < N with β in [n + m, n + 2m)
  // (group 1), α ≥ N with β < n (group 2); so the products are taken per pair of groups
  // (about 4x fewer flops than all NU² × NV² pairs).
  struct Group {
    Index a0, na, b0, nb;
  };
  std::array<Group, 3> group_layout() const {
    const Index n = n_, m = m_, p = p_, N = N_, nk = N - n;
    return {Group{0, n, 0, n + 2 * m}, Group{n, nk, n + m, m}, Group{N, p, 0, n}};
  }
  // Pair (g, h) of groups, g ≤ h: index g * 3 + h − g (g + 1) / 2.
  static Index pair_index(Index g, Index h) { return g * 3 + h - g * (g + 1) / 2; }
  // What the pass over the bins reads: the closed loop at θ and the controller's blocks,
  // complex (see evaluate).
  struct BinInputs {
    MatrixXcd Ac, Bq, Cc, D2, DkC, BDk, Ckc, Bkc;
    bool jac = false;
    const std::vector<std::vector<MatrixXcd>>* reps = nullptr;
    std::size_t S = 0;  // replicates
  };
  // What it sums: per pair of groups, Gu's and Gv's blocks (real and imaginary parts; one
  // column per bin, the block in column-major order); per chunk of bins, the cost's and
  // the gradient terms' partial sums (GJsum's and GJrep's, see evaluate).
  struct BinSums {
    std::array<MatrixXd, 6> AuRe, AuIm, AvRe, AvIm;
    std::vector<double> cost_part;
    std::vector<MatrixXcd> GJpart;
    std::vector<std::vector<MatrixXcd>> GJrep_part;
  };
  // The bins of chunk `chunk` of `chunks` (contiguous runs), into sums.
  void bin_chunk(Index chunk, Index chunks, const BinInputs& in, BinSums& sums) const;
  // The normal matrix M and gradient g over the basis columns (column c: Gu's row
  // col_alpha[c], Gv's row col_beta[c]), from the bins' sums.
  void basis_normal_equations(const BinSums& sums, const MatrixXcd& GJsum, MatrixXd& M, VectorXd& g,
                              std::vector<Index>& col_alpha, std::vector<Index>& col_beta) const;
  // The map T from θ to the basis columns, and their signs (r = Ĝ − H: −1 for the direct
  // columns, +1 for the truncation basis).
  MatrixXd basis_map(const MatrixXd& DQ, VectorXd& sgn) const;
  MatrixXd truncation_derivatives(const Loop& l, const MatrixXd& AL, const MatrixXd& B, const MatrixXd& C) const;

  const MarkovBins& data_;
  const Scaled& k_;
  Index n_, p_ = 0, m_ = 0, N_ = 0, np_ = 0;
};

// Column (θ index) of dQ_θ = d(A_cl^L B_cl)/dθ, stacked as vec (N × m), N m × np.
MatrixXd Model::truncation_derivatives(const Loop& l, const MatrixXd& AL, const MatrixXd& B, const MatrixXd& C) const {
  const Index n = n_, m = m_, p = p_, N = N_;
  const Index L = data_.num_lags;
  MatrixXd DQ(N * m, np_);
  const MatrixXd DkC = k_.Dk * C, BDk = B * k_.Dk;
  // rank-one dA_cl = u wᵀ for each parameter; dB_cl = e_i e_jᵀ (top block) for B(i, j).
  auto direction = [&](Index col, VectorXd& u, VectorXd& w) {
    u.setZero(N);
    w.setZero(N);
    if (col < n * n) {
      u(col % n) = 1.0;
      w(col / n) = 1.0;
    } else if (col < n * n + n * m) {
      const Index c = col - n * n, i = c % n, j = c / n;
      u(i) = 1.0;
      w.head(n) = -DkC.row(j).transpose();
      w.tail(N - n) = k_.Ck.row(j).transpose();
    } else {
      const Index c = col - n * n - n * m, i = c % p, j = c / p;
      u.head(n) = -BDk.col(i);
      u.tail(N - n) = -k_.Bk.col(i);
      w(j) = 1.0;
    }
  };
  const Eigen::EigenSolver<MatrixXd> es(l.A);
  const MatrixXcd V = es.eigenvectors();
  const Eigen::PartialPivLU<MatrixXcd> vlu(V);
  const MatrixXcd Vi = vlu.inverse();
  const double cond = V.norm() * Vi.norm();
  VectorXd u, w;
  if (es.info() == Eigen::Success && std::isfinite(cond) && cond < kMaxEigenvectorCondition) {
    const VectorXcd lam = es.eigenvalues();
    VectorXcd lamL(N);
    for (Index a = 0; a < N; ++a) lamL(a) = std::pow(lam(a), static_cast<double>(L));
    MatrixXcd Dd(N, N);
    for (Index a = 0; a < N; ++a)
      for (Index b = 0; b < N; ++b) {
        const Complex la = lam(a), lb = lam(b);
        if (std::abs(la - lb) > kConfluentRelative * std::max(1.0, std::abs(la)))
          Dd(a, b) = (lamL(a) - lamL(b)) / (la - lb);
        else
          Dd(a, b) = static_cast<double>(L) * std::pow(0.5 * (la + lb), static_cast<double>(L - 1));
      }
    const MatrixXcd Bt = Vi * l.B.cast<Complex>();
    for (Index col = 0; col < np_; ++col) {
      direction(col, u, w);
      const VectorXcd ut = Vi * u.cast<Complex>();
      const Eigen::RowVectorXcd wt = w.transpose().cast<Complex>() * V;
      const MatrixXcd inner = Dd * (wt.transpose().asDiagonal() * Bt);
      MatrixXd d = (V * (ut.asDiagonal() * inner)).real();
      if (col >= n * n && col < n * n + n * m) {
        const Index c = col - n * n;
        d.col(c / n) += AL.col(c % n);
      }
      DQ.col(col) = Eigen::Map<const VectorXd>(d.data(), N * m);
    }
  } else {
    MatrixXd Z = MatrixXd::Zero(2 * N, 2 * N);
    Z.topLeftCorner(N, N) = l.A;
    Z.bottomRightCorner(N, N) = l.A;
    for (Index col = 0; col < np_; ++col) {
      direction(col, u, w);
      Z.topRightCorner(N, N) = u * w.transpose();
      MatrixXd d = matrix_power(Z, L).topRightCorner(N, N) * l.B;
      if (col >= n * n && col < n * n + n * m) {
        const Index c = col - n * n;
        d.col(c / n) += AL.col(c % n);
      }
      DQ.col(col) = Eigen::Map<const VectorXd>(d.data(), N * m);
    }
  }
  return DQ;
}

double Model::evaluate(const VectorXd& theta, bool jac, MatrixXd* JtJ, VectorXd* Jtr, double& rho,
                      const std::vector<std::vector<MatrixXcd>>* reps, MatrixXd* rep_grads) const {
  const Index n = n_, m = m_, p = p_, N = N_, nk = N - n, L = data_.num_lags;
  MatrixXd A, B, C;
  unpack(theta, A, B, C);
  const Loop l = close(A, B, C, k_);
  rho = Eigen::EigenSolver<MatrixXd>(l.A, false).eigenvalues().cwiseAbs().maxCoeff();
  const MatrixXd AL = matrix_power(l.A, L);
  BinInputs in;
  in.Bq = (l.B - AL * l.B).cast<Complex>();
  in.Cc = l.C.cast<Complex>();
  in.D2 = data_.excitation_gram.cast<Complex>() / static_cast<double>(L);

  MatrixXd DQ;
  const Index NV = n + 2 * m;
  const Index ncol = n * NV + nk * m + p * n;  // columns of the outer-product basis
  const Index F = data_.num_bins();
  // Per bin, the Gram matrices s_f Gu = s_f Uᴴ Φ⁻¹ U (NU²) and Gv = Vᴴ (R₀/L) V (NV²) are
  // stored as columns; Σ_f Re(Gu_f(α, α') Gv_f(β, β')) for every pair is then one pair of
  // real matrix products (Re Au Re Avᵀ − Im Au Im Avᵀ), per pair of groups (Group).
  const std::array<Group, 3> groups = group_layout();
  BinSums sums;
  MatrixXcd GJsum;
  const std::size_t S = reps != nullptr ? reps->size() : 0;
  std::vector<MatrixXcd> GJrep(S);
  in.DkC = (k_.Dk * C).cast<Complex>();
  in.BDk = (B * k_.Dk).cast<Complex>();
  in.Ckc = k_.Ck.cast<Complex>();
  in.Bkc = k_.Bk.cast<Complex>();
  in.jac = jac;
  in.reps = reps;
  in.S = S;
  if (jac) {
    DQ = truncation_derivatives(l, AL, B, C);
    for (Index g = 0; g < 3; ++g)
      for (Index h = g; h < 3; ++h) {
        const Index k = pair_index(g, h);
        sums.AuRe[k].resize(groups[g].na * groups[h].na, F);
        sums.AuIm[k].resize(groups[g].na * groups[h].na, F);
        sums.AvRe[k].resize(groups[g].nb * groups[h].nb, F);
        sums.AvIm[k].resize(groups[g].nb * groups[h].nb, F);
      }
  }
  in.Ac = l.A.cast<Complex>();
  // The bins run as kEvaluateChunks contiguous runs (fewer for few bins), one task each
  // (idlib/core/parallel.h) with its own workspace and partial sums, added in chunk order.
  const Index chunks = std::max<Index>(1, std::min<Index>(kEvaluateChunks, F / kMinBinsPerChunk));
  sums.cost_part.assign(static_cast<std::size_t>(chunks), 0.0);
  sums.GJpart.resize(static_cast<std::size_t>(chunks));
  sums.GJrep_part.assign(static_cast<std::size_t>(chunks), std::vector<MatrixXcd>(S));
  parallel_for(chunks, [&](Index chunk) { bin_chunk(chunk, chunks, in, sums); });
  double cost = 0.0;
  for (const double c : sums.cost_part) cost += c;
  if (!jac) return cost;
  GJsum = sums.GJpart.front();
  for (Index c = 1; c < chunks; ++c) GJsum += sums.GJpart[static_cast<std::size_t>(c)];
  for (std::size_t r = 0; r < S; ++r) {
    GJrep[r] = sums.GJrep_part.front()[r];
    for (Index c = 1; c < chunks; ++c) GJrep[r] += sums.GJrep_part[static_cast<std::size_t>(c)][r];
  }
  MatrixXd M;
  VectorXd g;
  std::vector<Index> col_alpha, col_beta;
  basis_normal_equations(sums, GJsum, M, g, col_alpha, col_beta);
  VectorXd sgn;
  const MatrixXd T = basis_map(DQ, sgn);
  const MatrixXd St = sgn.asDiagonal() * T;
  *JtJ = St.transpose() * M * St;
  *Jtr = St.transpose() * g;
  if (rep_grads != nullptr) {
    rep_grads->resize(np_, static_cast<Index>(S));
    for (std::size_t r = 0; r < S; ++r) {
      VectorXd gr(ncol);
      for (Index c = 0; c < ncol; ++c) gr(c) = GJrep[r](col_alpha[c], col_beta[c]).real();
      rep_grads->col(static_cast<Index>(r)) = St.transpose() * gr;
    }
  }
  return cost;
}

void Model::bin_chunk(Index chunk, Index chunks, const BinInputs& in, BinSums& sums) const {
  const Index n = n_, m = m_, p = p_, N = N_, nk = N - n, L = data_.num_lags;
  const Index NU = N + p, NV = n + 2 * m;
  const Index F = data_.num_bins();
  const std::array<Group, 3> groups = group_layout();
  const bool jac = in.jac;
  MatrixXcd Z(N, N), X, Y, U, V;
  SmallLu lu;
  double cost = 0.0;
  MatrixXcd gj;  // Σ over this chunk's bins of GJsum's terms, and of GJrep's
  std::vector<MatrixXcd>& gj_rep = sums.GJrep_part[static_cast<std::size_t>(chunk)];
  if (jac) {
    gj.setZero(NU, NV);
    for (auto& x : gj_rep) x.setZero(NU, NV);
    U.resize(p, NU);
    V.resize(m, NV);
    V.rightCols(m).setIdentity();
  }
  for (Index f = chunk * F / chunks; f < (chunk + 1) * F / chunks; ++f) {
    const double w = data_.omega_rad_s(f) * data_.sample_period_s;
    const Complex z = std::polar(1.0, w);
    Z = -in.Ac;
    Z.diagonal().array() += z;
    lu.factor(Z);
    X = in.Bq;
    lu.solve_right(X);
    const MatrixXcd Rf = data_.response[static_cast<std::size_t>(f)] - in.Cc * X;
    const MatrixXcd& Phi = data_.noise_inverse[static_cast<std::size_t>(f)];
    const bool real_bin = f == 0 || 2 * f == L;
    const double s = real_bin ? 1.0 : 2.0;
    const MatrixXcd& D2f = data_.excitation_spectrum.empty()
                               ? in.D2
                               : data_.excitation_spectrum[static_cast<std::size_t>(f)];
    const MatrixXcd RD = Rf * D2f;
    cost += s * (Rf.adjoint() * Phi * RD).trace().real();
    if (!jac) continue;
    // Y = C_cl Z⁻¹ from the LU factors: P Z = L U  ⇒  Z⁻¹ = U⁻¹ L⁻¹ P.
    Y = in.Cc;
    lu.solve_left(Y);
    U.leftCols(N) = Y;
    MatrixXcd Wt = -(Y.leftCols(n) * in.BDk + Y.rightCols(nk) * in.Bkc);
    Wt.diagonal().array() += 1.0;
    U.rightCols(p) = Wt;
    V.leftCols(n) = X.topRows(n).transpose();
    MatrixXcd Zt = -in.DkC * X.topRows(n) + in.Ckc * X.bottomRows(nk);  // m × m
    Zt.diagonal().array() += 1.0;
    V.middleCols(n, m) = Zt.transpose();
    const MatrixXcd T1 = Phi * U;
    const MatrixXcd Gu = s * (U.adjoint() * T1);
    const MatrixXcd Gv = V.adjoint() * (D2f * V);
    for (Index g = 0; g < 3; ++g)
      for (Index h = g; h < 3; ++h) {
        const Index k = pair_index(g, h);
        const Group &G1 = groups[g], &G2 = groups[h];
        // Column f holds the block in column-major order (no temporaries).
        for (Index j = 0, r = 0; j < G2.na; ++j)
          for (Index i = 0; i < G1.na; ++i, ++r) {
            const Complex x = Gu(G1.a0 + i, G2.a0 + j);
            sums.AuRe[k](r, f) = x.real();
            sums.AuIm[k](r, f) = x.imag();
          }
        for (Index j = 0, r = 0; j < G2.nb; ++j)
          for (Index i = 0; i < G1.nb; ++i, ++r) {
            const Complex x = Gv(G1.b0 + i, G2.b0 + j);
            sums.AvRe[k](r, f) = x.real();
            sums.AvIm[k](r, f) = x.imag();
          }
      }
    gj.noalias() += s * ((T1.adjoint() * RD) * V.conjugate());
    for (std::size_t r = 0; r < in.S; ++r)
      gj_rep[r].noalias() += s * ((T1.adjoint() * ((*in.reps)[r][static_cast<std::size_t>(f)] * D2f)) * V.conjugate());
  }
  sums.cost_part[static_cast<std::size_t>(chunk)] = cost;
  sums.GJpart[static_cast<std::size_t>(chunk)] = std::move(gj);
}

void Model::basis_normal_equations(const BinSums& sums, const MatrixXcd& GJsum, MatrixXd& M, VectorXd& g,
                                   std::vector<Index>& col_alpha, std::vector<Index>& col_beta) const {
  const Index n = n_, m = m_, p = p_, N = N_, nk = N - n;
  const Index NU = N + p, NV = n + 2 * m;
  const Index ncol = n * NV + nk * m + p * n;  // columns of the outer-product basis
  const std::array<Group, 3> groups = group_layout();
  // K2[g, h](i + na_g i', j + nb_g j') = Σ_f s_f Re(Gu_f(a0_g + i, a0_h + i') Gv_f(b0_g + j, b0_h + j'))
  std::array<MatrixXd, 6> K2;
  parallel_for(6, [&](Index k) {  // one task per pair of groups
    K2[k].noalias() = sums.AuRe[k] * sums.AvRe[k].transpose();
    K2[k].noalias() -= sums.AuIm[k] * sums.AvIm[k].transpose();
  });
  // Groups: α = Y_i (i < n) with all NV v's; α = Y_a (a ≥ n) with e_b; α = W̃_i with X_j.
  std::vector<Index> col_group;
  for (Index ga = 0; ga < NU; ++ga) {
    const Index grp = ga < n ? 0 : (ga < N ? 1 : 2);
    for (Index c = 0; c < groups[grp].nb; ++c) {
      col_alpha.push_back(ga);
      col_beta.push_back(groups[grp].b0 + c);
      col_group.push_back(grp);
    }
  }
  M.resize(ncol, ncol);
  g.resize(ncol);
  for (Index c2 = 0; c2 < ncol; ++c2) {
    g(c2) = GJsum(col_alpha[c2], col_beta[c2]).real();
    for (Index c1 = 0; c1 <= c2; ++c1) {
      const Index g1 = col_group[c1], g2 = col_group[c2];  // g1 ≤ g2: columns are ordered by group
      const Group &G1 = groups[g1], &G2 = groups[g2];
      M(c1, c2) = M(c2, c1) =
          K2[pair_index(g1, g2)]((col_alpha[c1] - G1.a0) + G1.na * (col_alpha[c2] - G2.a0),
                                 (col_beta[c1] - G1.b0) + G1.nb * (col_beta[c2] - G2.b0));
    }
  }
}

MatrixXd Model::basis_map(const MatrixXd& DQ, VectorXd& sgn) const {
  const Index n = n_, m = m_, p = p_, N = N_, nk = N - n;
  const Index NU = N + p, NV = n + 2 * m;
  const Index ncol = n * NV + nk * m + p * n;  // columns of the outer-product basis
  sgn.resize(ncol);
  MatrixXd T = MatrixXd::Zero(ncol, np_);
  Index off = 0;
  for (Index ga = 0; ga < NU; ++ga) {
    if (ga < n) {
      const Index i = ga;
      for (Index j = 0; j < n; ++j) sgn(off) = -1, T(off++, i + j * n) = 1.0;                // A(i, j)
      for (Index j = 0; j < m; ++j) sgn(off) = -1, T(off++, n * n + i + j * n) = 1.0;        // B(i, j)
      for (Index b = 0; b < m; ++b) sgn(off) = 1, T.row(off++) = DQ.row(i + b * N);          // Q(i, b)
    } else if (ga < N) {
      for (Index b = 0; b < m; ++b) sgn(off) = 1, T.row(off++) = DQ.row(ga + b * N);         // Q(a, b)
    } else {
      const Index i = ga - N;
      for (Index j = 0; j < n; ++j) sgn(off) = -1, T(off++, n * n + n * m + i + j * p) = 1.0;  // C(i, j)
    }
  }
  return T;
}

// θ in the plant's own coordinates from scaled θ (B = B_s diag(1/su), C = diag(sq) C_s).
VectorXd coordinate_map(Index n, Index m, Index p, const VectorXd& su, const VectorXd& sq) {
  VectorXd map(n * n + n * m + p * n);
  map.head(n * n).setOnes();
  for (Index j = 0; j < m; ++j) map.segment(n * n + j * n, n).setConstant(1.0 / su(j));
  for (Index j = 0; j < n; ++j)
    for (Index i = 0; i < p; ++i) map(n * n + n * m + i + j * p) = sq(i);
  return map;
}

// Orthonormal basis of the complement of the similarity directions at θ.
MatrixXd gauge_complement(const Model& model, const VectorXd& theta, Index n) {
  MatrixXd A, B, C;
  model.unpack(theta, A, B, C);
  MatrixXd G(theta.size(), n * n);
  for (Index l = 0; l < n; ++l)
    for (Index k = 0; k < n; ++k) {
      MatrixXd T = MatrixXd::Zero(n, n);
      T(k, l) = 1.0;
      G.col(k + l * n) = model.pack(T * A - A * T, T * B, -C * T);
    }
  const Eigen::ColPivHouseholderQR<MatrixXd> qr(G);
  const VectorXd diag = qr.matrixR().diagonal().cwiseAbs();
  Index rank = 0;
  while (rank < diag.size() && diag(rank) > kGaugeRankTolerance * diag(0)) ++rank;
  const MatrixXd Q = qr.householderQ();
  return Q.rightCols(theta.size() - rank);
}

// (JᵀJ)⁺ restricted to the gauge complement at θ: Qp (Qpᵀ JᵀJ Qp)⁺ Qpᵀ, eigenvalues below
// kCovarianceRankTolerance of the largest dropped (unidentifiable combinations).
MatrixXd normal_pseudo_inverse(const Model& model, const VectorXd& theta, Index n, const MatrixXd& JtJ) {
  const MatrixXd Qp = gauge_complement(model, theta, n);
  const MatrixXd Nm = Qp.transpose() * JtJ * Qp;
  const Eigen::SelfAdjointEigenSolver<MatrixXd> es(0.5 * (Nm + Nm.transpose()));
  const double top = es.eigenvalues().cwiseAbs().maxCoeff();
  VectorXd inv = VectorXd::Zero(Nm.rows());
  for (Index i = 0; i < Nm.rows(); ++i)
    if (es.eigenvalues()(i) > kCovarianceRankTolerance * top) inv(i) = 1.0 / es.eigenvalues()(i);
  return Qp * es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose() * Qp.transpose();
}

}  // namespace

void PlantFitOptions::validate() const {
  if (max_iterations < 0) throw InputError(fmt::format("plant fit: max_iterations = {}; must be >= 0", max_iterations));
  if (!(cost_tolerance_absolute >= 0.0) || !(cost_tolerance_relative >= 0.0))
    throw InputError("plant fit: the cost tolerances must be >= 0");
  if (input_scale.size() > 0 && !(input_scale.allFinite() && input_scale.minCoeff() > 0.0))
    throw InputError("plant fit: every input scale must be finite and > 0");
  if (output_scale.size() > 0 && !(output_scale.allFinite() && output_scale.minCoeff() > 0.0))
    throw InputError("plant fit: every output scale must be finite and > 0");
}

namespace {
struct Setup {
  MarkovBins scaled;
  Scaled k;
  Eigen::VectorXd su, sq;
};

Setup setup(const MarkovBins& data, const StateSpace& controller, const StateSpace& initial,
            const PlantFitOptions& options) {
  options.validate();
  controller.validate();
  initial.validate();
  if (data.response.empty()) throw InputError("plant fit: no frequency bins");
  const Index p = data.response.front().rows(), m = data.response.front().cols(), n = initial.order();
  if (initial.num_inputs() != m || initial.num_outputs() != p)
    throw InputError(fmt::format("plant fit: the initial plant is {}x{} but the data are {}x{}", initial.num_outputs(),
                                 initial.num_inputs(), p, m));
  if (controller.num_inputs() != p || controller.num_outputs() != m)
    throw InputError(fmt::format("plant fit: the controller is {}x{} (outputs x inputs); it must map the {} outputs to "
                                 "the {} inputs",
                                 controller.num_outputs(), controller.num_inputs(), p, m));
  if (!initial.is_discrete() || !controller.is_discrete() ||
      std::abs(initial.sample_period_s - data.sample_period_s) > 1e-9 * data.sample_period_s ||
      std::abs(controller.sample_period_s - data.sample_period_s) > 1e-9 * data.sample_period_s)
    throw InputError("plant fit: the plant, the controller and the data must share one sample period");
  if (initial.D.norm() != 0.0) throw InputError("plant fit: the initial plant must have D = 0 (ZOH-sampled plant)");
  if (n < 1) throw InputError("plant fit: the initial plant has no states");

  const Eigen::VectorXd su = options.input_scale.size() > 0 ? options.input_scale : Eigen::VectorXd::Ones(m);
  const Eigen::VectorXd sq = options.output_scale.size() > 0 ? options.output_scale : Eigen::VectorXd::Ones(p);
  if (su.size() != m || sq.size() != p) throw InputError("plant fit: one scale per input and per output");
  // Scaled data: Ĝ_s = diag(1/sq) Ĝ diag(su); Φ⁻¹_s = diag(sq) Φ⁻¹ diag(sq);
  // R₀_s = diag(1/su) R₀ diag(1/su).  V is unchanged.
  MarkovBins scaled = data;
  for (Index f = 0; f < data.num_bins(); ++f) {
    scaled.response[static_cast<std::size_t>(f)] = sq.cwiseInverse().asDiagonal() * data.response[f] * su.asDiagonal();
    scaled.noise_inverse[static_cast<std::size_t>(f)] = sq.asDiagonal() * data.noise_inverse[f] * sq.asDiagonal();
  }
  scaled.excitation_gram = su.cwiseInverse().asDiagonal() * data.excitation_gram * su.cwiseInverse().asDiagonal();
  // Stored already divided by L, as the fit uses it (D2 of Model::evaluate).
  for (auto& S : scaled.excitation_spectrum)
    S = su.cwiseInverse().cast<std::complex<double>>().asDiagonal() * S *
        su.cwiseInverse().cast<std::complex<double>>().asDiagonal() / static_cast<double>(data.num_lags);
  Scaled k;
  k.Ak = controller.A;
  k.Bk = controller.B * sq.asDiagonal();
  k.Ck = su.cwiseInverse().asDiagonal() * controller.C;
  k.Dk = su.cwiseInverse().asDiagonal() * controller.D * sq.asDiagonal();
  return {std::move(scaled), std::move(k), su, sq};
}
}  // namespace

double plant_fit_cost(const MarkovBins& data, const StateSpace& controller, const StateSpace& plant,
                      const PlantFitOptions& options) {
  const Setup st = setup(data, controller, plant, options);
  const Model model(st.scaled, st.k, plant.order());
  double rho = 0.0;
  return model.evaluate(model.pack(plant.A, plant.B * st.su.asDiagonal(), st.sq.cwiseInverse().asDiagonal() * plant.C),
                        false, nullptr, nullptr, rho);
}

PlantFitResult fit_plant_closed_loop(const MarkovBins& data, const StateSpace& controller, const StateSpace& initial,
                                     const PlantFitOptions& options) {
  const Setup st = setup(data, controller, initial, options);
  const Index p = data.response.front().rows(), m = data.response.front().cols(), n = initial.order();
  const Eigen::VectorXd& su = st.su;
  const Eigen::VectorXd& sq = st.sq;
  const Model model(st.scaled, st.k, n);
  Eigen::VectorXd theta =
      model.pack(initial.A, initial.B * su.asDiagonal(), sq.cwiseInverse().asDiagonal() * initial.C);

  PlantFitResult result;
  result.residuals = data.real_residuals();
  Eigen::MatrixXd JtJ;
  Eigen::VectorXd Jtr;
  double rho = 0.0;
  double cost = model.evaluate(theta, true, &JtJ, &Jtr, rho);
  result.initial_cost = cost;
  double mu = kInitialDamping;
  int it = 0;
  bool converged = false;
  while (it < options.max_iterations && std::isfinite(cost)) {
    const Eigen::MatrixXd Qp = gauge_complement(model, theta, n);
    const Eigen::MatrixXd Nm = Qp.transpose() * JtJ * Qp;
    const Eigen::VectorXd gr = Qp.transpose() * Jtr;
    bool accepted = false;
    while (mu <= kMaxDamping) {
      Eigen::MatrixXd Aug = Nm;
      Aug.diagonal() += mu * Nm.diagonal();
      const Eigen::VectorXd step = Aug.ldlt().solve(-gr);
      const Eigen::VectorXd trial = theta + Qp * step;
      double rho_trial = 0.0;
      const double c = step.allFinite() ? model.evaluate(trial, false, nullptr, nullptr, rho_trial) : INFINITY;
      const bool stability_ok = rho_trial < 1.0 || rho >= 1.0;
      if (std::isfinite(c) && c < cost && stability_ok) {
        const double decrease = cost - c;
        theta = trial;
        cost = model.evaluate(theta, true, &JtJ, &Jtr, rho);
        mu = std::max(mu / kDampingDown, kMinDamping);
        accepted = true;
        if (decrease < std::max(options.cost_tolerance_absolute, options.cost_tolerance_relative * cost))
          converged = true;
        break;
      }
      mu *= kDampingUp;
    }
    ++it;
    if (!accepted) {
      converged = true;  // no descent direction left at any damping: a (local) minimum
      break;
    }
    if (converged) break;
  }
  result.iterations = it;
  result.cost = cost;

  Eigen::MatrixXd A, Bs, Cs;
  model.unpack(theta, A, Bs, Cs);
  result.plant = initial;
  result.plant.A = A;
  result.plant.B = Bs * su.cwiseInverse().asDiagonal();
  result.plant.C = sq.asDiagonal() * Cs;
  result.plant.D.setZero();
  result.closed_loop_stable = rho < 1.0;
  result.parameters = n * (m + p);
  const double dof = static_cast<double>(std::max<Index>(1, result.residuals - result.parameters));
  result.noise_scale = cost / dof;

  // Covariance in scaled coordinates, then mapped to the plant's own coordinates
  // (B = B_s diag(1/su), C = diag(sq) C_s: a diagonal change of variables).
  const Eigen::MatrixXd cov_s = result.noise_scale * normal_pseudo_inverse(model, theta, n, JtJ);
  const Eigen::VectorXd map = coordinate_map(n, m, p, su, sq);
  result.covariance = map.asDiagonal() * cov_s * map.asDiagonal();

  result.report.termination =
      fmt::format("{} after {} iterations: whitened cost {:.6g} -> {:.6g} over {} real residuals ({} free parameters), "
                  "noise scale {:.3g}",
                  converged ? "converged" : "stopped at the iteration limit", it, result.initial_cost, cost,
                  result.residuals, result.parameters, result.noise_scale);
  if (!converged) result.report.warnings.push_back(result.report.termination);
  if (!result.closed_loop_stable || !std::isfinite(cost)) {
    result.report.usable = false;
    result.report.warnings.push_back(fmt::format(
        "the fitted plant closes an unstable loop with the controller (spectral radius {:.6f})", rho));
  }
  return result;
}

void use_replicate_covariance(PlantFitResult& fit, const MarkovBins& data, const StateSpace& controller,
                              const std::vector<std::vector<Eigen::MatrixXcd>>& replicates,
                              const PlantFitOptions& options) {
  const Setup st = setup(data, controller, fit.plant, options);
  const Index p = data.response.front().rows(), m = data.response.front().cols(), n = fit.plant.order();
  if (replicates.size() < 2) throw InputError("replicate covariance: at least two replicates are needed");
  std::vector<std::vector<MatrixXcd>> scaled(replicates.size());
  for (std::size_t r = 0; r < replicates.size(); ++r) {
    if (static_cast<Index>(replicates[r].size()) != data.num_bins())
      throw InputError(fmt::format("replicate covariance: replicate {} has {} bins for {}", r, replicates[r].size(),
                                   data.num_bins()));
    for (const auto& b : replicates[r]) {
      if (b.rows() != p || b.cols() != m || !b.allFinite())
        throw InputError(fmt::format("replicate covariance: every bin must be a finite {}x{} matrix", p, m));
      scaled[r].push_back(st.sq.cwiseInverse().asDiagonal() * b * st.su.asDiagonal());
    }
  }
  const Model model(st.scaled, st.k, n);
  const Eigen::VectorXd theta =
      model.pack(fit.plant.A, fit.plant.B * st.su.asDiagonal(), st.sq.cwiseInverse().asDiagonal() * fit.plant.C);
  Eigen::MatrixXd JtJ, grads;
  Eigen::VectorXd Jtr;
  double rho = 0.0;
  model.evaluate(theta, true, &JtJ, &Jtr, rho, &scaled, &grads);
  // Residuals are orthogonal to the regressors, so the replicates sum to zero: the
  // meat Σ g gᵀ has S − 1 degrees of freedom (the factor S / (S − 1)).
  const double S = static_cast<double>(replicates.size());
  const Eigen::MatrixXd meat = (S / (S - 1.0)) * (grads * grads.transpose());
  const Eigen::MatrixXd bread = normal_pseudo_inverse(model, theta, n, JtJ);
  const Eigen::MatrixXd cov_s = bread * meat * bread;
  fit.covariance = coordinate_map(n, m, p, st.su, st.sq).asDiagonal() * cov_s *
                   coordinate_map(n, m, p, st.su, st.sq).asDiagonal();
  fit.replicates = static_cast<Index>(replicates.size());
}

}  // namespace lpvid
