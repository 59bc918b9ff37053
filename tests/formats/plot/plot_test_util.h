// Helpers shared by the plot tests: pixel colour checks and pinned errors.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <functional>
#include <opencv2/core.hpp>
#include <string>

#include "idlib/core/error.h"

namespace lpvid::plot_test {

// Anti-aliased 2 px lines blend with the background at their edges; the
// centre pixel of a line stays within this per-channel distance of the
// series colour (measured on OpenCV 4.6 LINE_AA output; typical <= 20).
inline constexpr int kColorTolerance = 40;

inline bool near_color(const cv::Vec3b& px, const cv::Scalar& color, int tol = kColorTolerance) {
  for (int c = 0; c < 3; ++c) {
    if (std::abs(static_cast<int>(px[c]) - static_cast<int>(color[c])) > tol) return false;
  }
  return true;
}

// Number of pixels of the colour inside the rectangle.
inline int count_color(const cv::Mat& image, const cv::Rect& r, const cv::Scalar& color,
                       int tol = kColorTolerance) {
  int n = 0;
  const cv::Rect inside = r & cv::Rect(0, 0, image.cols, image.rows);
  for (int y = inside.y; y < inside.br().y; ++y) {
    for (int x = inside.x; x < inside.br().x; ++x) n += near_color(image.at<cv::Vec3b>(y, x), color, tol);
  }
  return n;
}

// The InputError message thrown by f, or "" when it does not throw one.
inline std::string input_error(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace lpvid::plot_test
