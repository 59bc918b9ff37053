// lpvid — singular-value plot for order selection (the paper's Fig. 9,
// "largest 12 singular values"): singular values against their index on a
// log10 y axis, the values kept for the chosen order in one colour and the
// discarded ones in grey, the chosen order as a vertical dashed line
// ("order 9") and the noise floor as a horizontal dashed line.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "formats/plot/canvas.h"
#include "idlib/core/types.h"

namespace lpvid {

struct SingularValuePlotOptions {
  Index count = 20;         // how many of the largest values to show (>= 1)
  Index chosen_order = 0;   // values 1..chosen_order are "kept"; 0 = no order marked
  double noise_floor = 0;   // same scaling as the values; 0 = no line
  std::string title;        // figure title; empty = none
};

// Where the axes are in the figure and how values map to pixels (for tests).
// index maps the 1-based index (axis spans 0.5 .. shown + 0.5); value is log10.
struct SingularValueLayout {
  cv::Size figure;
  cv::Rect axes_px;
  plot::AxisMap index;
  plot::AxisMap value;
  // How many values are drawn: min(size, max(count, chosen_order + 1)), so
  // that the order line always has a discarded value to its right.
  Index shown = 0;
};

// singular_values: the values in any scaling, normally descending (drawn in
// the given order).  Zero values are not drawn (log axis).
// @throws InputError when singular_values is empty, has a negative or
//   non-finite entry, or all shown values are zero; when count < 1; when
//   chosen_order < 0 or > singular_values.size(); when noise_floor < 0 or
//   is not finite.
SingularValueLayout layout_singular_values(const Eigen::VectorXd& singular_values,
                                           const SingularValuePlotOptions& options);
cv::Mat render_singular_values(const Eigen::VectorXd& singular_values,
                               const SingularValuePlotOptions& options);
std::vector<unsigned char> singular_values_png(const Eigen::VectorXd& singular_values,
                                               const SingularValuePlotOptions& options);

}  // namespace lpvid
