// lpvid — the error falling, fit by fit (`lpvid history --png`): one bar per
// fit record in order, its height the mean weighted model error in percent on a
// log10 axis, a marker at the largest error, and under each bar the fit number
// with the effects of that model (rotated text), so a user sees which effect made
// the error fall.
#pragma once

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace lpvid {

struct HistoryBar {
  std::string label;       // e.g. "3: + delay" (lpvid history: the effects the fit added)
  double mean_percent = 0; // > 0
  double max_percent = 0;  // >= mean_percent
};

// @throws InputError  no bars; a value not finite or <= 0; max below mean.
cv::Mat render_history(const std::vector<HistoryBar>& bars, const std::string& title);
std::vector<unsigned char> history_png(const std::vector<HistoryBar>& bars, const std::string& title);

}  // namespace lpvid
