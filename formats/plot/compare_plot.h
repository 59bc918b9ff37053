// lpvid — the compare figure: where a model fails against measurements.
//
// One panel per (output, input) channel (row = output, column = input), each
// with two axes sharing a log frequency axis in rad/s:
//   - magnitude [dB]: each measurement (thin line in its series colour) with
//     its model (black, or dashed in the series colour when the models differ);
//   - model error [% of the channel's scale], log y: 100 |E_ij| / s_ij per
//     measurement, over the grey noise region 0 .. 100 k σ_c / s_ij (the confidence
//     band of the model-error model, idlib/validate/model_error.h): what lies inside
//     the grey area the noise explains; what sticks out of it is a real error.
//     s_ij = max(sqrt(|P_ii| |P_jj|), |P_ij|) is the error figure's scale: an
//     off-diagonal entry near zero, or a diagonal one at an antiresonance, is
//     measured against the channel's size there, not against itself, so the axis
//     does not read 10^5 % where the entry merely crosses zero (the curve's height
//     against the grey band is the same under either scale).
// Failing bands are shaded red across both axes of their channel, so a user sees
// at a glance where the model is wrong.  A legend explains every mark.
#pragma once

#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "formats/plot/canvas.h"
#include "idlib/core/types.h"

namespace lpvid {

// One measurement with its model on the measurement's grid.
struct CompareSeries {
  std::string label;                      // legend, e.g. "x_b = -0.1 m"
  Eigen::VectorXd omega_rad_s;            // F, > 0
  std::vector<Eigen::MatrixXcd> data;     // F matrices p x m
  std::vector<Eigen::MatrixXcd> model;    // F matrices p x m
  std::vector<Eigen::MatrixXd> radius;    // F matrices p x m: k σ_c (may be +inf)
  std::vector<Eigen::MatrixXd> scale;     // F matrices p x m: s_ij (ModelErrorModel::scale; 0: not drawn)
  std::vector<bool> skipped;              // F or empty: not drawn
};

// A failing band to shade: channel and [lo, hi] in rad/s.
struct CompareBandMark {
  Index output = 0, input = 0;
  double lo_rad_s = 0, hi_rad_s = 0;
};

struct ComparePlotOptions {
  std::string title;
  std::vector<std::string> input_labels, output_labels;  // empty = u1.. / y1..
  bool same_model = true;  // one model for every series: drawn once, in black
  std::string band_label = "99 % noise band";
  int panel_width_px = 380, magnitude_height_px = 190, error_height_px = 130;  // each >= 60
};

// @throws InputError  no series; a series whose vectors differ in length or
//   shape from the first's; a frequency not finite or <= 0; a scale negative or
//   not finite; label counts that do not match; panel sizes < 60.
cv::Mat render_compare(const std::vector<CompareSeries>& series, const std::vector<CompareBandMark>& bands,
                       const ComparePlotOptions& options);
// The error axis of channel (i, j), in percent of s_ij: whole decades around every
// shown error and noise radius, at least two decades, within 0.01 % .. 10^4 %
// (validated as render_compare does).
struct CompareErrorAxis {
  double lo_percent = 0, hi_percent = 0;
};
CompareErrorAxis compare_error_axis(const std::vector<CompareSeries>& series, Index i, Index j);

std::vector<unsigned char> compare_png(const std::vector<CompareSeries>& series,
                                       const std::vector<CompareBandMark>& bands, const ComparePlotOptions& options);

}  // namespace lpvid
