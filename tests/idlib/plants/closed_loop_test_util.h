// Test helper: the discrete closed loop of Fig. 8 built directly from the plant
// and controller matrices, independent of the simulator's loop code.
#pragma once

#include <Eigen/Core>

#include "idlib/core/types.h"

namespace lpvid::testing {

// State [x_p; x_c], input v (plant-input excitation), outputs q (3) and u (3):
//   x_p+ = (A_p - B_p D_c C_p) x_p + B_p C_c x_c + B_p v
//   x_c+ = -B_c C_p x_p + A_c x_c
//   q = C_p x_p,   u = -D_c C_p x_p + C_c x_c + v     (plant D = 0)
struct DiscreteClosedLoop {
  Eigen::MatrixXd A, B, Cq, Cu, Du;
};

inline DiscreteClosedLoop close_loop(const StateSpace& plant, const StateSpace& controller) {
  const Index np = plant.order();
  const Index nc = controller.order();
  DiscreteClosedLoop cl;
  cl.A = Eigen::MatrixXd::Zero(np + nc, np + nc);
  cl.A.topLeftCorner(np, np) = plant.A - plant.B * controller.D * plant.C;
  cl.A.topRightCorner(np, nc) = plant.B * controller.C;
  cl.A.bottomLeftCorner(nc, np) = -controller.B * plant.C;
  cl.A.bottomRightCorner(nc, nc) = controller.A;
  cl.B = Eigen::MatrixXd::Zero(np + nc, 3);
  cl.B.topRows(np) = plant.B;
  cl.Cq = Eigen::MatrixXd::Zero(3, np + nc);
  cl.Cq.leftCols(np) = plant.C;
  cl.Cu = Eigen::MatrixXd::Zero(3, np + nc);
  cl.Cu.leftCols(np) = -controller.D * plant.C;
  cl.Cu.rightCols(nc) = controller.C;
  cl.Du = Eigen::MatrixXd::Identity(3, 3);
  return cl;
}

}  // namespace lpvid::testing
