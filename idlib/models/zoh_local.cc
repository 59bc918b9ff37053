#include "idlib/models/zoh_local.h"

#include <fmt/format.h>

#include <cmath>
#include <unsupported/Eigen/MatrixFunctions>

#include "idlib/core/error.h"

namespace lpvid {

StateSpace discretize_zoh_local(const StateSpace& continuous, double sample_period_s) {
  continuous.validate();
  if (continuous.is_discrete())
    throw InputError(fmt::format(
        "ZOH discretisation: the model is already discrete (ts = {} s); pass a continuous model (ts = 0)",
        continuous.sample_period_s));
  if (!std::isfinite(sample_period_s) || !(sample_period_s > 0.0))
    throw InputError(fmt::format(
        "ZOH discretisation: sample_period_s = {}; it must be finite and > 0; give the sample period in s",
        sample_period_s));
  const Index n = continuous.order();
  const Index m = continuous.num_inputs();
  Eigen::MatrixXd block = Eigen::MatrixXd::Zero(n + m, n + m);
  block.topLeftCorner(n, n) = continuous.A * sample_period_s;
  block.topRightCorner(n, m) = continuous.B * sample_period_s;
  const Eigen::MatrixXd e = block.exp();

  StateSpace discrete = continuous;
  discrete.A = e.topLeftCorner(n, n);
  discrete.B = e.topRightCorner(n, m);
  discrete.sample_period_s = sample_period_s;
  return discrete;
}

}  // namespace lpvid
