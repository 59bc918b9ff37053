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
// (channel: its DOF), an input's limit w_max (channel: the input) or a ripple's period p
// (channel: its DOF).
struct ShapeParameter {
  enum class Kind { kStribeckScale, kInputLimit, kRipplePeriod };
  Index param = -1;
  Kind kind = Kind::kStribeckScale;
  Index channel = 0;
};
std::vector<ShapeParameter> shape_parameters(const PhysicalModel& model);

// The shaped terms (idlib/fit/force_error_shapes.cc), per kept row of d, smoothed as every
// term: DOF i's Stribeck regressor sign(q') exp(−(q'/v_s)²); input j clipped at ±limit
// (then held as d.w); DOF i's ripple regressors sin(2π q/p) and cos(2π q/p).
Eigen::VectorXd stribeck_regressor(const ForceErrorData& d, Index i, double v_s);
Eigen::VectorXd saturated_input(const ForceErrorData& d, Index j, double limit);
std::pair<Eigen::VectorXd, Eigen::VectorXd> ripple_regressors(const ForceErrorData& d, Index i, double period);

// The periods a ripple on DOF i is searched over, as spatial frequencies first + k step,
// k < lines (lines = 0: the log leaves no range: a travel under three shortest periods).
struct RippleGrid {
  double travel = 0.0, median_speed = 0.0;
  double period_min = 0.0, period_max = 0.0;
  double first = 0.0, step = 0.0;
  Index lines = 0;
  double period(Index k) const { return 1.0 / (first + static_cast<double>(k) * step); }
};
RippleGrid ripple_grid(const ForceErrorData& d, Index i);
// Per line of g: the share of the residual's (n rows) sum of squares that a sinusoid in
// DOF i's position of that period explains.
Eigen::VectorXd ripple_periodogram(const ForceErrorData& d, Index i, const Eigen::VectorXd& residual,
                                   const RippleGrid& g);
// The `count` highest local maxima, highest first; the median line.
std::vector<Index> periodogram_peaks(const Eigen::VectorXd& power, Index count);
double periodogram_median(const Eigen::VectorXd& power);

}  // namespace lpvid::force_error_detail
