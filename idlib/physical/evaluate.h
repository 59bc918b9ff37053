// lpvid — evaluating a physical model (idlib/physical/physical_model.h) at a value
// of its base's scheduling variable (the platform: the beam position x_b):
// continuous state space, exactly sampled (ZOH) state space with fractional input
// delays, and frequency response (docs/effects.md, docs/math.md "Physical model").
//
// Assembly (continuous, delays apart):
//
//   u ─► input blocks (in effect order) ─► w ─► rigid body + modes ─► q ─► output blocks ─► y
//
// | block        | states per channel | realisation |
// |--------------|--------------------|-------------|
// | first_order  | 1                  | x' = (u − x)/tau, out = x |
// | second_order | 2                  | x1' = x2, x2' = −w² x1 − 2 zeta w x2 + w² u, out = x1 |
// | resonance    | 2                  | x1' = x2, x2' = −wp² x1 − 2 zp wp x2 + u, out = g((wz² − wp²) x1 + (2 zz wz − 2 zp wp) x2 + u), g = wp²/wz² |
// | gain         | 0                  | out_c = g_c u_c |
// | coupling     | 0                  | out_to = u_to + c u_from |
// | rigid body   | 2 n_dof            | [q; q'],  q'' = M⁻¹(w − D q' − K q) |
// | mode         | 2                  | eta'' = −w² eta − 2 zeta w eta' + phiᵀ w,  q += phi eta |
//
// States: input blocks' (in order), then [q; q'] and each mode's [eta; eta'], then
// output blocks' (in order).  Delays act on the inputs u as given to the model
// (before every other input block); several delay blocks on one input add.
//
// Sampling (ZOH, period T).  The input u_j reaches the continuous system tau_j after
// it is set: tau_j = (k_j + f_j) T with k_j whole and 0 <= f_j < 1, so during
// [kT, kT + f_j T) the system sees u_j[k − k_j − 1] and after it u_j[k − k_j]:
//
//   x[k+1] = Ad x[k] + Σ_j ( b_new,j u_j[k − k_j] + b_old,j u_j[k − k_j − 1] ),
//   b_new,j = ∫_0^{(1−f_j)T} e^{Aσ} dσ b_j,   b_old,j = e^{A(1−f_j)T} ∫_0^{f_j T} e^{Aσ} dσ b_j,
//
// the exact sampled system (modified z-transform), which for f_j = 0 is the plain
// ZOH with a shift of k_j samples.  Its frequency response is
//
//   P(z) = (C (zI − Ad)⁻¹ (B_new + B_old z⁻¹) + D_j) diag(z^−k_j),  z = e^{jωT},
//
// (D_j: D's column j times z⁻¹ when f_j > 0).  Replacing the fractional part by
// e^{−jω f T} is NOT exact: its error grows steeply with ω (0.4 of a sample at
// 1 kHz: 3e-4 relative at 400 rad/s, 9e-3 at 1000 rad/s; tests/idlib/physical),
// above an analyzer's noise where modes sit.  In continuous time the delays are returned
// apart (P(jω) diag(e^{−jω tau_j})).
//
// The matrices are built by templates on the scalar type (double, or ceres::Jet in
// idlib/fit for exact derivatives, including d/dtau through f_j).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/types.h"
#include "idlib/physical/gauss_jordan.h"
#include "idlib/physical/mechanical/mechanical_base.h"
#include "idlib/physical/physical_model.h"
#include "idlib/physical/platform/platform_base.h"
#include "idlib/physical/stage6/stage6_base.h"

namespace lpvid {

// The double value of a scalar; idlib/fit specialises it for ceres::Jet.
template <class T>
struct ScalarValue {
  static double of(const T& x) { return static_cast<double>(x); }
};

template <class T>
using MatrixT = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;

// A model compiled once: parameter positions, blocks with channel indices.
struct ModelLayout {
  struct CompiledBlock {
    BlockKind kind;
    BlockSide side;
    std::vector<Index> channels;  // resolved; for per-channel kinds every channel when the block listed none
    std::vector<Index> params;    // positions in the model's parameter list
  };
  std::string base;
  std::optional<PlatformIndices> platform;
  std::optional<Stage6Indices> stage6;
  std::optional<MechanicalIndices> mechanical;
  std::vector<CompiledBlock> input_blocks, modes, output_blocks;
  std::vector<std::vector<Index>> delays;  // per input: parameter positions of its delays (summed)
  Index n_in = 0, n_out = 0, n_dof = 0;

