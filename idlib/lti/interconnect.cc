#include "idlib/lti/interconnect.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

void check_same_rate(const StateSpace& a, const StateSpace& b, const char* what) {
  const double ta = a.sample_period_s, tb = b.sample_period_s;
  const bool same = (ta == 0.0 && tb == 0.0) ||
                    (ta > 0.0 && tb > 0.0 && std::abs(ta - tb) <= kSamplePeriodRelTolerance * std::max(ta, tb));
  if (!same)
    throw InputError(fmt::format("{}: sample periods differ ({} s vs {} s; 0 = continuous); use models sampled at the same rate",
                                 what, ta, tb));
}

// The loop y = G (w + u_c), u_c = K y (K = ±controller), with both outputs.
struct Loop {
  Eigen::MatrixXd A, B, Cy, Dy, Cu, Du;
};

Loop close_positive(const StateSpace& G, const StateSpace& K, const char* what) {
  G.validate();
  K.validate();
  check_same_rate(G, K, what);
  const Index m = G.num_inputs(), p = G.num_outputs();
  if (K.num_inputs() != p || K.num_outputs() != m)
    throw InputError(fmt::format("{}: controller is {}x{} (outputs x inputs) but must be {}x{} for a plant with {} inputs and {} outputs",
                                 what, K.num_outputs(), K.num_inputs(), m, p, m, p));
  const Eigen::MatrixXd L = Eigen::MatrixXd::Identity(m, m) - K.D * G.D;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(L);
  const Eigen::VectorXd sv = svd.singularValues();
  // An algebraic loop is ill-posed when I ∓ D_C D_G is singular to working
  // precision; 1e-12 relative to its largest singular value leaves 4 digits
  // of margin over double rounding of a 3x3 product.
  constexpr double kSingularRel = 1e-12;
  if (m > 0 && !(sv[m - 1] > kSingularRel * std::max(1.0, sv[0])))
    throw InputError(fmt::format("{}: algebraic loop: I ∓ D_C·D_G is singular (smallest singular value {:.3g}); the direct feedthroughs of "
                                 "controller and model make the loop ill-posed, check D of both",
                                 what, m > 0 ? sv[m - 1] : 0.0));
  const Eigen::MatrixXd E = L.inverse();
  const Index nG = G.order(), nK = K.order(), n = nG + nK;
  const Eigen::MatrixXd EDkCg = E * K.D * G.C;  // u_c from x_G
  const Eigen::MatrixXd ECk = E * K.C;          // u_c from x_K
  Loop s;
  // u_G = w + u_c = [EDkCg  ECk] x + E w
  s.Cu.resize(m, n);
  s.Cu << EDkCg, ECk;
  s.Du = E;
  // y = C_G x_G + D_G u_G
  s.Cy.resize(p, n);
  s.Cy << G.C + G.D * EDkCg, G.D * ECk;
  s.Dy = G.D * E;
  s.A.resize(n, n);
  s.A.topRows(nG) = G.B * s.Cu;
  s.A.topLeftCorner(nG, nG) += G.A;
  s.A.bottomRows(nK) = K.B * s.Cy;
  s.A.bottomRightCorner(nK, nK) += K.A;
  s.B.resize(n, m);
  s.B << G.B * E, K.B * s.Dy;
  return s;
}

StateSpace negated(const StateSpace& K) {
  StateSpace out = K;
  out.C = -K.C;
  out.D = -K.D;
  return out;
}

}  // namespace

StateSpace series(const StateSpace& first, const StateSpace& second) {
  first.validate();
  second.validate();
  check_same_rate(first, second, "series connection");
  if (second.num_inputs() != first.num_outputs())
    throw InputError(fmt::format("series connection: first model has {} outputs but second has {} inputs; they must be equal",
                                 first.num_outputs(), second.num_inputs()));
  const Index n1 = first.order(), n2 = second.order();
  StateSpace s;
  s.A = Eigen::MatrixXd::Zero(n1 + n2, n1 + n2);
  s.A.topLeftCorner(n1, n1) = first.A;
  s.A.bottomLeftCorner(n2, n1) = second.B * first.C;
  s.A.bottomRightCorner(n2, n2) = second.A;
  s.B.resize(n1 + n2, first.num_inputs());
  s.B << first.B, second.B * first.D;
  s.C.resize(second.num_outputs(), n1 + n2);
  s.C << second.D * first.C, second.C;
  s.D = second.D * first.D;
  s.sample_period_s = first.sample_period_s;
  s.input_names = first.input_names;
  s.output_names = second.output_names;
  return s;
}

StateSpace closed_loop_output(const StateSpace& plant, const StateSpace& controller) {
  const Loop l = close_positive(plant, negated(controller), "closed loop");
  return StateSpace{l.A, l.B, l.Cy, l.Dy, plant.sample_period_s, plant.input_names, plant.output_names};
}

StateSpace closed_loop_input_sensitivity(const StateSpace& plant, const StateSpace& controller) {
  const Loop l = close_positive(plant, negated(controller), "input sensitivity");
  return StateSpace{l.A, l.B, l.Cu, l.Du, plant.sample_period_s, plant.input_names, plant.input_names};
}

StateSpace positive_feedback_with(const StateSpace& G, const StateSpace& controller) {
  const Loop l = close_positive(G, controller, "positive feedback");
  return StateSpace{l.A, l.B, l.Cy, l.Dy, G.sample_period_s, G.input_names, G.output_names};
}

}  // namespace lpvid

