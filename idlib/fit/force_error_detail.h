// lpvid — what the force-error route's two files share (idlib/fit/force_error.cc: the
// data and the fit; idlib/fit/force_error_diagnose.cc: the loop's step and where the
// fit fails).  Internal to idlib/fit.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "idlib/fit/force_error.h"

namespace lpvid::force_error_detail {

double rms(const Eigen::VectorXd& x);
// The time-only effects the route has a form for, in the order it tries them.
const std::vector<std::string>& time_effect_names();
bool is_time_effect(const std::string& name);
// The bounded linear fit with every shape parameter (below) held at the model's value
// (free or not): fit_force_error's inner problem.
ForceErrorFit fit_with_fixed_shape(const PhysicalModel& start, const ForceErrorData& d);
// A parameter that shapes a term instead of scaling it: a Stribeck velocity scale v_s
// (channel: its DOF) or an input's limit w_max (channel: the input).
struct ShapeParameter {
  enum class Kind { kStribeckScale, kInputLimit };
  Index param = -1;
  Kind kind = Kind::kStribeckScale;
  Index channel = 0;
};
std::vector<ShapeParameter> shape_parameters(const PhysicalModel& model);

}  // namespace lpvid::force_error_detail
