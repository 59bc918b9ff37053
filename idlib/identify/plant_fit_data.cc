// The plant fit's data and bands (plant_fit.h): the bins of ĝ's transform with their
// noise weights (make_markov_bins), and the variance of a fitted plant's response
// (plant_response_variance).  The fit itself: plant_fit.cc.
#include "idlib/identify/plant_fit.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "idlib/core/error.h"
#include "idlib/signal/real_fft.h"

namespace lpvid {

Index MarkovBins::real_residuals() const {
  if (response.empty()) return 0;
  const Index pm = response.front().size();
  Index r = 0;
  for (Index f = 0; f < num_bins(); ++f) r += (f == 0 || 2 * f == num_lags) ? pm : 2 * pm;
  return r;
}

MarkovBins make_markov_bins(const MarkovSequence& g, Index num_lags, Index num_bins,
                            const std::vector<Eigen::MatrixXcd>& noise_spectrum, const Eigen::MatrixXd& excitation_gram,
                            double sample_period_s, double relative_accuracy) {
  if (num_lags < 2) throw InputError(fmt::format("Markov bins: num_lags = {}; at least 2 are needed", num_lags));
  if (static_cast<Index>(g.size()) < num_lags + 1)
    throw InputError(fmt::format("Markov bins: g has {} lags but the transform needs {} (0..{})", g.size(), num_lags + 1,
                                 num_lags));
  if (num_bins < 1 || num_bins > num_lags / 2 + 1)
    throw InputError(fmt::format("Markov bins: {} bins asked of a {}-point transform; 1..{} are available", num_bins,
                                 num_lags, num_lags / 2 + 1));
  if (!(sample_period_s > 0.0)) throw InputError("Markov bins: the sample period must be > 0");
  const Index p = g.front().rows(), m = g.front().cols();
  if (static_cast<Index>(noise_spectrum.size()) != num_bins)
    throw InputError(fmt::format("Markov bins: {} noise spectra for {} bins", noise_spectrum.size(), num_bins));
  for (const auto& s : noise_spectrum)
    if (s.rows() != p || s.cols() != p || !s.allFinite())
      throw InputError(fmt::format("Markov bins: every noise spectrum must be a finite {}x{} matrix", p, p));
  if (excitation_gram.rows() != m || excitation_gram.cols() != m)
    throw InputError(fmt::format("Markov bins: excitation_gram is {}x{} for {} inputs", excitation_gram.rows(),
                                 excitation_gram.cols(), m));
  MarkovBins bins;
  bins.num_lags = num_lags;
  bins.sample_period_s = sample_period_s;
  bins.excitation_gram = excitation_gram;
  bins.omega_rad_s.resize(num_bins);
  for (Index f = 0; f < num_bins; ++f)
    bins.omega_rad_s(f) = 2.0 * M_PI * static_cast<double>(f) / (static_cast<double>(num_lags) * sample_period_s);
  bins.response.assign(static_cast<std::size_t>(num_bins), Eigen::MatrixXcd::Zero(p, m));
  signal_detail::RealFft fft(num_lags);
  auto in = signal_detail::alloc_real(num_lags);
  auto out = signal_detail::alloc_complex(fft.bins());
  for (Index i = 0; i < p; ++i)
    for (Index j = 0; j < m; ++j) {
      for (Index k = 0; k < num_lags; ++k) in[k] = g[static_cast<std::size_t>(k + 1)](i, j);
      fft.forward(in.get(), out.get());
      for (Index f = 0; f < num_bins; ++f)  // Σ_{k≥1} g[k] z^-k = z^-1 Σ_{k'≥0} g[k'+1] z^-k'
        bins.response[static_cast<std::size_t>(f)](i, j) =
            out[f] * std::polar(1.0, -2.0 * M_PI * static_cast<double>(f) / static_cast<double>(num_lags));
    }
  if (!(relative_accuracy > 0.0 && relative_accuracy < 1.0))
    throw InputError(fmt::format("Markov bins: relative accuracy {} must be in (0, 1)", relative_accuracy));
  Eigen::VectorXd floor = Eigen::VectorXd::Zero(p);
  for (Index f = 0; f < num_bins; ++f)
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < m; ++j)
        floor(i) = std::max(floor(i), std::norm(bins.response[static_cast<std::size_t>(f)](i, j)) *
                                          excitation_gram(j, j) / static_cast<double>(num_lags));
  floor *= relative_accuracy * relative_accuracy;
  floor = floor.cwiseMax(std::numeric_limits<double>::min());
  for (const auto& s : noise_spectrum) {
    Eigen::MatrixXcd h = 0.5 * (s + s.adjoint());
    h.diagonal().real() += floor;
    bins.noise_inverse.push_back(h.inverse());
  }
  return bins;
}

