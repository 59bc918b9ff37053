// lpvid — the Local Rational Method (lrm.h; docs/math.md 4d).
#include "idlib/signal/lrm.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>

namespace lpvid {
namespace {
// Added to the diagonal of the denominator block of the row-normalised Gram matrix (unit
// diagonal) only when that matrix is singular beyond max_condition: it bounds the
// block's condition near 1e8, below the default max_condition 1e10, and shifts a
// well-determined denominator by a relative ~1e-8 · cond, i.e. nothing one can measure.
constexpr double kLrmDenominatorRidge = 1e-8;

// The reciprocal condition of a Hermitian positive semi-definite matrix as the pivoted
// LDLᵀ sees it: min D / max D (a lower bound of the condition; Eigen's rcond() gives a
// sharper estimate by several extra solves, which here cost more than the fit).
double pivot_ratio(const Eigen::LDLT<Eigen::MatrixXcd>& ldlt) {
  if (ldlt.info() != Eigen::Success) return 0;
  const Eigen::VectorXd d = ldlt.vectorD().real();
  const double hi = d.maxCoeff();
  return hi > 0 ? std::max(0.0, d.minCoeff()) / hi : 0;
}
}  // namespace

void LrmOptions::validate() const {
  if (numerator_degree < 0 || numerator_degree > 4)
    throw InputError(fmt::format("LRM numerator degree {}: give 0..4 (2 is the usual choice)", numerator_degree));
  if (denominator_degree < 1 || denominator_degree > 4)
    throw InputError(fmt::format("LRM denominator degree {}: give 1..4 (2 holds one mode per window)", denominator_degree));
  if (half_width < 0) throw InputError(fmt::format("LRM half width {} is negative; give n >= 1 or 0 (automatic)", half_width));
  if (sk_iterations < 0 || sk_iterations > 20)
    throw InputError(fmt::format("LRM reweighting steps {}: give 0..20", sk_iterations));
  if (!(std::isfinite(sample_period_s) && sample_period_s > 0))
    throw InputError(fmt::format("sample period {} s: give a finite sample period > 0", sample_period_s));
  if (first_bin < 1) throw InputError(fmt::format("first bin {}: give >= 1", first_bin));
  if (stride < 1) throw InputError(fmt::format("bin stride {}: give >= 1", stride));
  if (!(max_condition > 1)) throw InputError(fmt::format("max_condition {} must be > 1", max_condition));
}

LrmResult estimate_lrm_frf(const std::vector<ExperimentView>& experiments, Index plant_inputs,
                           const LrmOptions& options) {
  options.validate();
  const signal_detail::LocalDfts dft = signal_detail::local_dfts(experiments, plant_inputs, options.remove_mean, "LRM");
  const Index E = dft.E, m = dft.m, nz = dft.nz, kmax = dft.kmax;
  const Index Rn1 = options.numerator_degree + 1, Rd = options.denominator_degree;
  const Index npar = Rn1 * (m + E) + Rd;  // per output row: [n_a,s ; t_e,s ; d_s]
  const Index dcol = Rn1 * (m + E);       // first denominator parameter
  const Index n = signal_detail::local_half_width(options.half_width, npar, nz, dft, "LRM");
  const Index width = 2 * n + 1, L = E * width, q = L - npar;

  LrmResult result;
  result.half_width = n;
  result.dof = q;
  FrequencyResponse& frd = result.frd;
  signal_detail::local_output_grid(dft, options.first_bin, options.stride, options.sample_period_s, result.bins, frd);
  const Index F = static_cast<Index>(result.bins.size());

  // Work space reused for every bin and row (allocation would dominate the small solves).
  const Index P = std::max(Rn1, Rd + 1);
  Eigen::MatrixXd powers(L, P);  // ρ^s at each window column
  Eigen::MatrixXcd K0(npar, L), K(npar, L), Ks(npar, L), gram(npar, npar), eps(nz, L), Gz(nz, m), V(L, nz);
  Eigen::RowVectorXcd zw(L), zt(L), theta(npar);
  Eigen::VectorXcd rhs(npar), unit(npar), qcol(npar);
  Eigen::VectorXd weight(L), d(npar);
  std::vector<Eigen::MatrixXcd> AG(static_cast<size_t>(nz), Eigen::MatrixXcd(L, m));
  Eigen::LDLT<Eigen::MatrixXcd> ldlt(npar);
  Index nflag = 0, ridged = 0;
  // About kProgressReports reports over the run (the renderer shows at most 10 a second).
  constexpr Index kProgressReports = 200;
  const Index report_every = std::max<Index>(1, F / kProgressReports);
  for (Index f = 0; f < F; ++f) {
    if (options.progress != nullptr && f % report_every == 0)
      options.progress->report({"frf lrm", "frequency line", f + 1, F, "", -1.0});
    const Index k = result.bins[static_cast<size_t>(f)];
    const Index start = std::clamp<Index>(k - n, 1, kmax - width + 1);
    // The row-independent part of the regressor: numerators of G and of the transients.
    K0.setZero();
    for (Index e = 0; e < E; ++e)
      for (Index w = 0; w < width; ++w) {
        const Index j = start + w, col = e * width + w;
        // Offsets scaled by n: the same fit, better conditioned powers.
        const double r = static_cast<double>(j - k) / static_cast<double>(n);
        powers(col, 0) = 1;
        for (Index s = 1; s < P; ++s) powers(col, s) = powers(col, s - 1) * r;
        for (Index a = 0; a < m; ++a)
          for (Index s = 0; s < Rn1; ++s) K0(a * Rn1 + s, col) = dft.U[static_cast<size_t>(e)](j, a) * powers(col, s);
        for (Index s = 0; s < Rn1; ++s) K0(m * Rn1 + e * Rn1 + s, col) = powers(col, s);
      }
    bool singular = false;
    for (Index i = 0; i < nz && !singular; ++i) {
      // Row i's denominator regressors −ρ^s Z_i(k+r) (Levy's linearisation).
      for (Index e = 0; e < E; ++e)
        for (Index w = 0; w < width; ++w) {
          const Index col = e * width + w;
          const Complex z = dft.Z[static_cast<size_t>(e)](start + w, i);
          zw(col) = z;
          for (Index s = 1; s <= Rd; ++s) K0(dcol + s - 1, col) = -powers(col, s) * z;
        }
      weight.setOnes();
      for (int it = 0; it <= options.sk_iterations; ++it) {
        K.noalias() = K0 * weight.asDiagonal();
        zt = zw.cwiseProduct(weight.transpose());
        // Row scaling (unit row norms) for conditioning: Q = D (D K̃ K̃ᴴ D)⁻¹ D.
        d = K.rowwise().squaredNorm().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
        Ks.noalias() = d.asDiagonal() * K;
        gram.noalias() = Ks * Ks.adjoint();
        ldlt.compute(gram);
        double rc = pivot_ratio(ldlt);
        if (ldlt.info() != Eigen::Success || !(rc > 0) || 1.0 / rc > options.max_condition) {
          // Nearly exact local data (little noise) leave the denominator undetermined up to a
          // common factor c(ρ) of numerators and denominator (c(0) = 1, so Ĝ = n_0 is not);
          // a ridge on the denominator block picks the smallest such denominator.  Still
          // singular: the input or transient block is (no excitation in the window): flag.
          for (Index s = 0; s < Rd; ++s) gram(dcol + s, dcol + s) += kLrmDenominatorRidge;
          ldlt.compute(gram);
          rc = pivot_ratio(ldlt);
          ++ridged;
          if (ldlt.info() != Eigen::Success || !(rc > 0) || 1.0 / rc > options.max_condition) {
            singular = true;
            break;
          }
        }
        // θ = z̃ K̃ᴴ Q, i.e. θᴴ = D (D K̃ K̃ᴴ D)⁻¹ D K̃ z̃ᴴ.
        rhs.noalias() = Ks * zt.adjoint();
        theta = (d.asDiagonal() * ldlt.solve(rhs)).adjoint();
        if (it == options.sk_iterations) break;
        // Sanathanan–Koerner: the next solve divides each equation by |D̂(ρ)|.
        for (Index c = 0; c < L; ++c) {
          Complex den = 1.0;
          for (Index s = 1; s <= Rd; ++s) den += theta(dcol + s - 1) * powers(c, s);
          weight(c) = std::sqrt(std::norm(den));
        }
        const double floor = 1e-8 * weight.maxCoeff();
        for (Index c = 0; c < L; ++c) weight(c) = 1.0 / std::max(weight(c), floor);
      }
      if (singular) break;
      eps.row(i) = zt;
      eps.row(i).noalias() -= theta * K;
      // A_G = K̃ᴴ Q(:, G columns): Q(:, g) = D (D K̃ K̃ᴴ D)⁻¹ D e_g.
      for (Index a = 0; a < m; ++a) {
        Gz(i, a) = theta(a * Rn1);
        unit.setZero();
        unit(a * Rn1) = d(a * Rn1);
        qcol = d.asDiagonal() * ldlt.solve(unit);
        AG[static_cast<size_t>(i)].col(a).noalias() = K.adjoint() * qcol;
      }
    }
    Eigen::MatrixXcd G, W, Sinv;
    if (singular || !signal_detail::plant_from_local_fit(Gz, plant_inputs, options.max_condition, G, W, Sinv)) {
      frd.flagged[static_cast<size_t>(f)] = true;
      ++nflag;
      continue;
    }
    const Eigen::MatrixXcd C = eps * eps.adjoint() / static_cast<double>(q);  // ĉ_kl
    for (Index j = 0; j < m; ++j) {
      // δP(:,j) = W δGz s; E δGz_ka conj(δGz_lb) = ĉ_kl (A_lᴴ A_k)(b, a), so with v_k = A_k,G s
      // E|δP_ij|² = (W (Ĉ ∘ Hᵀ) Wᴴ)_ii, H = Vᴴ V.
      const Eigen::VectorXcd s = Sinv.col(j);
      for (Index i = 0; i < nz; ++i) V.col(i).noalias() = AG[static_cast<size_t>(i)] * s;
      const Eigen::MatrixXcd H = V.adjoint() * V;
      const Eigen::MatrixXcd CH = C.cwiseProduct(H.transpose());
      frd.variance[static_cast<size_t>(f)].col(j) = (W * CH * W.adjoint()).diagonal().real().cwiseMax(0.0);
    }
    frd.response[static_cast<size_t>(f)] = G;
  }
  if (nflag > 0)
    result.report.warnings.push_back(fmt::format("{} bin(s) flagged: the local regression or Ŝ is singular there", nflag));
  if (ridged > 0)
    result.report.warnings.push_back(fmt::format("{} local solve(s) needed the denominator ridge (data nearly exact "
                                                 "there: the rational model has a common factor)",
                                                 ridged));
  result.report.termination =
      fmt::format("LRM numerator degree {}, denominator degree {}, {} reweighting step(s), {} bins per window (n = {}), "
                  "{} degrees of freedom, {} bins",
                  options.numerator_degree, options.denominator_degree, options.sk_iterations, width, n, q, F);
  return result;
}

}  // namespace lpvid
