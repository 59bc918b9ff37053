// lpvid — what the two forms of the output-error refinement share (output_error.cc, the
// full form; output_error_modal.cc, the separable modal form): the checks of their
// arguments, the channel scales that make every output count alike, and the solver's
// settings.  Internal to idlib/identify.
#pragma once

#include <ceres/ceres.h>

#include <vector>

#include "idlib/core/types.h"
#include "idlib/identify/output_error.h"

namespace lpvid::output_error_detail {

// @throws InputError  invalid options or start, a continuous start, no experiments, a log
//                     whose shape is not the model's.
void check_arguments(const std::vector<ExperimentView>& experiments, const StateSpace& start,
                     const OutputErrorOptions& options);

// The RMS of each centred input (su) and output (sy) over all experiments (1 for a
// constant channel): the refinement works in ũ = u / su, ỹ = y / sy, so each output
// counts alike (MATLAB compare's normalisation).
struct ChannelScales {
  Eigen::VectorXd su, sy;
};
ChannelScales channel_scales(const std::vector<ExperimentView>& experiments);

// Levenberg–Marquardt, dense QR, tight tolerances, silent, one thread.
ceres::Solver::Options solver_options(int max_iterations);

// The length of the record segments whose score sums make the sandwich covariance (batch
// means): long against the residual's correlation, so that a segment's sum carries its
// own correlated stretch (the relative bias of a batch-means variance is about τ/L, τ
// the residual's integrated autocorrelation time in samples: L = kSegmentsPerTau τ, 10 %),
// and otherwise as many as the record allows, between kMinSandwichSegments (the
// estimate of a variance from S segments has S − 1 degrees of freedom: from 8 it scatters
// by ±27 %, and with it every band of the record at once) and kMaxSandwichSegments
// (±18 %, the structured route's replicates; more cost and add little).  Never shorter
// than min_segment_samples.  τ is the largest over the channels of 1 + 2 Σ ρ(k), summed
// until ρ first falls to zero or below (the initial positive sequence), ρ from the
// FFT autocorrelation (idlib/signal/correlation.h).
// | residual: rows × p (time along rows; weighted as the criterion weighs it) |
inline constexpr Index kMinSandwichSegments = 8, kMaxSandwichSegments = 64;
inline constexpr double kSegmentsPerTau = 10.0;
Index sandwich_segment_length(const Eigen::Ref<const Eigen::MatrixXd>& residual, Index min_segment_samples);

}  // namespace lpvid::output_error_detail
