// lpvid — the error falling, fit by fit (`lpvid history --png`): one bar per
// fit record in order, its height the model's error figure in percent on a log10
// axis (idlib/fit/fit.h; older records: the mean channel error), a marker at the
// largest channel error, a green line at the data's noise floor where the record
// has one (a model at the line fits within the noise), and under each bar the fit number
// with the effects of that model (rotated text), so a user sees which effect made
// the error fall.
#pragma once

#include <opencv2/core.hpp>

#include <limits>
#include <string>
#include <vector>

namespace lpvid {

struct HistoryBar {
  std::string label;       // e.g. "3: + delay" (lpvid history: the effects the fit added)
  double mean_percent = 0; // > 0
  double max_percent = 0;  // >= mean_percent
  double floor_percent = std::numeric_limits<double>::quiet_NaN();  // noise floor; NaN = not known
};

// @throws InputError  no bars; a value not finite or <= 0; max below mean.
cv::Mat render_history(const std::vector<HistoryBar>& bars, const std::string& title);
std::vector<unsigned char> history_png(const std::vector<HistoryBar>& bars, const std::string& title);

}  // namespace lpvid