  // @throws InputError  model invalid (PhysicalModel::validate).
  explicit ModelLayout(const PhysicalModel& model);

  Index input_states() const;
  Index body_states() const { return 2 * n_dof + 2 * static_cast<Index>(modes.size()); }
  Index output_states() const;
  Index order() const { return input_states() + body_states() + output_states(); }
  bool has_delay() const;
};

namespace physical_detail {

// Inverse of a symmetric positive definite n×n matrix (n <= 6): Gauss–Jordan
// without pivoting (SPD needs none); false when a pivot is not positive (not
// positive definite).
template <class T>
bool spd_inverse(const MatrixT<T>& M, MatrixT<T>& inv) {
  return gauss_jordan_inverse<T>(M, inv, &ScalarValue<T>::of, true, 0.0);
}

template <class T>
struct Lti {
  MatrixT<T> A, B, C, D;
};

// u -> first -> second -> y.
template <class T>
Lti<T> series(const Lti<T>& first, const Lti<T>& second) {
  const Index n1 = first.A.rows(), n2 = second.A.rows();
  const T zero(0.0);
  Lti<T> s;
  s.A = MatrixT<T>::Constant(n1 + n2, n1 + n2, zero);
  s.A.topLeftCorner(n1, n1) = first.A;
  if (n2 > 0) {
    s.A.bottomLeftCorner(n2, n1) = second.B * first.C;
    s.A.bottomRightCorner(n2, n2) = second.A;
  }
  s.B = MatrixT<T>(n1 + n2, first.B.cols());
  s.B.topRows(n1) = first.B;
  if (n2 > 0) s.B.bottomRows(n2) = second.B * first.D;
  s.C = MatrixT<T>(second.C.rows(), n1 + n2);
  s.C.leftCols(n1) = second.D * first.C;
  if (n2 > 0) s.C.rightCols(n2) = second.C;
  s.D = second.D * first.D;
  return s;
}

// One side's chain of blocks on `width` channels.
template <class T>
Lti<T> block_chain(const std::vector<ModelLayout::CompiledBlock>& blocks, Index width, const T* p) {
  const T zero(0.0), one(1.0);
  Lti<T> acc{MatrixT<T>(0, 0), MatrixT<T>(0, width), MatrixT<T>(width, 0), MatrixT<T>::Identity(width, width)};
  for (const auto& b : blocks) {
    Lti<T> s;
    switch (b.kind) {
      case BlockKind::kGain:
      case BlockKind::kCoupling: {
        s = {MatrixT<T>(0, 0), MatrixT<T>(0, width), MatrixT<T>(width, 0), MatrixT<T>::Identity(width, width)};
        if (b.kind == BlockKind::kGain)
          for (std::size_t c = 0; c < b.channels.size(); ++c) s.D(b.channels[c], b.channels[c]) = p[b.params[c]];
        else
          s.D(b.channels[1], b.channels[0]) += p[b.params[0]];
        // a static block: fold into the output map of what is accumulated
        acc.C = s.D * acc.C;
        acc.D = s.D * acc.D;
        continue;
      }
      case BlockKind::kFirstOrder:
      case BlockKind::kSecondOrder:
      case BlockKind::kResonance: {
        const Index per = b.kind == BlockKind::kFirstOrder ? 1 : 2;
        const Index n = per * static_cast<Index>(b.channels.size());
        s.A = MatrixT<T>::Constant(n, n, zero);
        s.B = MatrixT<T>::Constant(n, width, zero);
        s.C = MatrixT<T>::Constant(width, n, zero);
        s.D = MatrixT<T>::Identity(width, width);
        for (std::size_t c = 0; c < b.channels.size(); ++c) {
          const Index ch = b.channels[c], i = per * static_cast<Index>(c);
          s.D(ch, ch) = zero;
          if (b.kind == BlockKind::kFirstOrder) {
            const T inv = one / p[b.params[0]];
            s.A(i, i) = -inv;
            s.B(i, ch) = inv;
            s.C(ch, i) = one;
          } else if (b.kind == BlockKind::kSecondOrder) {
            const T w = p[b.params[0]], z = p[b.params[1]];
            s.A(i, i + 1) = one;
            s.A(i + 1, i) = -w * w;
            s.A(i + 1, i + 1) = T(-2.0) * z * w;
            s.B(i + 1, ch) = w * w;
            s.C(ch, i) = one;
          } else {
            const T wp = p[b.params[0]], zp = p[b.params[1]], wz = p[b.params[2]], zz = p[b.params[3]];
            const T g = (wp * wp) / (wz * wz);
            s.A(i, i + 1) = one;
            s.A(i + 1, i) = -wp * wp;
            s.A(i + 1, i + 1) = T(-2.0) * zp * wp;
            s.B(i + 1, ch) = one;
            s.C(ch, i) = g * (wz * wz - wp * wp);
            s.C(ch, i + 1) = g * (T(2.0) * zz * wz - T(2.0) * zp * wp);
            s.D(ch, ch) = g;
          }
        }
        break;
      }
      case BlockKind::kDelay:
      case BlockKind::kMode:
        LPVID_ASSERT(false);  // not in a chain
    }
    acc = series(acc, s);
  }
  return acc;
}

}  // namespace physical_detail

// The base's second-order matrices at the scheduling value: M, D, K (n_dof²); Bw,
// its input map (w -> generalised force; identity for the platform); F, velocity
// feedback into the input chain (w -> w − F q'), empty when none; Cq, its output map
// (body coordinates -> what the sensors see), empty when the identity.  False when
// the base cannot be built there (stage6_matrices' reasons).
template <class T>
bool base_matrices(const ModelLayout& L, const T* p, double schedule, MatrixT<T>& M, MatrixT<T>& Dm, MatrixT<T>& K,
                   MatrixT<T>& Bw, MatrixT<T>& F, MatrixT<T>& Cq) {
  const Index nd = L.n_dof;
  M.resize(nd, nd);
  Dm.resize(nd, nd);
  K.resize(nd, nd);
  Bw = MatrixT<T>::Identity(nd, L.n_in);
  F.resize(0, 0);
  Cq.resize(0, 0);
  if (L.stage6) {
    if (!stage6_matrices<T>(*L.stage6, p, schedule, &ScalarValue<T>::of, M, Dm, K, Bw, F, Cq)) return false;
    if (L.stage6->com[0] < 0) Cq.resize(0, 0);
    if (L.stage6->back_emf < 0) F.resize(0, 0);
  } else if (L.mechanical) {
    mechanical_matrices<T>(*L.mechanical, p, M, Dm, K, Bw, Cq);
  } else if (L.platform) {
    T m3[3][3], d3[3][3], k3[3][3];
    platform_matrices<T>(*L.platform, p, schedule, m3, d3, k3);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        M(i, j) = m3[i][j];
        Dm(i, j) = d3[i][j];
        K(i, j) = k3[i][j];
      }
  } else {
    LPVID_ASSERT(false);  // every base has its branch here
  }
  return true;
}

