// lpvid — the Local Polynomial Method (lpm.h; docs/math.md).
#include "idlib/signal/lpm.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "idlib/signal/real_fft.h"

namespace lpvid {

using signal_detail::alloc_complex;
using signal_detail::alloc_real;
using signal_detail::RealFft;

namespace signal_detail {

LocalDfts local_dfts(const std::vector<ExperimentView>& experiments, Index plant_inputs, bool remove_mean,
                     const char* method) {
  if (experiments.empty()) throw InputError("no experiments; give at least one log");
  LocalDfts d;
  d.E = static_cast<Index>(experiments.size());
  d.N = experiments[0].excitation.rows();
  d.m = experiments[0].excitation.cols();
  d.nz = experiments[0].output.cols();
  const Index N = d.N;
  if (d.m < 1) throw InputError("no excitation column; give at least one");
  for (Index e = 0; e < d.E; ++e) {
    const auto& x = experiments[static_cast<size_t>(e)];
    if (x.excitation.rows() != N || x.output.rows() != N)
      throw InputError(fmt::format("experiment {} has {} / {} samples but experiment 1 has {}; the {} needs records "
                                   "of one length",
                                   e + 1, x.excitation.rows(), x.output.rows(), N, method));
    if (x.excitation.cols() != d.m || x.output.cols() != d.nz)
      throw InputError(fmt::format("experiment {} has {} excitation and {} measured columns, experiment 1 {} and {}", e + 1,
                                   x.excitation.cols(), x.output.cols(), d.m, d.nz));
    if (!x.excitation.allFinite() || !x.output.allFinite())
      throw InputError(fmt::format("experiment {} holds a NaN or Inf sample; give finite samples", e + 1));
  }
  if (plant_inputs != 0 && plant_inputs != d.m)
    throw InputError(fmt::format("{} plant input columns for {} excitation columns; give one plant input per excitation",
                                 plant_inputs, d.m));
  d.ny = d.nz - plant_inputs;
  if (d.ny < 1) throw InputError("no output column besides the plant inputs; give at least one output");
  d.kmax = (N - 1) / 2;

  // One DFT of each whole record, every channel.
  const Index nb = N / 2 + 1;
  RealFft fft(N);
  auto in = alloc_real(N);
  auto out = alloc_complex(nb);
  d.U.resize(static_cast<size_t>(d.E));
  d.Z.resize(static_cast<size_t>(d.E));
  auto transform = [&](const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::MatrixXcd& X) {
    X.resize(d.kmax + 1, x.cols());
    for (Index c = 0; c < x.cols(); ++c) {
      const double mean = remove_mean ? x.col(c).mean() : 0.0;
      for (Index t = 0; t < N; ++t) in[t] = x(t, c) - mean;
      fft.forward(in.get(), out.get());
      for (Index k = 0; k <= d.kmax; ++k) X(k, c) = out[k];
    }
  };
  for (Index e = 0; e < d.E; ++e) {
    transform(experiments[static_cast<size_t>(e)].excitation, d.U[static_cast<size_t>(e)]);
    transform(experiments[static_cast<size_t>(e)].output, d.Z[static_cast<size_t>(e)]);
  }
  return d;
}

Index local_half_width(Index given, Index npar, Index nz, const LocalDfts& d, const char* method) {
  Index n = given;
  if (n == 0) {
    n = 1;
    while (d.E * (2 * n + 1) - npar < std::max(kLpmMinDof, nz)) ++n;
  }
  const Index width = 2 * n + 1, q = d.E * width - npar;
  if (q < 1)
    throw InputError(fmt::format("{} half width {} leaves {} degrees of freedom for {} parameters per output; give a "
                                 "larger half width",
                                 method, n, q, npar));
  if (d.kmax < width)
    throw InputError(fmt::format("{} samples give {} frequency bins, fewer than the {} window of {}; record longer",
                                 d.N, d.kmax, method, width));
  return n;
}

void local_output_grid(const LocalDfts& d, Index first_bin, Index stride, double sample_period_s,
                       std::vector<Index>& bins, FrequencyResponse& frd) {
  bins.clear();
  for (Index k = first_bin; k <= d.kmax; k += stride) bins.push_back(k);
  const Index F = static_cast<Index>(bins.size());
  frd.omega_rad_s.resize(F);
  for (Index f = 0; f < F; ++f)
    frd.omega_rad_s(f) = 2.0 * std::numbers::pi * static_cast<double>(bins[static_cast<size_t>(f)]) /
                         (static_cast<double>(d.N) * sample_period_s);
  frd.response.assign(static_cast<size_t>(F), Eigen::MatrixXcd::Zero(d.ny, d.m));
  frd.variance.assign(static_cast<size_t>(F), Eigen::MatrixXd::Zero(d.ny, d.m));
  frd.flagged.assign(static_cast<size_t>(F), false);
}

bool plant_from_local_fit(const Eigen::MatrixXcd& Gz, Index plant_inputs, double max_condition, Eigen::MatrixXcd& G,
                          Eigen::MatrixXcd& W, Eigen::MatrixXcd& Sinv) {
  const Index nz = Gz.rows(), m = Gz.cols();
  if (plant_inputs == 0) {
    G = Gz;
    W = Eigen::MatrixXcd::Identity(nz, nz);
    Sinv = Eigen::MatrixXcd::Identity(m, m);
    return true;
  }
  const Index ny = nz - m;
  Eigen::PartialPivLU<Eigen::MatrixXcd> lu(Gz.bottomRows(m));
  const double src = lu.rcond();
  if (!(src > 0) || 1.0 / src > max_condition) return false;
  Sinv = lu.inverse();
  G = Gz.topRows(ny) * Sinv;
  W.resize(ny, nz);
  W << Eigen::MatrixXcd::Identity(ny, ny), -G;
  return true;
}

}  // namespace signal_detail

void LpmOptions::validate() const {
  if (order < 0 || order > 4) throw InputError(fmt::format("LPM order {}: give 0..4 (2 is the usual choice)", order));
  if (half_width < 0) throw InputError(fmt::format("LPM half width {} is negative; give n >= 1 or 0 (automatic)", half_width));
  if (!(std::isfinite(sample_period_s) && sample_period_s > 0))
    throw InputError(fmt::format("sample period {} s: give a finite sample period > 0", sample_period_s));
  if (first_bin < 1) throw InputError(fmt::format("first bin {}: give >= 1", first_bin));
  if (stride < 1) throw InputError(fmt::format("bin stride {}: give >= 1", stride));
  if (!(max_condition > 1)) throw InputError(fmt::format("max_condition {} must be > 1", max_condition));
}

LpmResult estimate_lpm_frf(const std::vector<ExperimentView>& experiments, Index plant_inputs,
                           const LpmOptions& options) {
  options.validate();
  const signal_detail::LocalDfts dft = signal_detail::local_dfts(experiments, plant_inputs, options.remove_mean, "LPM");
  const Index E = dft.E, m = dft.m, nz = dft.nz, kmax = dft.kmax;
  const auto& U = dft.U;
  const auto& Z = dft.Z;
  const Index R1 = options.order + 1, npar = R1 * (m + E);
  const Index n = signal_detail::local_half_width(options.half_width, npar, nz, dft, "LPM");
  const Index width = 2 * n + 1, q = E * width - npar;

  LpmResult result;
  result.half_width = n;
  result.dof = q;
  FrequencyResponse& frd = result.frd;
  signal_detail::local_output_grid(dft, options.first_bin, options.stride, options.sample_period_s, result.bins, frd);
  const Index F = static_cast<Index>(result.bins.size());
  Eigen::MatrixXcd K(npar, E * width), Zw(nz, E * width);
  Eigen::VectorXd powers(R1);
  // Work space reused for every bin (allocation would dominate the small solves).
  Eigen::VectorXd d(npar);
  Eigen::MatrixXcd Ks(npar, E * width), gram(npar, npar), Q(npar, npar), ZK(nz, npar), Theta(nz, npar),
      resid(nz, E * width), Cv(nz, nz), Gz(nz, m), Qgg(m, m);
  const Eigen::MatrixXcd identity = Eigen::MatrixXcd::Identity(npar, npar);
  Eigen::LDLT<Eigen::MatrixXcd> ldlt(npar);
  Index nflag = 0;
  // About kProgressReports reports over the run (the renderer shows at most 10 a second).
  constexpr Index kProgressReports = 200;
  const Index report_every = std::max<Index>(1, F / kProgressReports);
  for (Index f = 0; f < F; ++f) {
    if (options.progress != nullptr && f % report_every == 0)
      options.progress->report({"frf lpm", "frequency line", f + 1, F, "", -1.0});
    const Index k = result.bins[static_cast<size_t>(f)];
    const Index start = std::clamp<Index>(k - n, 1, kmax - width + 1);
    K.setZero();
    for (Index e = 0; e < E; ++e)
      for (Index w = 0; w < width; ++w) {
        const Index j = start + w, col = e * width + w;
        // Offsets scaled by n: the same fit, better conditioned powers.
        const double r = static_cast<double>(j - k) / static_cast<double>(n);
        powers(0) = 1;
        for (Index s = 1; s < R1; ++s) powers(s) = powers(s - 1) * r;
        for (Index a = 0; a < m; ++a)
          for (Index s = 0; s < R1; ++s) K(a * R1 + s, col) = U[static_cast<size_t>(e)](j, a) * powers(s);
        for (Index s = 0; s < R1; ++s) K(m * R1 + e * R1 + s, col) = powers(s);
        Zw.col(col) = Z[static_cast<size_t>(e)].row(j).transpose();
      }
    // Row scaling D (unit row norms) for conditioning: Q = D (D K Kᴴ D)⁻¹ D.
    d = K.rowwise().norm().cwiseMax(1e-300).cwiseInverse();
    Ks.noalias() = d.asDiagonal() * K;
    gram.noalias() = Ks * Ks.adjoint();
    ldlt.compute(gram);
    const double rc = ldlt.rcond();
    if (ldlt.info() != Eigen::Success || !(rc > 0) || 1.0 / rc > options.max_condition) {
      frd.flagged[static_cast<size_t>(f)] = true;
      ++nflag;
      continue;
    }
    Q = ldlt.solve(identity);
    Q = d.asDiagonal() * Q * d.asDiagonal();
    ZK.noalias() = Zw * K.adjoint();
    Theta.noalias() = ZK * Q;  // nz × npar
    resid = Zw;
    resid.noalias() -= Theta * K;
    Cv.noalias() = resid * resid.adjoint();
    Cv /= static_cast<double>(q);
    for (Index a = 0; a < m; ++a) {
      Gz.col(a) = Theta.col(a * R1);
      for (Index b = 0; b < m; ++b) Qgg(a, b) = Q(a * R1, b * R1);
    }
    Eigen::MatrixXcd G, W, Sinv;
    if (!signal_detail::plant_from_local_fit(Gz, plant_inputs, options.max_condition, G, W, Sinv)) {
      frd.flagged[static_cast<size_t>(f)] = true;
      ++nflag;
      continue;
    }
    const Eigen::VectorXd wcw = (W * Cv * W.adjoint()).diagonal().real();
    for (Index j = 0; j < m; ++j) {
      // Cov(δG(:,a), δG(:,b)) = Q(b, a) Ĉ_V, so E δP(:,j) δP(:,j)ᴴ = (sᴴ Q_GG s) W Ĉ_V Wᴴ.
      const Eigen::VectorXcd s = Sinv.col(j);
      const double factor = std::max(0.0, (s.adjoint() * Qgg * s)(0, 0).real());
      frd.variance[static_cast<size_t>(f)].col(j) = factor * wcw;
    }
    frd.response[static_cast<size_t>(f)] = G;
  }
  if (nflag > 0)
    result.report.warnings.push_back(fmt::format("{} bin(s) flagged: the local regression or Ŝ is singular there", nflag));
  result.report.termination = fmt::format("LPM order {}, {} bins per window (n = {}), {} degrees of freedom, {} bins",
                                          options.order, width, n, q, F);
  return result;
}

}  // namespace lpvid