std::vector<Eigen::MatrixXd> plant_response_variance(const PlantFitResult& fit, const Eigen::VectorXd& omega_rad_s) {
  const StateSpace& P = fit.plant;
  const Index n = P.order(), m = P.num_inputs(), p = P.num_outputs();
  const Index np = n * n + n * m + p * n;
  if (fit.covariance.rows() != np || fit.covariance.cols() != np)
    throw InputError(fmt::format("plant response variance: covariance is {}x{} for {} parameters",
                                 fit.covariance.rows(), fit.covariance.cols(), np));
  std::vector<Eigen::MatrixXd> out;
  out.reserve(static_cast<std::size_t>(omega_rad_s.size()));
  const Eigen::MatrixXcd A = P.A.cast<Complex>(), B = P.B.cast<Complex>(), C = P.C.cast<Complex>();
  Eigen::MatrixXd Gre(np, p * m), Gim(np, p * m);
  for (Index w = 0; w < omega_rad_s.size(); ++w) {
    const Complex z = std::polar(1.0, omega_rad_s(w) * P.sample_period_s);
    Eigen::MatrixXcd Zm = -A;
    Zm.diagonal().array() += z;
    const Eigen::PartialPivLU<Eigen::MatrixXcd> lu(Zm);
    const Eigen::MatrixXcd X = lu.solve(B);                                    // n × m
    const Eigen::MatrixXcd Y = Eigen::PartialPivLU<Eigen::MatrixXcd>(Zm.transpose()).solve(C.transpose()).transpose();  // p × n
    Gre.setZero();
    Gim.setZero();
    for (Index l = 0; l < m; ++l)
      for (Index k = 0; k < p; ++k) {
        const Index e = k + l * p;
        for (Index j = 0; j < n; ++j)
          for (Index i = 0; i < n; ++i) {  // dP/dA(i,j) = Y(:,i) X(j,:)
            const Complex d = Y(k, i) * X(j, l);
            Gre(i + j * n, e) = d.real();
            Gim(i + j * n, e) = d.imag();
          }
        for (Index i = 0; i < n; ++i) {  // dP/dB(i,l) = Y(:,i) e_l
          Gre(n * n + i + l * n, e) = Y(k, i).real();
          Gim(n * n + i + l * n, e) = Y(k, i).imag();
        }
        for (Index j = 0; j < n; ++j) {  // dP/dC(k,j) = e_k X(j,:)
          Gre(n * n + n * m + k + j * p, e) = X(j, l).real();
          Gim(n * n + n * m + k + j * p, e) = X(j, l).imag();
        }
      }
    const Eigen::MatrixXd a = (Gre.transpose() * fit.covariance * Gre).diagonal();
    const Eigen::MatrixXd b = (Gim.transpose() * fit.covariance * Gim).diagonal();
    Eigen::MatrixXd v(p, m);
    for (Index l = 0; l < m; ++l)
      for (Index k = 0; k < p; ++k) v(k, l) = std::max(0.0, a(k + l * p) + b(k + l * p));
    out.push_back(v);
  }
  return out;
}

}  // namespace lpvid