// Continuous (A, B, C, D) of the model at the scheduling value (x_b for the
// platform), delays apart.  Returns false when the base's mass matrix is not
// positive definite there (no model).  Shapes: A n×n, B n×n_in, C n_out×n, D n_out×n_in.
template <class T>
bool build_continuous(const ModelLayout& L, const T* p, double schedule, MatrixT<T>& A, MatrixT<T>& B, MatrixT<T>& C,
                      MatrixT<T>& D) {
  using physical_detail::Lti;
  const T zero(0.0), one(1.0);
  const Index nd = L.n_dof;
  MatrixT<T> M(nd, nd), Dm(nd, nd), K(nd, nd);
  // Bw: the base's input map (w -> generalised force; identity for the platform);
  // F: velocity feedback into the input chain (w -> w − F q'), empty when none.
  // Cq: the base's output map (body coordinates -> what the sensors see), empty
  // when the identity.
  MatrixT<T> Bw, F, Cq;
  if (!base_matrices<T>(L, p, schedule, M, Dm, K, Bw, F, Cq)) return false;
  MatrixT<T> Mi;
  if (!physical_detail::spd_inverse<T>(M, Mi)) return false;
  const Index nm = static_cast<Index>(L.modes.size());
  const Index nb = 2 * nd + 2 * nm;
  Lti<T> body;
  body.A = MatrixT<T>::Constant(nb, nb, zero);
  body.B = MatrixT<T>::Constant(nb, L.n_in, zero);
  body.C = MatrixT<T>::Constant(nd, nb, zero);
  body.D = MatrixT<T>::Constant(nd, L.n_in, zero);
  for (Index i = 0; i < nd; ++i) {
    body.A(i, nd + i) = one;
    body.C(i, i) = one;
  }
  body.A.block(nd, 0, nd, nd) = -(Mi * K);
  body.A.block(nd, nd, nd, nd) = -(Mi * Dm);
  body.B.block(nd, 0, nd, L.n_in) = Mi * Bw;
  for (Index k = 0; k < nm; ++k) {
    const auto& b = L.modes[static_cast<std::size_t>(k)];
    const Index i = 2 * nd + 2 * k;
    const T w = p[b.params[0]], z = p[b.params[1]];
    body.A(i, i + 1) = one;
    body.A(i + 1, i) = -w * w;
    body.A(i + 1, i + 1) = T(-2.0) * z * w;
    for (Index d = 0; d < nd; ++d) {
      const T phi = p[b.params[static_cast<std::size_t>(2 + d)]];
      for (Index j = 0; j < L.n_in; ++j) body.B(i + 1, j) += phi * Bw(d, j);
      body.C(d, i) = phi;
    }
  }
  if (L.mechanical && std::any_of(L.mechanical->output_derivative.begin(), L.mechanical->output_derivative.end(),
                                  [](int d) { return d != 0; })) {
    // Sensors of velocity or acceleration: each output row is C_q applied to q, q' or q''.
    MatrixT<T> C1 = MatrixT<T>::Constant(nd, nb, zero), C2 = MatrixT<T>::Constant(nd, nb, zero);
    MatrixT<T> D2 = Mi * Bw;  // q'' = M⁻¹(B_w w − D q' − K q) + Σ φ η''
    for (Index i = 0; i < nd; ++i) C1(i, nd + i) = one;
    C2.leftCols(2 * nd) = body.A.block(nd, 0, nd, 2 * nd);
    for (Index k = 0; k < nm; ++k) {
      const auto& b = L.modes[static_cast<std::size_t>(k)];
      const Index i = 2 * nd + 2 * k;
      const T w = p[b.params[0]], z = p[b.params[1]];
      for (Index d = 0; d < nd; ++d) {
        const T phi = p[b.params[static_cast<std::size_t>(2 + d)]];
        C1(d, i + 1) = phi;
        C2(d, i) = -phi * w * w;
        C2(d, i + 1) = T(-2.0) * phi * z * w;
        for (Index j = 0; j < L.n_in; ++j) D2(d, j) += phi * body.B(i + 1, j);
      }
    }
    const MatrixT<T> C0 = body.C;
    body.C = MatrixT<T>(Cq.rows(), nb);
    body.D = MatrixT<T>::Constant(Cq.rows(), L.n_in, zero);
    for (Index r = 0; r < Cq.rows(); ++r) {
      const int order = L.mechanical->output_derivative[static_cast<std::size_t>(r)];
      body.C.row(r) = Cq.row(r) * (order == 0 ? C0 : order == 1 ? C1 : C2);
      if (order == 2) body.D.row(r) = Cq.row(r) * D2;
    }
  } else if (Cq.size() > 0) {
    body.C = Cq * body.C;
    body.D = MatrixT<T>::Constant(Cq.rows(), L.n_in, zero);
  }
  const Lti<T> in = physical_detail::block_chain<T>(L.input_blocks, L.n_in, p);
  const Lti<T> out = physical_detail::block_chain<T>(L.output_blocks, L.n_out, p);
  Lti<T> driven = physical_detail::series(in, body);
  if (F.size() > 0) {
    // The chain's input is w − F q': close the loop from the body's velocities
    // (states n_in_states + nd .. + 2 nd of the series) to the chain's input.
    const Index ni = in.A.rows();
    const MatrixT<T> BF = driven.B * F;  // (states) × nd
    for (Index d = 0; d < nd; ++d) driven.A.col(ni + nd + d) -= BF.col(d);
    const MatrixT<T> DF = driven.D * F;
    for (Index d = 0; d < nd; ++d) driven.C.col(ni + nd + d) -= DF.col(d);
  }
  const Lti<T> all = physical_detail::series(driven, out);
  A = all.A;
  B = all.B;
  C = all.C;
  D = all.D;
  return true;
}

