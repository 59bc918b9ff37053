// lpvid — the base "mechanical": a stage the USER describes (a wafer stage, a
// positioning axis, a flexible structure on a shaker), the standard model of
// precision mechatronics, declared in a description file (docs/formats.md,
// "Mechanical base descriptions"; docs/effects.md, "Base: mechanical"):
//
//   M q'' + D q' + K q = B_w w,      y = C_q q  (or C_q q', C_q q'' per output),
//
// q the rigid-body DOFs (any number up to kMaxMechanicalDofs, any units), w the
// inputs after the input blocks, y the outputs before the output blocks.  Every
// entry of M, D, K, B_w and C_q is a LINEAR EXPRESSION of the base's parameters:
// a number, a parameter name, or a sum of terms "c*name" / "name" / "c"
// (e.g. "m_carriage_kg + m_load_kg", "-k_coupling_N_per_m", "0.5*k_f_N_per_A").
// M must be symmetric (as expressions) and positive definite at the values the
// model holds; D and K may be anything, zero included (a levitated or guided
// stage has no stiffness in its free directions).  Flexible modes are the
// library's structural_mode effect (collocated, shape per DOF), added one at a
// time; every block effect (delay, lags, gains, cross-talk, user-defined blocks)
// applies unchanged.  There is no scheduling variable (not yet: a mechanical
// base is linear time-invariant).
//
// The description travels inside the model file (key "mechanical"), so every
// command that reads the model rebuilds the same base.  The matrices are built by a
// template on the scalar type (double, or ceres::Jet in idlib/fit).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/physical/physical_model.h"

namespace lpvid {

inline constexpr Index kMaxMechanicalDofs = 12;
// Flexible modes the library offers a mechanical base: structural_mode,
// structural_mode_2 ... structural_mode_8 (each proposed once the one before is in).
inline constexpr int kMaxMechanicalModes = 8;

// c × (the parameter's value), or c alone when parameter is empty.
struct LinearTerm {
  double coefficient = 1.0;
  std::string parameter;
  bool operator==(const LinearTerm& o) const { return coefficient == o.coefficient && parameter == o.parameter; }
};
using LinearExpression = std::vector<LinearTerm>;  // empty: 0

// "m1 + m2", "-k", "0.5*kf", "2e-3", "kf*0.5".  @throws InputError naming the
// character where the text stops being such an expression.
LinearExpression parse_linear_expression(const std::string& text);
// Its canonical text ("0" when empty), which parses back to the same terms.
std::string linear_expression_text(const LinearExpression& e);

struct MechanicalChannel {
  std::string name, unit;
  // outputs only: what the sensor measures of C_q q: 0 position (the default), 1
  // velocity (a geophone, a laser vibrometer), 2 acceleration (an accelerometer:
  // y = C_q q'' = C_q M⁻¹(B_w w − D q' − K q) plus the modes' φ η'', with a direct
  // feedthrough)
  int derivative = 0;
};

struct MechanicalDescription {
  std::string name;         // what the user calls the stage, e.g. "ball_screw_axis"
  std::string description;  // one line
  std::vector<MechanicalChannel> dofs, inputs, outputs;
  std::vector<PhysicalParameter> parameters;  // the base's, with design values, bounds, priors
  // Row-major: mass, damping, stiffness n_dof × n_dof; input_map n_dof × n_in;
  // output_map n_out × n_dof.
  std::vector<std::vector<LinearExpression>> mass, damping, stiffness, input_map, output_map;
};

// The base a model of it needs: the description, its BaseInfo and its effect
// library (the block effects every base shares, with its channel names).
struct UserBase {
  MechanicalDescription description;
  BaseInfo info;
  std::vector<EffectInfo> library;
};

// Checks the description and builds the base.  @throws InputError for: no DOF or
// more than kMaxMechanicalDofs, no input or output, a name empty, repeated or not
// an identifier, a unit empty, a parameter repeated or with value outside finite
// ordered bounds, a matrix of the wrong shape, an expression naming an unknown
// parameter, a parameter no matrix uses, M not symmetric, M not positive
// definite at the design values.
std::shared_ptr<const UserBase> make_mechanical_base(const MechanicalDescription& description);

// Positions of the expressions' parameters in a model's list.
struct MechanicalIndices {
  struct Entry {
    Index row = 0, col = 0;
    double coefficient = 0.0;
    Index parameter = -1;  // -1: a constant
  };
  Index n_dof = 0, n_in = 0, n_out = 0;
  std::vector<Entry> mass, damping, stiffness, input_map, output_map;
  std::vector<int> output_derivative;  // per output: 0 position, 1 velocity, 2 acceleration
  explicit MechanicalIndices(const PhysicalModel& model);
};

// M, D, K (n_dof²), B_w (n_dof × n_in), C_q (n_out × n_dof) at parameter values p.
template <class T>
void mechanical_matrices(const MechanicalIndices& L, const T* p,
                         Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& M,
                         Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& D,
                         Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& K,
                         Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& Bw,
                         Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& Cq) {
  using Mat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
  auto fill = [&](const std::vector<MechanicalIndices::Entry>& entries, Index rows, Index cols, Mat& out) {
    out = Mat::Constant(rows, cols, T(0.0));
    for (const auto& e : entries)
      out(e.row, e.col) += e.parameter >= 0 ? T(e.coefficient) * p[e.parameter] : T(e.coefficient);
  };
  fill(L.mass, L.n_dof, L.n_dof, M);
  fill(L.damping, L.n_dof, L.n_dof, D);
  fill(L.stiffness, L.n_dof, L.n_dof, K);
  fill(L.input_map, L.n_dof, L.n_in, Bw);
  fill(L.output_map, L.n_out, L.n_dof, Cq);
}

}  // namespace lpvid
