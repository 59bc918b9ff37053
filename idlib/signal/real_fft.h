// lpvid — internal: a real-to-complex FFT of one fixed size (FFTW3), and the
// blocked FFT correlation/convolution kernels that correlation.cc and markov.cc
// share.  Not part of the public idlib API; include correlation.h / markov.h.
#pragma once

#include <fftw3.h>

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid::signal_detail {

struct FftwFree {
  void operator()(void* p) const { fftw_free(p); }
};
// SIMD-aligned arrays (fftw_malloc), so that one plan can run on any of them.
using RealArray = std::unique_ptr<double[], FftwFree>;
using ComplexArray = std::unique_ptr<Complex[], FftwFree>;
RealArray alloc_real(Index n);
ComplexArray alloc_complex(Index n);  // zero-initialised

// Smallest power of two >= n (n >= 1).
Index next_pow2(Index n);
// Smallest 2^a 3^b >= n (n >= 1): FFTW transforms these about as fast per point as
// powers of two, and they lie much closer to n (2L + 2 = 65538 for L = 2^15: 69984 =
// 2^5 3^7 points, not 131072; measured 221 us against 485 us per real transform).
Index next_fft_size(Index n);

// Out-of-place r2c / c2r transforms of size n (FFTW_ESTIMATE plans, created and
// destroyed under a process-wide mutex because FFTW planning is not thread-safe;
// execution is thread-safe).  Arrays must come from alloc_real/alloc_complex.
class RealFft {
 public:
  explicit RealFft(Index n);
  ~RealFft();
  RealFft(const RealFft&) = delete;
  RealFft& operator=(const RealFft&) = delete;

  Index size() const { return n_; }
  Index bins() const { return n_ / 2 + 1; }
  // out[0..bins) = DFT(in[0..n)); in is preserved.
  void forward(const double* in, Complex* out) const;
  // out[0..n) = n * IDFT(in[0..bins)) (unnormalised); in is destroyed.
  void inverse(Complex* in, double* out) const;

 private:
  Index n_;
  fftw_plan forward_ = nullptr;
  fftw_plan inverse_ = nullptr;
};

// One signal channel as the kernels read it: value(t) = active ? data[t] - offset : 0,
// t = 0..n-1 (data is contiguous in time: a column of an N x channels matrix).
struct ChannelView {
  const double* data = nullptr;
  double offset = 0.0;
  bool active = true;
};

// FFT size used for blocked correlation/convolution with lags 0..max_lag over n samples.
Index block_fft_size(Index n, Index max_lag);

// out[tau](i, j) += sum_{t: 0 <= t, t + tau < n} x_i(t + tau) * y_j(t), tau = 0..max_lag.
// out must hold max_lag + 1 matrices of xs.size() x ys.size().  O(n log max_lag).
void accumulate_cross_correlation(const std::vector<ChannelView>& xs,
                                  const std::vector<ChannelView>& ys, Index n, Index max_lag,
                                  std::vector<Eigen::MatrixXd>& out);

// The residual of an FIR model, e_i(t) = q_i(t) - sum_{k=0}^{L} sum_a g[k](i, a) v_a(t - k)
// (v_a(t) = 0 for t < 0), delivered block by block: visit(i, t0, t1, e) with e[0..t1-t0)
// = e_i(t0..t1-1); blocks of one output arrive in time order.  Overlap-save FFT blocks.
void for_each_fir_residual_block(const std::vector<ChannelView>& vs, const std::vector<ChannelView>& qs, Index n,
                                 const MarkovSequence& g,
                                 const std::function<void(Index, Index, Index, const double*)>& visit);

// Residual energy of an FIR model: for each output i,
//   sum_sq[i] += sum_{t=0}^{n-1} (q_i(t) - sum_{k=0}^{L} sum_a g[k](i, a) v_a(t - k))^2,
// with v_a(t) = 0 for t < 0.  g holds L+1 matrices of qs.size() x vs.size().
void accumulate_fir_residual_energy(const std::vector<ChannelView>& vs,
                                    const std::vector<ChannelView>& qs, Index n,
                                    const MarkovSequence& g, Eigen::VectorXd& sum_sq);

// acc[b] += a[b] * conj(c[b]), b = 0..nb-1 (cross-spectrum accumulation),
// written on doubles so that it vectorises.
void mac_conj(const Complex* a, const Complex* c, Complex* acc, Index nb);
// acc[b] += a[b] * c[b] over nb bins.
void mac(const Complex* a, const Complex* c, Complex* acc, Index nb);

}  // namespace lpvid::signal_detail