// e^X by scaling and squaring with a degree-14 Taylor polynomial: X is scaled by
// 2^-s so that its 1-norm is <= 0.5, where the truncation error is below
// 0.5^15/15! ≈ 2e-17 relative (Moler & Van Loan, "Nineteen dubious ways",
// method 3).  Works for Jets (derivatives are exact derivatives of the
// approximation).
template <class T>
MatrixT<T> expm_taylor(const MatrixT<T>& X) {
  const Index n = X.rows();
  double norm = 0.0;
  for (Index j = 0; j < n; ++j) {
    double col = 0.0;
    for (Index i = 0; i < n; ++i) col += std::abs(ScalarValue<T>::of(X(i, j)));
    norm = std::max(norm, col);
  }
  int s = 0;
  while (norm > 0.5) {
    norm *= 0.5;
    ++s;
  }
  const MatrixT<T> Y = X * T(std::ldexp(1.0, -s));
  const MatrixT<T> I = MatrixT<T>::Identity(n, n);
  MatrixT<T> E = I;
  constexpr int kTaylorDegree = 14;
  for (int k = kTaylorDegree; k >= 1; --k) E = I + (Y * E) * T(1.0 / k);
  for (int k = 0; k < s; ++k) E = E * E;
  return E;
}

// ZOH over h: exp([[A B]; [0 0]] h) = [[Ad Bd]; [0 I]].
template <class T>
void zoh_discretize(const MatrixT<T>& A, const MatrixT<T>& B, const T& h, MatrixT<T>& Ad, MatrixT<T>& Bd) {
  const Index n = A.rows(), m = B.cols();
  MatrixT<T> Z = MatrixT<T>::Constant(n + m, n + m, T(0.0));
  Z.topLeftCorner(n, n) = A * h;
  Z.topRightCorner(n, m) = B * h;
  const MatrixT<T> E = expm_taylor<T>(Z);
  Ad = E.topLeftCorner(n, n);
  Bd = E.topRightCorner(n, m);
}

