// lpvid — what the force-error route's two files share (idlib/fit/force_error.cc: the
// data and the fit; idlib/fit/force_error_diagnose.cc: the loop's step and where the
// fit fails).  Internal to idlib/fit.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

namespace lpvid::force_error_detail {

double rms(const Eigen::VectorXd& x);
// The time-only effects the route has a form for, in the order it tries them.
const std::vector<std::string>& time_effect_names();
bool is_time_effect(const std::string& name);

}  // namespace lpvid::force_error_detail
