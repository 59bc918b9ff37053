#include "idlib/signal/real_fft.h"

#include <algorithm>
#include <functional>
#include <mutex>

#include "idlib/core/error.h"
#include "idlib/core/parallel.h"

namespace lpvid::signal_detail {
namespace {

// FFTW's planner and plan destruction are not thread-safe (FFTW manual, "Thread
// safety"); fftw_execute_* on an existing plan is.
std::mutex& fftw_planner_mutex() {
  static std::mutex m;
  return m;
}

// Block FFT size for the blocked kernels: at least this many points, and at least
// kBlockLagFactor times the lag span, so that the max_lag overlap wasted per block
// stays a small fraction.  Measured (thread CPU time, 3x3 channels x 1e6 samples x
// 2000 lags): 8192 -> 26 ms, 16384 -> 20-22 ms, 32768 -> 34 ms.
constexpr Index kMinBlockFftSize = 16384;
constexpr Index kBlockLagFactor = 4;
// accumulate_cross_correlation runs its blocks as this many tasks (parallel.h): two
// cores on the reference machine; a fixed number, so that the sums do not depend on
// the machine.
constexpr Index kCorrelationChunks = 2;


// buf[0..len) = channel values at t = t_begin .. t_begin+len-1 (zero outside [0, n)).
void load(const ChannelView& ch, Index n, Index t_begin, Index len, double* buf) {
  const Index lo = std::max<Index>(t_begin, 0);
  const Index hi = std::min<Index>(t_begin + len, n);
  Index i = 0;
  for (; i < lo - t_begin && i < len; ++i) buf[i] = 0.0;
  const double* src = ch.data;
  const double off = ch.offset;
  for (Index t = lo; t < hi; ++t, ++i) buf[i] = src[t] - off;
  for (; i < len; ++i) buf[i] = 0.0;
}

}  // namespace

// acc[b] += a[b] * c[b] over nb bins, written on doubles so it vectorises.
void mac(const Complex* a, const Complex* c, Complex* acc, Index nb) {
  const double* ad = reinterpret_cast<const double*>(a);
  const double* cd = reinterpret_cast<const double*>(c);
  double* sd = reinterpret_cast<double*>(acc);
  for (Index b = 0; b < nb; ++b) {
    const double ar = ad[2 * b], ai = ad[2 * b + 1];
    const double cr = cd[2 * b], ci = cd[2 * b + 1];
    sd[2 * b] += ar * cr - ai * ci;
    sd[2 * b + 1] += ar * ci + ai * cr;
  }
}

// acc[b] += a[b] * conj(c[b]) over nb bins, written on doubles so it vectorises.
void mac_conj(const Complex* a, const Complex* c, Complex* acc, Index nb) {
  const double* ad = reinterpret_cast<const double*>(a);
  const double* cd = reinterpret_cast<const double*>(c);
  double* sd = reinterpret_cast<double*>(acc);
  for (Index b = 0; b < nb; ++b) {
    const double ar = ad[2 * b], ai = ad[2 * b + 1];
    const double cr = cd[2 * b], ci = cd[2 * b + 1];
    sd[2 * b] += ar * cr + ai * ci;
    sd[2 * b + 1] += ai * cr - ar * ci;
  }
}

RealArray alloc_real(Index n) {
  auto* p = fftw_alloc_real(static_cast<size_t>(std::max<Index>(n, 1)));
  if (p == nullptr) throw std::bad_alloc();
  return RealArray(p);
}

ComplexArray alloc_complex(Index n) {
  auto* p = fftw_alloc_complex(static_cast<size_t>(std::max<Index>(n, 1)));
  if (p == nullptr) throw std::bad_alloc();
  auto* c = reinterpret_cast<Complex*>(p);
  std::fill(c, c + std::max<Index>(n, 1), Complex(0.0, 0.0));
  return ComplexArray(c);
}

Index next_pow2(Index n) {
  Index p = 1;
  while (p < n) p *= 2;
  return p;
}

RealFft::RealFft(Index n) : n_(n) {
  LPVID_ASSERT(n >= 2);
  RealArray r = alloc_real(n);
  ComplexArray c = alloc_complex(n / 2 + 1);
  auto* fc = reinterpret_cast<fftw_complex*>(c.get());
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  forward_ = fftw_plan_dft_r2c_1d(static_cast<int>(n), r.get(), fc, FFTW_ESTIMATE);
  inverse_ = fftw_plan_dft_c2r_1d(static_cast<int>(n), fc, r.get(), FFTW_ESTIMATE);
  LPVID_ASSERT(forward_ != nullptr && inverse_ != nullptr);
}

RealFft::~RealFft() {
  std::lock_guard<std::mutex> lock(fftw_planner_mutex());
  fftw_destroy_plan(forward_);
  fftw_destroy_plan(inverse_);
}

void RealFft::forward(const double* in, Complex* out) const {
  fftw_execute_dft_r2c(forward_, const_cast<double*>(in), reinterpret_cast<fftw_complex*>(out));
}

void RealFft::inverse(Complex* in, double* out) const {
  fftw_execute_dft_c2r(inverse_, reinterpret_cast<fftw_complex*>(in), out);
}

Index next_fft_size(Index n) {
  Index best = next_pow2(n);
  for (Index three = 3; three < best; three *= 3) {  // 3^b 2^a for b >= 1
    Index size = three;
    while (size < n) size *= 2;
    best = std::min(best, size);
  }
  return best;
}

Index block_fft_size(Index n, Index max_lag) {
  const Index wanted = next_fft_size(std::max(kMinBlockFftSize, kBlockLagFactor * (max_lag + 1)));
  // A short record needs no more than one block: n + max_lag points avoid wrap-around.
  // That block stays a power of two: the golden Markov parameters (tests/golden, 10
  // digits of each channel's peak) were made with its round-off, and a 2^a 3^b block
  // moved them by 7e-10 of the peak (their normal equations amplify round-off ~1e6x).
  const Index enough = next_pow2(std::max<Index>(n + max_lag + 1, 2));
  return std::min(wanted, enough);
}

void accumulate_cross_correlation(const std::vector<ChannelView>& xs,
                                  const std::vector<ChannelView>& ys, Index n, Index max_lag,
                                  std::vector<Eigen::MatrixXd>& out) {
  const Index nx = static_cast<Index>(xs.size());
  const Index ny = static_cast<Index>(ys.size());
  LPVID_ASSERT(static_cast<Index>(out.size()) == max_lag + 1);
  if (nx == 0 || ny == 0 || n == 0) return;
  const Index M = block_fft_size(n, max_lag);
  // Circular correlation of an M-point x segment with a B-point (zero-padded) y
  // block is free of wrap-around for lags 0..max_lag when B + max_lag <= M.
  const Index B = M - max_lag;
  LPVID_ASSERT(B >= 1);
  const RealFft fft(M);
  const Index nb = fft.bins();

  // The blocks are split into kCorrelationChunks contiguous runs, one task each (own
  // buffers and cross-spectra), summed in order at the end (parallel.h).
  const Index blocks = (n + B - 1) / B;
  const Index chunks = std::min(kCorrelationChunks, blocks);
  std::vector<ComplexArray> accs(static_cast<std::size_t>(chunks));
  parallel_for(chunks, [&](Index c) {
    RealArray buf = alloc_real(M);
    ComplexArray xspec = alloc_complex(nx * nb);
    ComplexArray yspec = alloc_complex(ny * nb);
    ComplexArray acc = alloc_complex(nx * ny * nb);  // acc[(i*ny + j)*nb + b]
    for (Index blk = c * blocks / chunks; blk < (c + 1) * blocks / chunks; ++blk) {
      const Index t0 = blk * B;
      for (Index j = 0; j < ny; ++j) {
        if (!ys[j].active) continue;
        load(ys[j], n, t0, B, buf.get());
        std::fill(buf.get() + B, buf.get() + M, 0.0);
        fft.forward(buf.get(), yspec.get() + j * nb);
      }
      for (Index i = 0; i < nx; ++i) {
        if (!xs[i].active) continue;
        load(xs[i], n, t0, M, buf.get());
        fft.forward(buf.get(), xspec.get() + i * nb);
        for (Index j = 0; j < ny; ++j) {
          if (!ys[j].active) continue;
          mac_conj(xspec.get() + i * nb, yspec.get() + j * nb, acc.get() + (i * ny + j) * nb, nb);
        }
      }
    }
    accs[static_cast<std::size_t>(c)] = std::move(acc);
  });
  Complex* acc = accs.front().get();
  for (Index c = 1; c < chunks; ++c) {
    double* a = reinterpret_cast<double*>(acc);
    const double* b = reinterpret_cast<const double*>(accs[static_cast<std::size_t>(c)].get());
    for (Index k = 0; k < 2 * nx * ny * nb; ++k) a[k] += b[k];
  }
  // The sum over blocks of circular correlations is the inverse FFT of the summed
  // cross-spectra: one inverse transform per channel pair.
  RealArray buf = alloc_real(M);
  const double scale = 1.0 / static_cast<double>(M);
  for (Index i = 0; i < nx; ++i) {
    if (!xs[i].active) continue;
    for (Index j = 0; j < ny; ++j) {
      if (!ys[j].active) continue;
      fft.inverse(acc + (i * ny + j) * nb, buf.get());
      for (Index tau = 0; tau <= max_lag; ++tau) out[tau](i, j) += buf[tau] * scale;
    }
  }
}

void for_each_fir_residual_block(const std::vector<ChannelView>& vs, const std::vector<ChannelView>& qs, Index n,
                                 const MarkovSequence& g,
                                 const std::function<void(Index, Index, Index, const double*)>& visit) {
  const Index m = static_cast<Index>(vs.size());
  const Index p = static_cast<Index>(qs.size());
  const Index L = static_cast<Index>(g.size()) - 1;
  LPVID_ASSERT(L >= 0);
  if (n == 0 || p == 0) return;
  const Index M = block_fft_size(n, L);
  // Overlap-save: an M-point segment starting L samples before the block yields
  // B = M - L outputs free of wrap-around (indices L..M-1).
  const Index B = M - L;
  const RealFft fft(M);
  const Index nb = fft.bins();

  RealArray buf = alloc_real(M);
  std::vector<double> res(static_cast<std::size_t>(B));
  ComplexArray gspec = alloc_complex(p * m * nb);  // gspec[(i*m + a)*nb + b]
  for (Index i = 0; i < p; ++i) {
    for (Index a = 0; a < m; ++a) {
      std::fill(buf.get(), buf.get() + M, 0.0);
      for (Index k = 0; k <= L; ++k) buf[k] = g[k](i, a);
      fft.forward(buf.get(), gspec.get() + (i * m + a) * nb);
    }
  }
  ComplexArray vspec = alloc_complex(m * nb);
  ComplexArray yspec = alloc_complex(nb);
  const double scale = 1.0 / static_cast<double>(M);

  for (Index t0 = 0; t0 < n; t0 += B) {
    for (Index a = 0; a < m; ++a) {
      if (!vs[a].active) continue;
      load(vs[a], n, t0 - L, M, buf.get());
      fft.forward(buf.get(), vspec.get() + a * nb);
    }
    const Index t1 = std::min(t0 + B, n);
    for (Index i = 0; i < p; ++i) {
      std::fill(yspec.get(), yspec.get() + nb, Complex(0.0, 0.0));
      for (Index a = 0; a < m; ++a) {
        if (!vs[a].active) continue;
        mac(gspec.get() + (i * m + a) * nb, vspec.get() + a * nb, yspec.get(), nb);
      }
      fft.inverse(yspec.get(), buf.get());
      const ChannelView& q = qs[i];
      for (Index t = t0; t < t1; ++t) {
        const double qv = q.active ? q.data[t] - q.offset : 0.0;
        res[static_cast<std::size_t>(t - t0)] = qv - buf[L + (t - t0)] * scale;
      }
      visit(i, t0, t1, res.data());
    }
  }
}

void accumulate_fir_residual_energy(const std::vector<ChannelView>& vs,
                                    const std::vector<ChannelView>& qs, Index n,
                                    const MarkovSequence& g, Eigen::VectorXd& sum_sq) {
  LPVID_ASSERT(sum_sq.size() == static_cast<Index>(qs.size()));
  for_each_fir_residual_block(vs, qs, n, g, [&](Index i, Index t0, Index t1, const double* e) {
    double s = 0.0;
    for (Index t = 0; t < t1 - t0; ++t) s += e[t] * e[t];
    sum_sq[i] += s;
  });
}

}  // namespace lpvid::signal_detail