// The exactly sampled model (header comment): x[k+1] = Ad x + B_new u[k − k_j] + B_old u[k − k_j − 1].
template <class T>
struct SampledModel {
  MatrixT<T> Ad, B_new, B_old, C, D;
  std::vector<Index> shift;      // k_j per input
  std::vector<bool> fractional;  // f_j > 0 per input
};

// Per-input total delay tau_j (0 without delay blocks on input j).
template <class T>
std::vector<T> input_delays(const ModelLayout& L, const T* p) {
  std::vector<T> tau(static_cast<std::size_t>(L.n_in), T(0.0));
  for (Index j = 0; j < L.n_in; ++j)
    for (Index q : L.delays[static_cast<std::size_t>(j)]) tau[static_cast<std::size_t>(j)] += p[q];
  return tau;
}

template <class T>
SampledModel<T> sample_model(const MatrixT<T>& A, const MatrixT<T>& B, const MatrixT<T>& C, const MatrixT<T>& D,
                             const std::vector<T>& tau, double T_s) {
  // A fractional part within 1e-12 of a whole sample is that whole sample (the
  // ZOH is continuous in tau there; this keeps whole delays on the plain route).
  constexpr double kWholeSample = 1e-12;
  const Index n = A.rows(), m = B.cols();
  SampledModel<T> s;
  s.C = C;
  s.D = D;
  s.shift.assign(static_cast<std::size_t>(m), 0);
  s.fractional.assign(static_cast<std::size_t>(m), false);
  std::vector<T> f(static_cast<std::size_t>(m), T(0.0));
  for (Index j = 0; j < m; ++j) {
    const double x = ScalarValue<T>::of(tau[static_cast<std::size_t>(j)]) / T_s;
    Index k = static_cast<Index>(std::floor(x + kWholeSample));
    if (k < 0) k = 0;
    s.shift[static_cast<std::size_t>(j)] = k;
    const double frac = x - static_cast<double>(k);
    if (frac > kWholeSample) {
      s.fractional[static_cast<std::size_t>(j)] = true;
      f[static_cast<std::size_t>(j)] = tau[static_cast<std::size_t>(j)] / T(T_s) - T(static_cast<double>(k));
    }
  }
  zoh_discretize<T>(A, B, T(T_s), s.Ad, s.B_new);
  s.B_old = MatrixT<T>::Constant(n, m, T(0.0));
  // inputs with a fractional part: group equal fractions (one shared delay: one group)
  std::vector<bool> done(static_cast<std::size_t>(m), false);
  for (Index j = 0; j < m; ++j) {
    if (!s.fractional[static_cast<std::size_t>(j)] || done[static_cast<std::size_t>(j)]) continue;
    std::vector<Index> group;
    for (Index i = j; i < m; ++i)
      if (s.fractional[static_cast<std::size_t>(i)] && !done[static_cast<std::size_t>(i)] &&
          ScalarValue<T>::of(f[static_cast<std::size_t>(i)]) == ScalarValue<T>::of(f[static_cast<std::size_t>(j)])) {
        group.push_back(i);
        done[static_cast<std::size_t>(i)] = true;
      }
    MatrixT<T> Bg(n, static_cast<Index>(group.size()));
    for (std::size_t g = 0; g < group.size(); ++g) Bg.col(static_cast<Index>(g)) = B.col(group[g]);
    const T fj = f[static_cast<std::size_t>(j)];
    MatrixT<T> Phi1, G1, Phi2, G2;
    zoh_discretize<T>(A, Bg, (T(1.0) - fj) * T(T_s), Phi1, G1);
    zoh_discretize<T>(A, Bg, fj * T(T_s), Phi2, G2);
    const MatrixT<T> old = Phi1 * G2;
    for (std::size_t g = 0; g < group.size(); ++g) {
      s.B_new.col(group[g]) = G1.col(static_cast<Index>(g));
      s.B_old.col(group[g]) = old.col(static_cast<Index>(g));
    }
  }
  return s;
}

