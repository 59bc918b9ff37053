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

// e = q − y_c − Σ_{k=0}^{L} g[k] v(t − k), less its mean over the record (the offset),
// N × p (v = 0 before the record; y_c = *correction, or none).  Blocked FFT convolution.
// @throws InputError  g's shape or the correction's does not match the experiment.
void fir_residual(const ExperimentView& experiment, const MarkovSequence& g, const Eigen::MatrixXd* correction,
                  Eigen::MatrixXd& e);

std::vector<Eigen::MatrixXcd> fir_residual_spectrum(const std::vector<ExperimentView>& experiments,
                                                    const MarkovSequence& g, Index segment_length, Index num_bins,
                                                    const std::vector<Eigen::MatrixXd>& output_correction = {});

// Replicates of a least-squares Markov estimate's error, one per record segment: the
// data's own measure of how uncertain ĝ is, whatever the noise's spectrum, its
// correlation or its cause (identify's bands: a sandwich covariance, plant_fit.h).
//
// The LS error is δg = Φ⁻¹ Σ_t φ(t) e(t) (φ(t) the lagged excitations, e the noise).
// With white excitation Φ ≈ I ⊗ R₀ (R₀ = Σ v vᵀ over all experiments), so splitting
// the sum over t into segments s gives δg = Σ_s δg_s,
//   δg_s[k] = (Σ_{t∈s} e(t) v(t − k)ᵀ) R₀⁻¹,   k = 1..num_lags,
// with e the residual of g (as fir_residual_spectrum: less the correction and its
// mean).  Each experiment is cut into ⌊N_e / segment_length⌋ segments (the last takes
// the remainder); terms of different segments are nearly uncorrelated when segments
// are long against the correlation time of e·v, so Σ_s δG_s δG_sᴴ estimates the
// error covariance of the bins (Σ_s δg_s = 0: e is orthogonal to the regressors).
// Coloured excitation breaks Φ ≈ I ⊗ R₀; the replicates are then only indicative.
//
// Returned: per segment, the num_lags-point DFT bins f = 0..num_bins−1 of
// Σ_{k=1}^{num_lags} δg_s[k] z^−k (make_markov_bins' transform of g), p × m each.
// Cost O(segments (m_active + 2p) M log M), M ≥ segment_length + num_lags.
// @throws InputError  as fir_residual_spectrum; num_lags < 2; num_bins not in
//                     1..num_lags/2+1; a singular excitation_gram.
std::vector<std::vector<Eigen::MatrixXcd>> markov_error_replicates(
    const std::vector<ExperimentView>& experiments, const MarkovSequence& g, const Eigen::MatrixXd& excitation_gram,
    Index segment_length, Index num_lags, Index num_bins, const std::vector<Eigen::MatrixXd>& output_correction = {});

}  // namespace lpvid
