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

}  // namespace lpvid::output_error_detail