// The model at one scheduling value.
struct PhysicalStateSpace {
  StateSpace system;                // inputs/outputs named after the base
  std::vector<double> input_delay_s;  // per input; continuous: to apply on top of system
  // discrete: the delays are inside system (shift registers, b_old), delay_samples
  // the largest whole shift (0 without delay)
  Index delay_samples = 0;
};

// Continuous (sample_period_s == 0) or exactly sampled model.  In discrete time
// the delays are realised as L registers per input (L = max_j k_j + [f_j > 0]) at
// the end of the state vector, so that system alone simulates them.
// @throws InputError  model invalid; scheduling value outside the base's range or
//   not finite; sample_period_s < 0 or not finite; mass matrix not positive definite.
PhysicalStateSpace physical_state_space(const PhysicalModel& model, double schedule, double sample_period_s = 0.0);

// Frequency response at omega_rad_s (layout of idlib/core/types.h), continuous
// (P(jω) diag(e^{−jω tau_j})) or sampled (header comment).
// @throws InputError  as physical_state_space; an ω not finite.
std::vector<Eigen::MatrixXcd> physical_response(const PhysicalModel& model, double schedule,
                                                const Eigen::VectorXd& omega_rad_s, double sample_period_s = 0.0);

// What a structural mode of shape φ adds to the base's response, the input and output
// blocks apart: C_q φ φᵀ B_w (jω)^d_i / (ω_m² − ω² + 2jζω_m ω) in output row i, d_i the
// derivative that output measures (0 position; a mechanical base's velocity or
// acceleration sensors).  C_q (n_out × n_dof) and B_w (n_dof × n_in) at the model's
// values and the scheduling value (diagnose seeds a mode's shape from them).
// @throws InputError  as physical_state_space.
struct ModeMaps {
  Eigen::MatrixXd Cq, Bw;
  std::vector<int> output_derivative;
};
ModeMaps mode_maps(const PhysicalModel& model, double schedule);

// @throws InputError  the scheduling value is outside the base's range (the
//   platform: |x_b| > beam_stroke_m) or not finite.
void check_schedule(const PhysicalModel& model, double schedule);

}  // namespace lpvid
