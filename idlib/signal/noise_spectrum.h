// lpvid — the noise spectrum behind a Markov (FIR) estimate: power spectral density of
// the residual e(t) = q(t) − y_c(t) − Σ_{k=0}^{L} g[k] v(t − k) − c_e of each
// experiment (c_e its mean, the estimated offset; y_c an optional known part of the
// output to remove, e.g. the response beyond the horizon), pooled over experiments.
//
// Welch's method (Hann window, 50 % overlap) with segments of `segment_length`
// samples, so that bin f lies at ω_f = 2π f / (segment_length Ts), the bins of the
// segment_length-point DFT of g (idlib/identify/plant_fit.h).  The estimate is the
// two-sided density per sample: for white noise of covariance Σ it is Σ at every
// bin, E[X_f X_fᴴ] / (Σ_t w(t)²) for the windowed segment transform X_f.
//
// | argument / result | shape |
// |-------------------|-------|
// | experiments       | each: excitation N_e × m (v), output N_e × p (q) |
// | g                 | L + 1 matrices p × m |
// | output_correction | empty, or one N_e × p matrix per experiment (y_c) |
// | result            | num_bins Hermitian p × p matrices (f = 0..num_bins−1) |
//
// Cost O(Σ N_e (m + p) log L) for the residual (blocked FFT convolution) plus
// O(Σ N_e p² ...) for the periodograms; memory one segment and one block per channel.
// @throws InputError  no experiments; shapes that differ from g's; segment_length < 2
//                     or longer than the shortest record; num_bins not in
//                     1..segment_length/2+1; a correction of the wrong shape.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/signal/markov.h"

namespace lpvid {

std::vector<Eigen::MatrixXcd> fir_residual_spectrum(const std::vector<ExperimentView>& experiments,
                                                    const MarkovSequence& g, Index segment_length, Index num_bins,
                                                    const std::vector<Eigen::MatrixXd>& output_correction = {});

}  // namespace lpvid
