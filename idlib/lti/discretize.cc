#include "idlib/lti/discretize.h"

#include <fmt/format.h>

#include <cmath>
#include <unsupported/Eigen/MatrixFunctions>

#include "idlib/core/error.h"

namespace lpvid {

StateSpace discretize_zoh(const StateSpace& continuous, double sample_period_s) {
  continuous.validate();
  if (continuous.is_discrete())
    throw InputError(fmt::format("discretize: the model is already discrete (ts = {} s); pass a continuous model (ts = 0)",
                                 continuous.sample_period_s));
  if (!std::isfinite(sample_period_s) || !(sample_period_s > 0.0))
    throw InputError(fmt::format("discretize: sample period {} s; it must be finite and > 0", sample_period_s));
  const Index n = continuous.order(), m = continuous.num_inputs();
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n + m, n + m);
  M.topLeftCorner(n, n) = continuous.A * sample_period_s;
  M.topRightCorner(n, m) = continuous.B * sample_period_s;
  const Eigen::MatrixXd E = M.exp();
  StateSpace d = continuous;
  d.A = E.topLeftCorner(n, n);
  d.B = E.topRightCorner(n, m);
  d.sample_period_s = sample_period_s;
  return d;
}

}  // namespace lpvid
