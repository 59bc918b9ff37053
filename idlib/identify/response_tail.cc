#include "idlib/identify/response_tail.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/lti/interconnect.h"
#include "idlib/signal/noise_spectrum.h"

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
    // ξ = modal state at time t, on plain arrays (real and imaginary parts apart; the
    // per-sample Eigen expressions on dynamic sizes cost ~100 ns a sample in temporaries),
    // over the inputs that are not identically zero; y(t + L) = Re(c ξ(t)) is taken per
    // block of samples as one real matrix product.
    const Index m = loop.num_inputs();
    std::vector<Index> inputs;
    for (Index j = 0; j < m; ++j)
      if ((excitation.col(j).array() != 0.0).any()) inputs.push_back(j);
    const Index ma = static_cast<Index>(inputs.size());
    std::vector<double> lr(static_cast<std::size_t>(K)), li(lr), xr(lr.size(), 0.0), xi(lr.size(), 0.0),
        br(static_cast<std::size_t>(K * ma)), bi(br);
    for (Index a = 0; a < K; ++a) {
      lr[static_cast<std::size_t>(a)] = l(a).real();
      li[static_cast<std::size_t>(a)] = l(a).imag();
      for (Index j = 0; j < ma; ++j) {
        br[static_cast<std::size_t>(a * ma + j)] = b(a, inputs[static_cast<std::size_t>(j)]).real();
        bi[static_cast<std::size_t>(a * ma + j)] = b(a, inputs[static_cast<std::size_t>(j)]).imag();
      }
    }
    Eigen::MatrixXd cri(2 * K, p);  // [Re c, −Im c]ᵀ
    cri.topRows(K) = c.real().transpose();
    cri.bottomRows(K) = -c.imag().transpose();
    constexpr Index kBlock = 512;
    // row s: [Re ξ, Im ξ] at t0 + s; row-major, so that each sample writes one run of memory
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> hist(kBlock, 2 * K);
    std::vector<double> u(static_cast<std::size_t>(std::max<Index>(ma, 1)));
    for (Index t0 = 0; t0 + lag < T; t0 += kBlock) {
      const Index len = std::min(kBlock, T - lag - t0);
      for (Index s = 0; s < len; ++s) {
        const Index t = t0 + s;
        for (Index a = 0; a < K; ++a) {
          hist(s, a) = xr[static_cast<std::size_t>(a)];
          hist(s, K + a) = xi[static_cast<std::size_t>(a)];
        }
        for (Index j = 0; j < ma; ++j) u[static_cast<std::size_t>(j)] = excitation(t, inputs[static_cast<std::size_t>(j)]);
        for (Index a = 0; a < K; ++a) {  // ξ ← λ ξ + b v(t)
          const std::size_t k = static_cast<std::size_t>(a);
          double nr = lr[k] * xr[k] - li[k] * xi[k], ni = lr[k] * xi[k] + li[k] * xr[k];
          for (Index j = 0; j < ma; ++j) {
            nr += br[static_cast<std::size_t>(a * ma + j)] * u[static_cast<std::size_t>(j)];
            ni += bi[static_cast<std::size_t>(a * ma + j)] * u[static_cast<std::size_t>(j)];
          }
          xr[k] = nr;
          xi[k] = ni;
        }
      }
      y.middleRows(t0 + lag, len).noalias() = hist.topRows(len) * cri;
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

std::vector<Eigen::MatrixXd> refit_response_beyond(const StateSpace& plant, const StateSpace& controller,
                                                   const std::vector<ExperimentView>& corrected,
                                                   const MarkovSequence& g, Index lag) {
  plant.validate();
  controller.validate();
  if (lag < 1) throw InputError(fmt::format("tail refit: lag {} < 1", lag));
  const Index m = plant.num_inputs(), p = plant.num_outputs();
  std::vector<Eigen::MatrixXd> out;
  for (const auto& x : corrected) {
    if (x.excitation.cols() != m || x.output.cols() != p || x.excitation.rows() != x.output.rows())
      throw InputError(fmt::format("tail refit: every experiment must have {} inputs and {} outputs over one record", m, p));
    out.push_back(Eigen::MatrixXd::Zero(x.output.rows(), p));
  }
  const StateSpace loop = closed_loop_output(plant, controller);
  const Eigen::EigenSolver<Eigen::MatrixXd> es(loop.A, false);
  if (es.info() != Eigen::Success) return out;
  std::vector<Complex> slow;  // one of each complex pair (Im > 0) and the real modes
  for (Index a = 0; a < loop.order(); ++a) {
    const Complex l = es.eigenvalues()(a);
    if (l.imag() < 0.0 || std::pow(std::abs(l), static_cast<double>(lag)) < kSlowModeTail) continue;
    slow.push_back(l);
  }
  if (slow.empty()) return out;
  // Regressor columns: (mode, input, part), part 0 = Re, 1 = Im (complex modes only).
  struct Column {
    std::size_t mode;
    Index input;
    int part;
  };
  std::vector<Column> cols;
  for (std::size_t i = 0; i < slow.size(); ++i)
    for (Index a = 0; a < m; ++a) {
      cols.push_back({i, a, 0});
      if (slow[i].imag() > 0.0) cols.push_back({i, a, 1});
    }
  const Index r = static_cast<Index>(cols.size());
  // Per experiment only the excited inputs' columns are non-zero: `act` lists them, and
  // U(t) is built row by row over those (never the N × r matrix): U(t + lag) = [Re, Im]
  // ξ_{i,a}(t), zero before.
  auto active_columns = [&](const ExperimentView& x) {
    std::vector<Index> act;
    for (Index c = 0; c < r; ++c) {
      const auto col = x.excitation.col(cols[static_cast<std::size_t>(c)].input);
      if ((col.array() != 0.0).any()) act.push_back(c);
    }
    return act;
  };
  auto for_each_row = [&](const ExperimentView& x, const std::vector<Index>& act, const auto& visit) {
    const Index n = x.excitation.rows(), na = static_cast<Index>(act.size());
    std::vector<Complex> xi(static_cast<std::size_t>(na), Complex(0.0));
    Eigen::VectorXd u = Eigen::VectorXd::Zero(na);
    for (Index t = 0; t < n; ++t) {
      if (t >= lag) {
        for (Index k = 0; k < na; ++k) {
          const Column& c = cols[static_cast<std::size_t>(act[static_cast<std::size_t>(k)])];
          Complex& z = xi[static_cast<std::size_t>(k)];
          u(k) = c.part == 0 ? z.real() : z.imag();
          // the Im column shares ξ with the Re column before it: advance ξ once, at the last part
          const bool last = c.part == 1 || slow[c.mode].imag() <= 0.0;
          if (c.part == 0 && !last) continue;  // advanced with its Im column
          z = slow[c.mode] * z + x.excitation(t - lag, c.input);
          if (c.part == 1) xi[static_cast<std::size_t>(k - 1)] = z;
        }
      }
      visit(t, u);
    }
  };
  // Centred per experiment (the offset is part of the model): Σ (u − ū)(u − ū)ᵀ and
  // Σ (u − ū) eᵀ, e of zero mean.
  Eigen::MatrixXd UtU = Eigen::MatrixXd::Zero(r, r), Ute = Eigen::MatrixXd::Zero(r, p);
  std::vector<Eigen::VectorXd> means;
  std::vector<std::vector<Index>> acts;
  Eigen::MatrixXd e;
  for (const auto& x : corrected) {
    const std::vector<Index> act = active_columns(x);
    const Index na = static_cast<Index>(act.size());
    fir_residual(x, g, nullptr, e);
    constexpr Index kBlock = 1024;  // rows gathered per matrix product
    Eigen::MatrixXd Ub(kBlock, na), Eb(kBlock, p), uu = Eigen::MatrixXd::Zero(na, na), ue = Eigen::MatrixXd::Zero(na, p);
    Eigen::VectorXd sum = Eigen::VectorXd::Zero(na);
    Index filled = 0;
    auto flush = [&] {
      uu.noalias() += Ub.topRows(filled).transpose() * Ub.topRows(filled);
      ue.noalias() += Ub.topRows(filled).transpose() * Eb.topRows(filled);  // Σ ū eᵀ = 0
      filled = 0;
    };
    for_each_row(x, act, [&](Index t, const Eigen::VectorXd& u) {
      sum += u;
      Ub.row(filled) = u.transpose();
      Eb.row(filled) = e.row(t);
      if (++filled == kBlock) flush();
    });
    flush();
    const double n = static_cast<double>(x.excitation.rows());
    const Eigen::VectorXd mean = sum / n;
    uu -= n * mean * mean.transpose();
    Eigen::VectorXd full_mean = Eigen::VectorXd::Zero(r);
    for (Index k = 0; k < na; ++k) {
      full_mean(act[static_cast<std::size_t>(k)]) = mean(k);
      Ute.row(act[static_cast<std::size_t>(k)]) += ue.row(k);
      for (Index l = 0; l < na; ++l) UtU(act[static_cast<std::size_t>(k)], act[static_cast<std::size_t>(l)]) += uu(k, l);
    }
    means.push_back(full_mean);
    acts.push_back(act);
  }
  // Columns of inputs never excited are zero: a pseudo-inverse leaves them at zero.
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(UtU);
  const Eigen::MatrixXd dc = cod.solve(Ute);
  for (std::size_t k = 0; k < corrected.size(); ++k) {
    const std::vector<Index>& act = acts[k];
    Eigen::MatrixXd dca(static_cast<Index>(act.size()), p);
    for (std::size_t c = 0; c < act.size(); ++c) dca.row(static_cast<Index>(c)) = dc.row(act[c]);
    const Eigen::RowVectorXd offset = means[k].transpose() * dc;
    for_each_row(corrected[k], act, [&](Index t, const Eigen::VectorXd& u) { out[k].row(t) = u.transpose() * dca - offset; });
  }
  return out;
}

}  // namespace lpvid
