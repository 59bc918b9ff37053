#include "idlib/closedloop/interpolation.h"
#include "idlib/core/eigen_decompositions.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include <cmath>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

// Controller poles closer than this (relative to max(1, |λ|)) are one pole of
// higher multiplicity (e.g. three PI integrators at z = 1).
constexpr double kPoleGroupTolerance = 1e-8;
// Eigenvector matrices of the controller's A above this condition number mean
// a (nearly) defective A, whose residues are not defined by simple poles.
constexpr double kMaxEigenvectorCondition = 1e10;

double condition_number(const Eigen::MatrixXcd& M) {
  if (M.size() == 0) return INFINITY;
  Eigen::JacobiSVD<Eigen::MatrixXcd> svd(M);
  const auto& s = svd.singularValues();
  return s(s.size() - 1) > 0 ? s(0) / s(s.size() - 1) : INFINITY;
}

}  // namespace

InterpolationCorrection impose_controller_interpolation(const StateSpace& G, const StateSpace& C) {
  const Index m = G.num_inputs(), p = G.num_outputs(), n = G.order();
  if (C.num_inputs() != p || C.num_outputs() != m)
    throw InputError(fmt::format("controller is {}x{} (outputs x inputs) but the closed loop is {}x{}",
                                 C.num_outputs(), C.num_inputs(), p, m));
  InterpolationCorrection out;
  out.closed_loop = G;
  if (C.order() == 0) {
    out.note = "the controller has no states: no interpolation conditions";
    return out;
  }
  if (n == 0) {
    out.note = "the closed loop has no states: no interpolation conditions can be imposed on it";
    return out;
  }
  if (m != p) {
    out.note = "the loop is not square: the residue conditions G'(λ) = R⁻¹ are not defined";
    return out;
  }
  Eigen::ComplexEigenSolver<Eigen::MatrixXcd> eig(C.A.cast<Complex>());
  const Eigen::MatrixXcd V = eig.eigenvectors();
  if (condition_number(V) > kMaxEigenvectorCondition) {
    out.note = "the controller's A is (nearly) defective: residues undefined, no conditions imposed";
    return out;
  }
  const Eigen::MatrixXcd W = V.inverse();
  const Eigen::VectorXcd lambda = eig.eigenvalues();

  // Group equal poles; keep one of each conjugate pair (real ΔB makes the
  // condition at the conjugate hold automatically).
  std::vector<std::vector<Index>> groups;
  std::vector<bool> used(static_cast<std::size_t>(lambda.size()), false);
  for (Index i = 0; i < lambda.size(); ++i) {
    if (used[i]) continue;
    std::vector<Index> g;
    for (Index j = i; j < lambda.size(); ++j)
      if (!used[j] && std::abs(lambda[j] - lambda[i]) <= kPoleGroupTolerance * std::max(1.0, std::abs(lambda[i]))) {
        g.push_back(j);
        used[j] = true;
      }
    if (lambda[i].imag() < 0) continue;  // the conjugate (imag > 0) group carries it
    groups.push_back(g);
  }

  std::vector<Eigen::MatrixXd> rows, rhs;
  std::vector<std::string> skipped;
  const Eigen::MatrixXcd A = G.A.cast<Complex>(), B = G.B.cast<Complex>(), Cg = G.C.cast<Complex>();
  const Eigen::MatrixXcd I = Eigen::MatrixXcd::Identity(n, n);
  for (const auto& g : groups) {
    Complex l = 0;
    for (Index i : g) l += lambda[i];
    l /= static_cast<double>(g.size());
    // Residue R = C_c (Σ_g v_i w_iᵀ) B_c.
    Eigen::MatrixXcd proj = Eigen::MatrixXcd::Zero(C.order(), C.order());
    for (Index i : g) proj += V.col(i) * W.row(i);
    const Eigen::MatrixXcd R = C.C.cast<Complex>() * proj * C.B.cast<Complex>();
    if (condition_number(R) > kMaxResidueCondition) {
      skipped.push_back(fmt::format("({:.6g}{:+.6g}j): residue of rank < {}", l.real(), l.imag(), m));
      continue;
    }
    Eigen::PartialPivLU<Eigen::MatrixXcd> lu(l * I - A);
    if (!std::isfinite(condition_number(l * I - A)) || condition_number(l * I - A) > 1e14) {
      skipped.push_back(fmt::format("({:.6g}{:+.6g}j): also a pole of G", l.real(), l.imag()));
      continue;
    }
    const Eigen::MatrixXcd M1C = lu.solve(I);  // (λI − A)⁻¹
    const Eigen::MatrixXcd K1 = Cg * M1C;                 // G(λ) = K1 B + D
    const Eigen::MatrixXcd K2 = -Cg * M1C * M1C;          // G'(λ) = K2 B
    const Eigen::MatrixXcd r1 = -(K1 * B + G.D.cast<Complex>());
    const Eigen::MatrixXcd r2 = R.inverse() - K2 * B;
    Eigen::MatrixXcd K(2 * p, n), r(2 * p, m);
    K << K1, K2;
    r << r1, r2;
    rows.push_back(K.real());
    rhs.push_back(r.real());
    if (std::abs(l.imag()) > 0) {
      rows.push_back(K.imag());
      rhs.push_back(r.imag());
    }
  }
  Index total = 0;
  for (const auto& k : rows) total += k.rows();
  if (total == 0) {
    out.note = "no controller pole gives usable conditions" + (skipped.empty() ? std::string() : ": " + skipped.front());
    return out;
  }
  if (total > n) {
    out.note = fmt::format("{} conditions for {} states: too many to impose on B; none imposed", total, n);
    return out;
  }
  Eigen::MatrixXd K(total, n), r(total, m);
  Index at = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    K.middleRows(at, rows[i].rows()) = rows[i];
    r.middleRows(at, rows[i].rows()) = rhs[i];
    at += rows[i].rows();
  }
  const Eigen::MatrixXd dB = K.completeOrthogonalDecomposition().solve(r);  // minimum norm
  out.closed_loop.B = G.B + dB;
  out.applied = true;
  out.conditions = total;
  out.relative_change = dB.norm() / std::max(G.B.norm(), 1e-300);
  out.note = fmt::format("imposed G(λ) = 0 and G'(λ) = R⁻¹ at {} controller pole(s) ({} equations), changing B by {:.3g} "
                         "(relative){}",
                         groups.size() - skipped.size(), total, out.relative_change,
                         skipped.empty() ? "" : "; skipped " + skipped.front());
  return out;
}

}  // namespace lpvid
