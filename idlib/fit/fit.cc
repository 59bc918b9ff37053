#include "idlib/fit/fit.h"
#include "idlib/core/eigen_decompositions.h"

#include <ceres/ceres.h>
#include <ceres/jet.h>
#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <nlopt.hpp>
#include <numbers>
#include <random>

#include "idlib/lti/frequency_response.h"
#include "idlib/physical/evaluate.h"

namespace lpvid {

template <int N>
struct ScalarValue<ceres::Jet<double, N>> {
  static double of(const ceres::Jet<double, N>& x) { return x.a; }
};

namespace {

using Cx = Complex;
constexpr int kMaxDim = 6;  // largest base (inputs/outputs); fixed capacity, no heap per frequency
using CMat = Eigen::Matrix<Cx, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDim, kMaxDim>;
using RMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDim, kMaxDim>;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A data set ready for evaluation (used frequencies only).
struct Prepared {
  double sched = 0.0;
  std::vector<double> omega;
  std::vector<CMat> data;       // Ĥ
  std::vector<CMat> ctrl;       // C(λ) (G/S targets)
  std::vector<RMat> weight;     // 1/σ
  std::vector<RMat> inv_scale;  // 1/s
  std::vector<RMat> sigma;      // σ per real part
};

// Shape of the target for a base: rows × cols.
std::pair<Index, Index> target_shape(const BaseInfo& b, FitTarget t) {
  const Index ni = static_cast<Index>(b.input_names.size()), no = static_cast<Index>(b.output_names.size());
  return t == FitTarget::kInputSensitivity ? std::pair<Index, Index>{ni, ni} : std::pair<Index, Index>{no, ni};
}

// Everything needed to evaluate the target response and its derivatives.
class Engine {
 public:
  Engine(const PhysicalModel& model, const FitOptions& options)
      : layout_(model), options_(options), full_(model.values()), free_(model.free_indices()) {
    // which free parameters are delays of which input (continuous route)
    delay_of_.assign(free_.size(), {});
    for (Index j = 0; j < layout_.n_in; ++j)
      for (Index q : layout_.delays[static_cast<std::size_t>(j)])
        for (std::size_t f = 0; f < free_.size(); ++f)
          if (free_[f] == q) delay_of_[f].push_back(j);
  }

  Index num_free() const { return static_cast<Index>(free_.size()); }
  const std::vector<Index>& free() const { return free_; }
  Eigen::VectorXd& full() { return full_; }
  const ModelLayout& layout() const { return layout_; }

  // T at the prepared frequencies, and when dT != nullptr its derivatives
  // (dT[k][q] = ∂T(ω_k)/∂θ_free(q)).  Returns false when the model cannot be
  // evaluated (mass matrix not positive definite, non-finite response).
  bool evaluate(const Prepared& d, std::vector<CMat>& T, std::vector<std::vector<CMat>>* dT) const {
    const Index p = num_free();
    Built b;
    if (dT == nullptr || p == 0) {
      if (!build<0>(d, b, 0)) return false;
      return respond(d, 0, b, T, nullptr);
    }
    // Forward-mode derivatives kLanes parameters at a time (as Ceres'
    // DynamicAutoDiffCostFunction strides): each lane's arithmetic is the same
    // whatever the Jet's width, so the derivatives equal those of one Jet as wide as
    // the parameters, and the file instantiates the model's Jet code once instead
    // of once per width (it was six widths: 0, 8, 16, 24, 32, 48 — most of this
    // file's compile time, .ci/run's budget).
    for (Index q0 = 0; q0 < p; q0 += kLanes)
      if (!build<kLanes>(d, b, q0)) return false;
    return respond(d, p, b, T, dT);
  }

 private:
  static constexpr int kLanes = 8;

  // The model's matrices at the current parameters and, for N > 0, the derivatives
  // by the free parameters q0 .. q0 + N - 1 (forward-mode Jets of N lanes); b's
  // values and the derivative arrays are set by the call with q0 = 0.  Only this
  // part depends on N: the response at every frequency (respond) does not.
  struct Built {
    Eigen::MatrixXd A, Bn, Bo, C, D;
    std::vector<Eigen::MatrixXd> dA, dBn, dBo, dC, dD;
    std::vector<Index> shift;
    std::vector<bool> frac;
    std::vector<double> tau;
  };

  template <int N>
  bool build(const Prepared& d, Built& b, const Index q0) const {
    const Index p = N == 0 ? 0 : num_free();
    const Index lanes = N == 0 ? 0 : std::min<Index>(N, p - q0);
    const double ts = options_.sample_period_s;
    Eigen::MatrixXd& A = b.A; Eigen::MatrixXd& Bn = b.Bn; Eigen::MatrixXd& Bo = b.Bo;
    Eigen::MatrixXd& C = b.C; Eigen::MatrixXd& D = b.D;
    std::vector<Index>& shift = b.shift;
    std::vector<bool>& frac = b.frac;
    std::vector<double>& tau = b.tau;
    if constexpr (N == 0) {
      Eigen::MatrixXd B;
      if (!build_continuous<double>(layout_, full_.data(), d.sched, A, B, C, D)) return false;
      tau = input_delays<double>(layout_, full_.data());
      if (ts > 0.0) {
        SampledModel<double> sm = sample_model<double>(A, B, C, D, tau, ts);
        A = std::move(sm.Ad);
        Bn = std::move(sm.B_new);
        Bo = std::move(sm.B_old);
        shift = sm.shift;
        frac = sm.fractional;
      } else {
        Bn = std::move(B);
        Bo = Eigen::MatrixXd::Zero(A.rows(), Bn.cols());
      }
    } else {
      using J = ceres::Jet<double, N>;
      std::vector<J> x(static_cast<std::size_t>(full_.size()));
      for (Index i = 0; i < full_.size(); ++i) x[static_cast<std::size_t>(i)] = J(full_(i));
      for (Index l = 0; l < lanes; ++l) x[static_cast<std::size_t>(free_[static_cast<std::size_t>(q0 + l)])].v[l] = 1.0;
      MatrixT<J> Aj, Bj, Cj, Dj, Boj;
      if (!build_continuous<J>(layout_, x.data(), d.sched, Aj, Bj, Cj, Dj)) return false;
      const std::vector<J> tj = input_delays<J>(layout_, x.data());
      tau.clear();
      for (const J& t : tj) tau.push_back(t.a);
      if (ts > 0.0) {
        SampledModel<J> sm = sample_model<J>(Aj, Bj, Cj, Dj, tj, ts);
        Aj = std::move(sm.Ad);
        Bj = std::move(sm.B_new);
        Boj = std::move(sm.B_old);
        shift = sm.shift;
        frac = sm.fractional;
      } else {
        Boj = MatrixT<J>::Constant(Aj.rows(), Bj.cols(), J(0.0));
      }
      auto split = [p, q0, lanes](const MatrixT<J>& m, Eigen::MatrixXd& v, std::vector<Eigen::MatrixXd>& dv) {
        v.resize(m.rows(), m.cols());
        if (q0 == 0) dv.assign(static_cast<std::size_t>(p), Eigen::MatrixXd(m.rows(), m.cols()));
        for (Index i = 0; i < m.rows(); ++i)
          for (Index j = 0; j < m.cols(); ++j) {
            v(i, j) = m(i, j).a;
            for (Index l = 0; l < lanes; ++l) dv[static_cast<std::size_t>(q0 + l)](i, j) = m(i, j).v[l];
          }
      };
      split(Aj, A, b.dA);
      split(Bj, Bn, b.dBn);
      split(Boj, Bo, b.dBo);
      split(Cj, C, b.dC);
      split(Dj, D, b.dD);
    }
    return true;
  }

  // T (and dT) at the prepared frequencies from the built matrices; p: the number
  // of parameters whose derivatives b holds (0: none).
  bool respond(const Prepared& d, const Index p, const Built& b, std::vector<CMat>& T,
               std::vector<std::vector<CMat>>* dT) const {
    const double ts = options_.sample_period_s;
    const Eigen::MatrixXd& A = b.A; const Eigen::MatrixXd& Bn = b.Bn; const Eigen::MatrixXd& Bo = b.Bo;
    const Eigen::MatrixXd& C = b.C; const Eigen::MatrixXd& D = b.D;
    const std::vector<Eigen::MatrixXd>& dA = b.dA; const std::vector<Eigen::MatrixXd>& dBn = b.dBn;
    const std::vector<Eigen::MatrixXd>& dBo = b.dBo; const std::vector<Eigen::MatrixXd>& dC = b.dC;
    const std::vector<Eigen::MatrixXd>& dD = b.dD;
    const std::vector<Index>& shift = b.shift;
    const std::vector<bool>& frac = b.frac;
    const std::vector<double>& tau = b.tau;
    if (!A.allFinite() || !Bn.allFinite() || !Bo.allFinite() || !C.allFinite()) return false;
    const Index n = A.rows(), ni = Bn.cols(), no = C.rows();
    const bool any_old = ts > 0.0 && Bo.cwiseAbs().maxCoeff() > 0.0;
    const std::size_t F = d.omega.size();
    T.resize(F);
    if (dT != nullptr) dT->resize(F);

    // Modal route: A = V diag(μ) V⁻¹, so (λI − A)⁻¹ = V diag(1/(λ − μ)) V⁻¹ and
    // every frequency costs O(n·n_in·n_out) (plus O(n²) per parameter for the
    // derivatives) instead of a complex LU.  Used when cond(V) (Frobenius estimate)
    // is below kMaxModalCondition, so that round-off stays below ~1e-16·1e6 = 1e-10
    // relative; otherwise (near-defective A, e.g. repeated lag poles or delay
    // registers) the Schur route: A = Q T Qᴴ (complex Schur, Q unitary, T upper
    // triangular), so (λI − A)⁻¹ = Q (λI − T)⁻¹ Qᴴ and every frequency costs two
    // triangular solves, O(n²·(n_in + n_out)), where a complex LU and inverse cost
    // O(n³); Q being unitary, the transformation adds no round-off beyond the Schur
    // form's backward error whatever the conditioning of A's eigenvectors.  The
    // per-frequency LU route remains for a Schur iteration that does not converge.
    constexpr double kMaxModalCondition = 1e6;
    bool modal = n > 0;
    bool schur = false;
    Eigen::VectorXcd mu;
    Eigen::MatrixXcd V, Vinv, Ch, Bhn, Bho;
    Eigen::MatrixXcd Tq;  // the Schur route's triangular factor (Ch, Bhn, Bho: C Q, Qᴴ B)
    // Derivatives in modal coordinates, stacked over the parameters (q-th block):
    // dAv (n·p × n) = [V⁻¹ dA_q V], dBv (n·p × n_in) = [V⁻¹ dB_q], dCv (n_out·p × n) = [dC_q V],
    // so that every frequency needs three GEMMs for all parameters at once.
    Eigen::MatrixXcd dAv, dBvn, dBvo, dCv;
    // Only the parameters that move A or B (inner) enter the first products and only
    // those that move C (outer) the last: output blocks (gains, cross-talk) touch C
    // alone, so their rows would be zeros.  pos_inner/pos_outer: a free parameter's
    // row block in the stacks (-1: not there).
    std::vector<Index> pos_inner(static_cast<std::size_t>(p), -1), pos_outer(static_cast<std::size_t>(p), -1);
    Index n_inner = 0, n_outer = 0;
    if (dT != nullptr)
      for (Index q = 0; q < p; ++q) {
        const auto s = static_cast<std::size_t>(q);
        const auto nonzero = [](const Eigen::MatrixXd& m) { return m.size() > 0 && m.cwiseAbs().maxCoeff() > 0.0; };
        if (nonzero(dA[s]) || nonzero(dBn[s]) || (any_old && nonzero(dBo[s]))) pos_inner[s] = n_inner++;
        if (nonzero(dC[s])) pos_outer[s] = n_outer++;
      }
    if (modal) {
      const Eigen::EigenSolver<Eigen::MatrixXd> es(A);
      modal = es.info() == Eigen::Success;
      if (modal) {
        V = es.eigenvectors();
        Vinv = V.partialPivLu().inverse();
        modal = Vinv.allFinite() && V.norm() * Vinv.norm() < kMaxModalCondition;
        if (modal) {
          mu = es.eigenvalues();
          Ch = C.cast<Cx>() * V;
          Bhn = Vinv * Bn.cast<Cx>();
          Bho = Vinv * Bo.cast<Cx>();
        }
      }
      if (!modal) {
        const Eigen::ComplexSchur<Eigen::MatrixXd> cs(A);
        schur = cs.info() == Eigen::Success && cs.matrixT().allFinite();
        if (schur) {
          V = cs.matrixU();
          Vinv = V.adjoint();
          Tq = cs.matrixT().triangularView<Eigen::Upper>();
          Ch = C.cast<Cx>() * V;
          Bhn = Vinv * Bn.cast<Cx>();
          Bho = Vinv * Bo.cast<Cx>();
        }
      }
    }
    if (dT != nullptr && p > 0) {
      // Stacked derivatives: in modal coordinates (V⁻¹ dA_q V, V⁻¹ dB_q, dC_q V) on the
      // modal route, in Schur coordinates (Qᴴ dA_q Q, Qᴴ dB_q, dC_q Q) on the Schur route;
      // untransformed on the resolvent route, where with X = (λI − A)⁻¹ B_z and
      // Y = C (λI − A)⁻¹ every frequency likewise needs three GEMMs for all parameters.
      const Eigen::MatrixXcd Vr = modal || schur ? V : Eigen::MatrixXcd::Identity(n, n);
      const Eigen::MatrixXcd Vl = modal || schur ? Vinv : Eigen::MatrixXcd::Identity(n, n);
      dAv.resize(n * n_inner, n);
      dBvn.resize(n * n_inner, ni);
      if (any_old) dBvo.resize(n * n_inner, ni);
      dCv.resize(no * n_outer, n);
      for (Index q = 0; q < p; ++q) {
        const auto s = static_cast<std::size_t>(q);
        if (const Index r = pos_inner[s]; r >= 0) {
          dAv.middleRows(r * n, n).noalias() = Vl * (dA[s].cast<Cx>() * Vr);
          dBvn.middleRows(r * n, n).noalias() = Vl * dBn[s].cast<Cx>();
          if (any_old) dBvo.middleRows(r * n, n).noalias() = Vl * dBo[s].cast<Cx>();
        }
        if (const Index r = pos_outer[s]; r >= 0) dCv.middleRows(r * no, no).noalias() = dC[s].cast<Cx>() * Vr;
      }
    }
    const Eigen::MatrixXcd Ac = A.cast<Cx>(), Bnc = Bn.cast<Cx>(), Boc = Bo.cast<Cx>(), Cc = C.cast<Cx>();
    const Eigen::MatrixXcd Dc = D.cast<Cx>();
    // dD is zero unless a block has feedthrough depending on a parameter (resonance gains)
    std::vector<bool> dD_nonzero;
    for (const auto& m : dD) dD_nonzero.push_back(m.cwiseAbs().maxCoeff() > 0.0);
    // work space, allocated once per evaluation
    Eigen::MatrixXcd Z(n, n), Chd(no, n), Bhd(n, ni), Bhz(n, ni), X, Y, Bz, tmp(n, ni), dPm(no, ni);
    Eigen::MatrixXcd U, R, S;  // stacked derivative products
    // With X = (λI − A)⁻¹ B_z and Y = C (λI − A)⁻¹ in the route's coordinates (modal,
    // Schur or none): U = [dA_q X + dB_q] (n·p_in × n_in, inner q); R = Y U reshaped
    // (n_out × n_in·p_in, column j·p_in + q); S = [dC_q X] (n_out·p_out × n_in).
    const auto stacked_products = [&](const Eigen::MatrixXcd& Yk, const Eigen::MatrixXcd& Xk, const Cx zinv) {
      if (n_inner > 0) {
        U.noalias() = dAv * Xk;
        U += dBvn;
        if (any_old) U += dBvo * zinv;
        R.noalias() = Yk * Eigen::Map<const Eigen::MatrixXcd>(U.data(), n, ni * n_inner);
      }
      if (n_outer > 0) S.noalias() = dCv * Xk;
    };
    for (std::size_t k = 0; k < F; ++k) {
      const double w = d.omega[k];
      const Cx lambda = ts > 0.0 ? std::exp(Cx(0.0, w * ts)) : Cx(0.0, w);
      const Cx zinv = ts > 0.0 ? 1.0 / lambda : Cx(0.0);
      // column factors: z^-k_j (sampled) or e^{-jω tau_j} (continuous); D_f column j × z⁻¹ when fractional
      Eigen::Matrix<Cx, Eigen::Dynamic, 1, 0, kMaxDim, 1> colf(ni), dcol(ni);
      for (Index j = 0; j < ni; ++j) {
        const auto jj = static_cast<std::size_t>(j);
        colf(j) = ts > 0.0 ? std::exp(Cx(0.0, -w * ts * static_cast<double>(shift[jj]))) : std::exp(Cx(0.0, -w * tau[jj]));
        dcol(j) = ts > 0.0 && frac[jj] ? zinv : Cx(1.0);
      }
      CMat P(no, ni);
      if (modal) {
        if (any_old)
          Bhz = Bhn + Bho * zinv;
        else
          Bhz = Bhn;
        for (Index a = 0; a < n; ++a) {
          const Cx da = 1.0 / (lambda - mu(a));
          Chd.col(a) = Ch.col(a) * da;
        }
        dPm.noalias() = Chd * Bhz;
        P = dPm + Dc * dcol.asDiagonal();
        if (dT != nullptr && p > 0) {
          for (Index a = 0; a < n; ++a) Bhd.row(a) = Bhz.row(a) / (lambda - mu(a));
          stacked_products(Chd, Bhd, zinv);  // X = Λ Bh, Y = Ch Λ
        }
      } else if (schur) {
        // X = (λI − T)⁻¹ Qᴴ B_z and Y = C Q (λI − T)⁻¹ by back substitution; then as
        // on the resolvent route below, in Schur coordinates.
        Z = -Tq;
        Z.diagonal().array() += lambda;
        Bhz = any_old ? Eigen::MatrixXcd(Bhn + Bho * zinv) : Bhn;
        X = Z.triangularView<Eigen::Upper>().solve(Bhz);
        if (dT != nullptr && p > 0) {
          Y = Z.triangularView<Eigen::Upper>().solve<Eigen::OnTheRight>(Ch);
          stacked_products(Y, X, zinv);
        }
        dPm.noalias() = Ch * X;
        P = dPm + Dc * dcol.asDiagonal();
      } else {
        Z = -Ac;
        Z.diagonal().array() += lambda;
        const Eigen::PartialPivLU<Eigen::MatrixXcd> lu(Z);
        Bz = any_old ? Eigen::MatrixXcd(Bnc + Boc * zinv) : Bnc;
        if (dT == nullptr || p == 0) {
          X = lu.solve(Bz);
        } else {
          const Eigen::MatrixXcd Rz = lu.inverse();
          X = Rz * Bz;
          Y = Cc * Rz;
          stacked_products(Y, X, zinv);
        }
        P = Cc * X + Dc * dcol.asDiagonal();
      }
      const CMat P0 = P;  // before the column factors
      P = P * colf.asDiagonal();
      if (!P.allFinite()) return false;
      // The target and its sensitivity to P: dT = Lm dP Rm.
      CMat Lm, Rm;
      const bool plant = options_.target == FitTarget::kPlant;
      switch (options_.target) {
        case FitTarget::kPlant:
          T[k] = P;
          break;
        case FitTarget::kClosedLoopOutput: {
          const CMat S = (CMat::Identity(ni, ni) + d.ctrl[k] * P).inverse();
          T[k] = P * S;
          Lm = CMat::Identity(no, no) - T[k] * d.ctrl[k];
          Rm = S;
          break;
        }
        case FitTarget::kInputSensitivity: {
          const CMat S = (CMat::Identity(ni, ni) + d.ctrl[k] * P).inverse();
          T[k] = S;
          Lm = -S * d.ctrl[k];
          Rm = S;
          break;
        }
      }
      if (dT == nullptr || p == 0) continue;
      auto& out = (*dT)[k];
      out.resize(static_cast<std::size_t>(p));
      for (Index q = 0; q < p; ++q) {
        const auto s = static_cast<std::size_t>(q);
        {
          // dP = Ch Λ (dAh Λ Bh + dBh) + dCh Λ Bh (modal), Y (dA X + dB) + dC X
          // (resolvent): gathered from the stacked products
          const Index qi = pos_inner[s], qo = pos_outer[s];
          for (Index j = 0; j < ni; ++j)
            for (Index i = 0; i < no; ++i)
              dPm(i, j) = (qi >= 0 ? R(i, j * n_inner + qi) : Cx(0.0)) + (qo >= 0 ? S(qo * no + i, j) : Cx(0.0));
        }
        CMat dP = dPm;
        if (dD_nonzero[s]) dP += dD[s].cast<Cx>() * dcol.asDiagonal();
        dP = dP * colf.asDiagonal();
        if (ts == 0.0)
          for (Index j : delay_of_[s]) dP.col(j) += Cx(0.0, -w) * P0.col(j) * colf(j);
        out[s] = plant ? dP : CMat(Lm * dP * Rm);
      }
    }
    return true;
  }

  ModelLayout layout_;
  const FitOptions& options_;
  Eigen::VectorXd full_;
  std::vector<Index> free_;
  std::vector<std::vector<Index>> delay_of_;  // per free parameter: inputs it delays
};

// Optimisation coordinates: log for parameters with a positive lower bound.
struct Coordinates {
  std::vector<bool> log;
  std::vector<double> lower, upper;  // in z

  double to_theta(Index q, double z) const { return log[static_cast<std::size_t>(q)] ? std::exp(z) : z; }
  double to_z(Index q, double theta) const { return log[static_cast<std::size_t>(q)] ? std::log(theta) : theta; }
};

Coordinates make_coordinates(const PhysicalModel& model, const std::vector<Index>& free) {
  Coordinates c;
  for (Index i : free) {
    const auto& par = model.parameters[static_cast<std::size_t>(i)];
    const bool lg = par.lower > 0.0;
    c.log.push_back(lg);
    c.lower.push_back(lg ? std::log(par.lower) : par.lower);
    c.upper.push_back(lg ? std::log(par.upper) : par.upper);
  }
  return c;
}

// A free parameter's Gaussian prior: one more residual, (θ − mean) / sigma, in the
// units of the data's residuals (their noise), so the least squares are a MAP fit.
struct PriorRow {
  Index q = 0;  // free-parameter index
  double mean = 0.0, sigma = 1.0;
};

std::vector<PriorRow> prior_rows(const PhysicalModel& m, const std::vector<Index>& free) {
  std::vector<PriorRow> out;
  for (std::size_t q = 0; q < free.size(); ++q) {
    const PhysicalParameter& par = m.parameters[static_cast<std::size_t>(free[q])];
    if (par.has_prior()) out.push_back({static_cast<Index>(q), par.prior_mean, par.prior_sigma});
  }
  return out;
}

struct Problem {
  Engine& engine;
  const Coordinates& coords;
  const std::vector<Prepared>& sets;
  Index residuals = 0;  // the data's, then one per prior
  std::vector<PriorRow> priors = {};

  void set_z(const double* z) {
    for (Index q = 0; q < engine.num_free(); ++q)
      engine.full()(engine.free()[static_cast<std::size_t>(q)]) = coords.to_theta(q, z[q]);
  }

  // Residuals (and jac, row-major residuals × p, d r / d z) at z.
  bool residual(const double* z, double* r, double* jac) {
    set_z(z);
    const Index p = engine.num_free();
    std::vector<CMat> T;
    std::vector<std::vector<CMat>> dT;
    Index row = 0;
    for (const Prepared& d : sets) {
      if (!engine.evaluate(d, T, jac != nullptr ? &dT : nullptr)) return false;
      for (std::size_t k = 0; k < d.omega.size(); ++k)
        for (Index i = 0; i < d.data[k].rows(); ++i)
          for (Index j = 0; j < d.data[k].cols(); ++j) {
            const double w = d.weight[k](i, j);
            const Cx e = (T[k](i, j) - d.data[k](i, j)) * w;
            r[row] = e.real();
            r[row + 1] = e.imag();
            if (jac != nullptr)
              for (Index q = 0; q < p; ++q) {
                const double chain = coords.log[static_cast<std::size_t>(q)]
                                         ? engine.full()(engine.free()[static_cast<std::size_t>(q)])
                                         : 1.0;
                const Cx g = dT[k][static_cast<std::size_t>(q)](i, j) * (w * chain);
                jac[row * p + q] = g.real();
                jac[(row + 1) * p + q] = g.imag();
              }
            row += 2;
          }
    }
    for (const PriorRow& pr : priors) {
      const auto s = static_cast<std::size_t>(pr.q);
      const double theta = engine.full()(engine.free()[s]);
      r[row] = (theta - pr.mean) / pr.sigma;
      if (jac != nullptr) {
        for (Index q = 0; q < p; ++q) jac[row * p + q] = 0.0;
        jac[row * p + pr.q] = (coords.log[s] ? theta : 1.0) / pr.sigma;
      }
      ++row;
    }
    return true;
  }

  double cost(const double* z) {
    std::vector<double> r(static_cast<std::size_t>(residuals));
    if (!residual(z, r.data(), nullptr)) return kInf;
    double c = 0.0;
    for (double x : r) c += x * x;
    return std::isfinite(c) ? c : kInf;
  }
};

class CeresCost final : public ceres::CostFunction {
 public:
  explicit CeresCost(Problem& problem) : problem_(problem) {
    set_num_residuals(static_cast<int>(problem.residuals));
    mutable_parameter_block_sizes()->push_back(static_cast<int32_t>(problem.engine.num_free()));
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    return problem_.residual(parameters[0], residuals, jacobians != nullptr ? jacobians[0] : nullptr);
  }

 private:
  Problem& problem_;
};

Index count_residuals(const std::vector<Prepared>& sets) {
  Index n = 0;
  for (const auto& d : sets)
    for (const auto& m : d.data) n += 2 * m.size();
  return n;
}

std::vector<CMat> controller_at(const StateSpace& c, const std::vector<double>& omega) {
  Eigen::VectorXd w(static_cast<Index>(omega.size()));
  for (std::size_t k = 0; k < omega.size(); ++k) w(static_cast<Index>(k)) = omega[k];
  const auto r = evaluate_response(c, w);
  std::vector<CMat> out;
  for (const auto& m : r) out.emplace_back(m);
  return out;
}

bool same_line(double a, double b) { return std::abs(a - b) <= kControllerLineRelTolerance * std::abs(b); }

void check_controller(const FitOptions& o, const BaseInfo* base) {
  if (o.target == FitTarget::kPlant) return;
  if (!o.controller && !o.measured_controller)
    throw InputError(fmt::format("target {} needs the controller C (e = -q -> u_c); give it (--controller C.json, or "
                                 "its measured response C.csv)",
                                 target_name(o.target)));
  if (o.controller && o.measured_controller)
    throw InputError("both a controller model and a measured controller are given; give one");
  Index c_in = 0, c_out = 0;
  if (o.controller) {
    o.controller->validate();
    c_in = o.controller->num_inputs();
    c_out = o.controller->num_outputs();
  } else {
    const FrequencyResponse& c = *o.measured_controller;
    if (c.num_frequencies() == 0 || c.response.size() != static_cast<std::size_t>(c.num_frequencies()))
      throw InputError("the measured controller holds no frequencies; give its response on the data's frequency lines");
    c_in = c.num_inputs();
    c_out = c.num_outputs();
    for (std::size_t k = 0; k < c.response.size(); ++k) {
      const double w = c.omega_rad_s(static_cast<Index>(k));
      if (!std::isfinite(w) || !(w > 0.0) || c.response[k].rows() != c_out || c.response[k].cols() != c_in ||
          !c.response[k].allFinite())
        throw InputError(fmt::format("the measured controller's line {} ({} rad/s) is not a finite {}x{} response at a "
                                     "frequency > 0; give its response on the data's frequency lines",
                                     k + 1, w, c_out, c_in));
    }
  }
  if (base == nullptr) return;
  const Index ni = static_cast<Index>(base->input_names.size()), no = static_cast<Index>(base->output_names.size());
  if (c_in != no || c_out != ni)
    throw InputError(fmt::format("the controller has {} inputs and {} outputs; base '{}' needs {} (e = -q) and {} "
                                 "(u_c)",
                                 c_in, c_out, base->name, no, ni));
}

// s_ij(ω_k) >= kLocalLevelRatio × the largest s_ij within ±kLocalLevelDecades of ω_k
// (fit.h, "noise model"): the bottom of a narrow notch is not the size of its channel
// there.  ω in increasing order (the FRD formats' rule); otherwise left as it is.
void floor_at_local_level(const Eigen::VectorXd& omega, std::vector<Eigen::MatrixXd>& s) {
  const Index F = omega.size();
  if (F < 2 || static_cast<Index>(s.size()) != F) return;
  for (Index k = 1; k < F; ++k)
    if (!(omega(k) > omega(k - 1)) || !(omega(k - 1) > 0)) return;
  const double ratio = std::pow(10.0, kLocalLevelDecades);
  std::vector<Eigen::MatrixXd> out = s;
  Index lo = 0, hi = 0;
  for (Index k = 0; k < F; ++k) {
    while (omega(lo) * ratio < omega(k)) ++lo;
    while (hi + 1 < F && omega(hi + 1) <= omega(k) * ratio) ++hi;
    Eigen::MatrixXd local = s[static_cast<std::size_t>(lo)];
    for (Index j = lo + 1; j <= hi; ++j) local = local.cwiseMax(s[static_cast<std::size_t>(j)]);
    out[static_cast<std::size_t>(k)] = s[static_cast<std::size_t>(k)].cwiseMax(kLocalLevelRatio * local);
  }
  s = std::move(out);
}

// Per frequency: s_ij floored, σ per real part (header cases), the case's name.
struct NoiseTable {
  std::vector<RMat> scale, sigma;
  bool known = false;
  std::string source;
};

NoiseTable noise_table(const FrequencyResponse& f, const NoiseOptions& noise, double scale_floor,
                       const std::string& label) {
  NoiseTable t;
  const Index F = f.num_frequencies();
  std::vector<Eigen::MatrixXd> scales = response_scales(f.response, scale_floor);
  floor_at_local_level(f.omega_rad_s, scales);
  const bool var = !f.variance.empty();
  const bool coh = !f.coherence.empty();
  const double n_d = f.averages > 0 ? f.averages : noise.averages;
  if (var) {
    t.known = true;
    t.source = "variance";
  } else if (coh && n_d > 0) {
    t.known = true;
    t.source = fmt::format("coherence ({:g} averages{})", n_d, f.averages > 0 ? "" : ", given");
  } else if (noise.noise_level > 0) {
    t.known = true;
    t.source = fmt::format("noise level {:g} %", 100.0 * noise.noise_level);
  } else {
    t.known = false;
    t.source = coh ? "unknown (coherence without the number of averages)" : "unknown";
  }
  if (var && static_cast<Index>(f.variance.size()) != F)
    throw InputError(fmt::format("{}: {} variance matrices for {} frequencies", label, f.variance.size(), F));
  if (coh && static_cast<Index>(f.coherence.size()) != F)
    throw InputError(fmt::format("{}: {} coherence matrices for {} frequencies", label, f.coherence.size(), F));
  for (Index k = 0; k < F; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    const Eigen::MatrixXcd& h = f.response[kk];
    RMat s = scales[kk];
    RMat sg(h.rows(), h.cols());
    for (Index i = 0; i < h.rows(); ++i)
      for (Index j = 0; j < h.cols(); ++j) {
        double sigma;
        if (var) {
          // a variance beyond kNoInformationVariance stands for "no information" (the
          // FRD format holds finite numbers only; lpvid frf writes 1e300 there)
          constexpr double kNoInformationVariance = 1e250;
          const double v = f.variance[kk](i, j);
          sigma = v >= kNoInformationVariance ? kInf : std::sqrt(std::max(v, 0.0) / 2.0);
        } else if (coh && n_d > 0) {
          const double g2 = std::clamp(f.coherence[kk](i, j), 0.0, 1.0);
          sigma = g2 > 0 ? std::abs(h(i, j)) * std::sqrt((1.0 - g2) / (2.0 * n_d * g2)) : kInf;
        } else if (noise.noise_level > 0) {
          sigma = noise.noise_level * s(i, j) / std::sqrt(2.0);
        } else if (coh) {
          // relative weights from the coherence (n_d unknown: taken as 1 for the weights only)
          const double g2 = std::clamp(f.coherence[kk](i, j), 0.0, 1.0);
          sigma = g2 > 0 ? std::abs(h(i, j)) * std::sqrt((1.0 - g2) / (2.0 * g2)) : kInf;
        } else {
          sigma = s(i, j) / std::sqrt(2.0);
        }
        // Measured noise (variance, coherence): an entry is never measured against
        // less than kNoiseScaleRatio × its own noise rms √2σ.  Below that its relative
        // error measures the noise (the F-16's acc3 at 5.66 Hz, |H| at twice its noise;
        // fit.h, "noise model", with the local-level floor that does most of the work).
        if ((var || (coh && n_d > 0)) && std::isfinite(sigma))
          s(i, j) = std::max(s(i, j), kNoiseScaleRatio * std::sqrt(2.0) * sigma);
        sg(i, j) = std::max(sigma, noise.sigma_floor * s(i, j));
      }
    t.scale.push_back(std::move(s));
    t.sigma.push_back(std::move(sg));
  }
  return t;
}

bool in_band(double w, const FitOptions& o) { return w >= o.band_min_rad_s && w <= o.band_max_rad_s; }

Prepared prepare(const FitDataset& ds, const PhysicalModel& model, const FitOptions& o, bool* noise_known,
                 std::string* noise_source) {
  const FrequencyResponse& f = ds.response;
  const BaseInfo& base = model.base_info();
  if (f.num_frequencies() == 0 || f.response.size() != static_cast<std::size_t>(f.num_frequencies()))
    throw InputError(fmt::format("{}: no frequencies (or as many responses as frequencies are missing); give FRD data",
                                 ds.label));
  const auto [rows, cols] = target_shape(base, o.target);
  if (f.num_outputs() != rows || f.num_inputs() != cols)
    throw InputError(fmt::format("{}: the response is {}×{}; the {} target of base '{}' is {}×{}", ds.label,
                                 f.num_outputs(), f.num_inputs(), target_name(o.target), base.name, rows, cols));
  check_schedule(model, ds.beam_position_m);
  const Index F = f.num_frequencies();
  for (Index k = 0; k < F; ++k) {
    const double w = f.omega_rad_s(k);
    if (!std::isfinite(w) || !(w > 0.0))
      throw InputError(fmt::format("{}: frequency {} rad/s; frequencies must be finite and > 0", ds.label, w));
    if (!f.response[static_cast<std::size_t>(k)].allFinite())
      throw InputError(fmt::format("{}: a response value at {} rad/s is not finite", ds.label, w));
  }
  const NoiseTable nt = noise_table(f, o.noise, o.scale_floor, ds.label);
  if (noise_known) *noise_known = nt.known;
  if (noise_source) *noise_source = nt.source;
  Prepared d;
  d.sched = ds.beam_position_m;
  for (Index k = 0; k < F; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    if (!f.flagged.empty() && f.flagged[kk]) continue;
    if (!in_band(f.omega_rad_s(k), o)) continue;
    RMat inv_scale = nt.scale[kk].cwiseInverse(), weight(rows, cols);
    for (Index i = 0; i < rows; ++i)
      for (Index j = 0; j < cols; ++j) weight(i, j) = std::isinf(nt.sigma[kk](i, j)) ? 0.0 : 1.0 / nt.sigma[kk](i, j);
    d.omega.push_back(f.omega_rad_s(k));
    d.data.emplace_back(f.response[kk]);
    d.inv_scale.push_back(inv_scale);
    d.weight.push_back(weight);
    d.sigma.push_back(nt.sigma[kk]);
  }
  if (d.omega.empty())
    throw InputError(fmt::format("{}: no frequency in the band [{:g}, {:g}] rad/s (after flagged ones); widen the "
                                 "band or check the data's frequencies",
                                 ds.label, o.band_min_rad_s, o.band_max_rad_s));
  if (o.target != FitTarget::kPlant) {
    if (o.controller) {
      d.ctrl = controller_at(*o.controller, d.omega);
    } else {
      check_controller_lines(*o.measured_controller, f.omega_rad_s, "the measured controller", ds.label);
      for (Index k = 0; k < F; ++k) {
        const auto kk = static_cast<std::size_t>(k);
        if ((f.flagged.empty() || !f.flagged[kk]) && in_band(f.omega_rad_s(k), o))
          d.ctrl.emplace_back(o.measured_controller->response[kk]);
      }
    }
  }
  return d;
}

Prepared subsample(const Prepared& d, int count) {
  const std::size_t F = d.omega.size();
  if (static_cast<std::size_t>(count) >= F) return d;
  Prepared s;
  s.sched = d.sched;
  // Evenly spaced indices over the (log-spaced, typically) grid.
  for (int i = 0; i < count; ++i) {
    const auto k = static_cast<std::size_t>(std::llround(static_cast<double>(i) * static_cast<double>(F - 1) /
                                                         static_cast<double>(count - 1)));
    s.omega.push_back(d.omega[k]);
    s.data.push_back(d.data[k]);
    s.weight.push_back(d.weight[k]);
    s.inv_scale.push_back(d.inv_scale[k]);
    s.sigma.push_back(d.sigma[k]);
    if (!d.ctrl.empty()) s.ctrl.push_back(d.ctrl[k]);
  }
  return s;
}

std::string format_combination(const Eigen::VectorXd& v, const std::vector<std::string>& names) {
  std::string out;
  for (Index q = 0; q < v.size(); ++q) {
    // Components below 0.2 contribute < 4 % of the direction's squared length.
    if (std::abs(v(q)) < 0.2) continue;
    out += fmt::format("{}{:.2f}·{}", out.empty() ? (v(q) < 0 ? "-" : "") : (v(q) < 0 ? " - " : " + "), std::abs(v(q)),
                       names[static_cast<std::size_t>(q)]);
  }
  return out;
}

// Channel names: the data's (first set) when complete, else the base's.
void channel_names(const std::vector<FitDataset>& data, const BaseInfo& b, FitTarget t, std::vector<std::string>& outs,
                   std::vector<std::string>& ins) {
  const auto [rows, cols] = target_shape(b, t);
  const FrequencyResponse& f = data.front().response;
  outs = static_cast<Index>(f.output_names.size()) == rows ? f.output_names : std::vector<std::string>{};
  ins = static_cast<Index>(f.input_names.size()) == cols ? f.input_names : std::vector<std::string>{};
  if (outs.empty()) {
    if (t == FitTarget::kInputSensitivity)
      for (const auto& n : b.input_names) outs.push_back("u_" + n);
    else
      outs = b.output_names;
  }
  if (ins.empty()) {
    if (t == FitTarget::kPlant)
      ins = b.input_names;
    else
      for (const auto& n : b.input_names) ins.push_back("v_" + n);
  }
}

// Per-channel error and noise floor over the sets at the engine's current values.
void score_channels(Engine& engine, const std::vector<Prepared>& sets, bool noise_known,
                    std::vector<ChannelFit>& channels, double& error, double& floor) {
  const Index rows = sets.front().data.front().rows(), cols = sets.front().data.front().cols();
  channels.clear();
  for (Index i = 0; i < rows; ++i)
    for (Index j = 0; j < cols; ++j) channels.push_back(ChannelFit{i, j, 0.0, 0.0, {}});
  std::vector<double> sum(static_cast<std::size_t>(rows * cols), 0.0), nsum(sum);
  Index count = 0;
  for (const Prepared& d : sets) {
    std::vector<CMat> T;
    engine.evaluate(d, T, nullptr);
    for (Index c = 0; c < rows * cols; ++c) {
      const Index i = c / cols, j = c % cols;
      double s = 0.0, ns = 0.0;
      for (std::size_t k = 0; k < d.omega.size(); ++k) {
        s += std::norm((T[k](i, j) - d.data[k](i, j)) * d.inv_scale[k](i, j));
        const double r = d.sigma[k](i, j) * d.inv_scale[k](i, j);
        ns += std::isfinite(r) ? 2.0 * r * r : 0.0;
      }
      sum[static_cast<std::size_t>(c)] += s;
      nsum[static_cast<std::size_t>(c)] += ns;
      channels[static_cast<std::size_t>(c)].per_dataset.push_back(
          std::sqrt(s / static_cast<double>(std::max<std::size_t>(d.omega.size(), 1))));
    }
    count += static_cast<Index>(d.omega.size());
  }
  double e2 = 0.0, f2 = 0.0;
  for (Index c = 0; c < rows * cols; ++c) {
    auto& ch = channels[static_cast<std::size_t>(c)];
    ch.relative_rms_error = std::sqrt(sum[static_cast<std::size_t>(c)] / static_cast<double>(std::max<Index>(count, 1)));
    ch.noise_floor = noise_known ? std::sqrt(nsum[static_cast<std::size_t>(c)] / static_cast<double>(std::max<Index>(count, 1)))
                                 : kNaN;
    e2 += ch.relative_rms_error * ch.relative_rms_error;
    f2 += noise_known ? ch.noise_floor * ch.noise_floor : 0.0;
  }
  error = std::sqrt(e2 / static_cast<double>(rows * cols));
  floor = noise_known ? std::sqrt(f2 / static_cast<double>(rows * cols)) : kNaN;
}

struct PreparedAll {
  std::vector<Prepared> sets;
  bool noise_known = true;
  std::string noise_source;
};

PreparedAll prepare_all(const PhysicalModel& model, const std::vector<FitDataset>& data, const FitOptions& options) {
  if (data.empty()) throw InputError("no data to fit; give at least one response with its scheduling value");
  PreparedAll all;
  for (const auto& ds : data) {
    bool known = false;
    std::string source;
    all.sets.push_back(prepare(ds, model, options, &known, &source));
    all.noise_known = all.noise_known && known;
    if (all.noise_source.empty())
      all.noise_source = source;
    else if (all.noise_source != source)
      all.noise_source += "; " + source;
  }
  return all;
}

}  // namespace

std::string target_name(FitTarget target) {
  switch (target) {
    case FitTarget::kPlant:
      return "plant";
    case FitTarget::kClosedLoopOutput:
      return "G";
    case FitTarget::kInputSensitivity:
      return "S";
  }
  return "plant";
}

FitTarget parse_target(const std::string& text) {
  if (text == "plant" || text == "P") return FitTarget::kPlant;
  if (text == "G") return FitTarget::kClosedLoopOutput;
  if (text == "S") return FitTarget::kInputSensitivity;
  throw InputError(fmt::format("target '{}': give plant (P data), G (closed loop v -> q) or S (input sensitivity "
                               "v -> u)",
                               text));
}

void NoiseOptions::validate() const {
  if (!std::isfinite(averages) || averages < 0 || (averages > 0 && averages < 1))
    throw InputError(fmt::format("averages {}: give the independent averages behind the coherence, a number >= 1 "
                                 "(or 0 to take it from the data)",
                                 averages));
  if (!std::isfinite(noise_level) || noise_level < 0 || noise_level >= 1)
    throw InputError(fmt::format("noise level {}: give the relative rms error of the measurement, in [0, 1) (e.g. "
                                 "0.01 for 1 %)",
                                 noise_level));
  if (!std::isfinite(sigma_floor) || sigma_floor < 0 || sigma_floor >= 1)
    throw InputError(fmt::format("sigma floor {}: must be in [0, 1)", sigma_floor));
}

void FitOptions::validate() const {
  auto bad = [](const char* name, double v, const char* rule) {
    throw InputError(fmt::format("fit option {} = {}: {}", name, v, rule));
  };
  if (!std::isfinite(sample_period_s) || sample_period_s < 0) bad("sample_period_s", sample_period_s, "must be >= 0");
  if (!(band_min_rad_s >= 0) || !(band_max_rad_s > band_min_rad_s) || std::isnan(band_max_rad_s))
    throw InputError(fmt::format("frequency band [{}, {}] rad/s: give 0 <= low < high (e.g. --band-min 1 "
                                 "--band-max 400)",
                                 band_min_rad_s, band_max_rad_s));
  noise.validate();
  if (global_starts < 1) bad("global_starts", global_starts, "must be >= 1");
  if (!(global_search_factor > 1.0) || !std::isfinite(global_search_factor))
    bad("global_search_factor", global_search_factor, "must be finite and > 1");
  if (global_subsample < 2) bad("global_subsample", global_subsample, "must be >= 2");
  if (global_max_evaluations < 10) bad("global_max_evaluations", global_max_evaluations, "must be >= 10");
  if (restarts < 0) bad("restarts", restarts, "must be >= 0");
  if (max_iterations < 1) bad("max_iterations", max_iterations, "must be >= 1");
  if (!(function_tolerance > 0.0) || !(function_tolerance < 1.0))
    bad("function_tolerance", function_tolerance, "must be in (0, 1)");
  if (!(scale_floor > 0.0) || !(scale_floor < 1.0)) bad("scale_floor", scale_floor, "must be in (0, 1)");
  if (!(correlation_flag > 0.0) || !(correlation_flag <= 1.0))
    bad("correlation_flag", correlation_flag, "must be in (0, 1]");
  if (!(singular_value_flag > 0.0) || !(singular_value_flag < 1.0))
    bad("singular_value_flag", singular_value_flag, "must be in (0, 1)");
  check_controller(*this, nullptr);
}

std::vector<Eigen::MatrixXd> data_sigma(const FrequencyResponse& data, const NoiseOptions& noise,
                                        std::string* source, bool* known, std::vector<Eigen::MatrixXd>* scales) {
  noise.validate();
  const NoiseTable t = noise_table(data, noise, 1e-6, "data");
  if (source) *source = t.source;
  if (known) *known = t.known;
  if (scales) scales->assign(t.scale.begin(), t.scale.end());
  std::vector<Eigen::MatrixXd> out;
  for (const RMat& s : t.sigma) out.emplace_back(s);
  return out;
}

ModelScore score_model(const PhysicalModel& model, const std::vector<FitDataset>& data, const FitOptions& options) {
  options.validate();
  model.validate();
  check_controller(options, &model.base_info());
  const PreparedAll all = prepare_all(model, data, options);
  Engine engine(model, options);
  ModelScore s;
  s.noise_known = all.noise_known;
  score_channels(engine, all.sets, all.noise_known, s.channels, s.error, s.noise_floor);
  std::vector<CMat> T;
  for (const Prepared& d : all.sets) {
    if (!engine.evaluate(d, T, nullptr))
      throw InputError("the model cannot be evaluated at a data set's scheduling value (mass matrix not positive "
                       "definite); check the model");
    for (std::size_t k = 0; k < d.omega.size(); ++k)
      for (Index i = 0; i < d.data[k].rows(); ++i)
        for (Index j = 0; j < d.data[k].cols(); ++j) {
          s.cost += std::norm((T[k](i, j) - d.data[k](i, j)) * d.weight[k](i, j));
          s.residual_count += 2;
        }
  }
  return s;
}

namespace {

// One round: global start, then Levenberg–Marquardt (fit_physical_model repeats it).
// Levenberg–Marquardt's iterations as progress reports (FitOptions::progress); not
// iteration 0, the start's evaluation.
class IterationProgress final : public ceres::IterationCallback {
 public:
  IterationProgress(Progress* progress, const std::string& task) : progress_(progress), task_(task) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (s.iteration < 1) return ceres::SOLVER_CONTINUE;
    // Ceres' cost is half the sum of squares; the fit's (FitResult::cost_final) is the sum.
    const std::string detail = fmt::format("cost {:.6g}", 2.0 * s.cost);
    progress_->report({task_, "Levenberg-Marquardt iteration", s.iteration, 0, detail, -1.0});
    return ceres::SOLVER_CONTINUE;
  }

 private:
  Progress* progress_;
  const std::string& task_;
};

// One round: global start + Levenberg–Marquardt; `task` names it in progress reports.
FitResult fit_round(const PhysicalModel& start, const std::vector<FitDataset>& data, const FitOptions& options,
                    const std::string& task) {
  const auto t0 = std::chrono::steady_clock::now();
  options.validate();
  start.validate();
  const BaseInfo& base = start.base_info();
  check_controller(options, &base);
  Engine engine(start, options);
  const Index p = engine.num_free();
  if (p == 0) throw InputError("the model has no free parameter; free the ones to estimate (lpvid model set --model MODEL.json --free NAME)");
  constexpr Index kMaxFree = 48;  // the largest Jet size instantiated (Engine::evaluate)
  if (p > kMaxFree)
    throw InputError(fmt::format("the model has {} free parameters; at most {} can be fitted at once — fix some", p,
                                 kMaxFree));
  const PreparedAll all = prepare_all(start, data, options);
  const std::vector<Prepared>& sets = all.sets;
  const Coordinates coords = make_coordinates(start, engine.free());
  const std::vector<PriorRow> priors = prior_rows(start, engine.free());
  if (!priors.empty() && !all.noise_known)
    throw InputError(fmt::format("parameter '{}' has a prior, which weighs against the data's noise, and the noise of "
                                 "the data is unknown; give the data's variance, or coherence with the number of "
                                 "averages, or a noise level",
                                 start.parameters[static_cast<std::size_t>(engine.free()[static_cast<std::size_t>(
                                                      priors.front().q)])]
                                     .name));
  const Index data_residuals = count_residuals(sets);
  Problem full{engine, coords, sets, data_residuals + static_cast<Index>(priors.size()), priors};
  if (data_residuals <= p)
    throw InputError(fmt::format("{} residuals for {} free parameters: give more (unflagged) frequencies", data_residuals,
                                 p));

  std::vector<double> z(static_cast<std::size_t>(p));
  for (Index q = 0; q < p; ++q)
    z[static_cast<std::size_t>(q)] =
        coords.to_z(q, start.parameters[static_cast<std::size_t>(engine.free()[static_cast<std::size_t>(q)])].value);
  FitResult result;
  result.noise_known = all.noise_known;
  result.noise_source = all.noise_source;
  result.cost_start = full.cost(z.data());
  // Extra starts: the start with the given values (checked before anything runs).
  std::vector<std::vector<double>> extra;
  for (const auto& overrides : options.extra_starts) {
    std::vector<double> x = z;
    for (const auto& [name, value] : overrides) {
      const Index i = start.index_of(name);
      if (i < 0) throw InputError(fmt::format("extra start: the model has no parameter '{}'", name));
      const auto it = std::find(engine.free().begin(), engine.free().end(), i);
      if (it == engine.free().end()) continue;  // a fixed parameter keeps its value
      const Index q = it - engine.free().begin();
      const auto& par = start.parameters[static_cast<std::size_t>(i)];
      x[static_cast<std::size_t>(q)] = coords.to_z(q, std::clamp(value, par.lower, par.upper));
    }
    extra.push_back(std::move(x));
  }
  // A start whose free parameters sit on their bounds (a previous fit that could not
  // follow the data, e.g. before the missing effect was added) is also started from
  // the library defaults of those parameters: from the distorted values the
  // parameters often stay in the wrong basin (measured on the stage: fit1's
  // inertia_yy = 1000 at its bound, `model add gap_dependence`, refit: 16.5 % from
  // the start, 2.95 % from the defaults).
  {
    std::vector<double> x = z;
    bool any = false;
    for (Index q = 0; q < p; ++q) {
      const auto& par = start.parameters[static_cast<std::size_t>(engine.free()[static_cast<std::size_t>(q)])];
      const double span = par.upper - par.lower;
      if (!(span > 0) || (par.value - par.lower > 1e-9 * span && par.upper - par.value > 1e-9 * span)) continue;
      std::optional<double> fallback;
      for (const auto& b : base.parameters)
        if (b.name == par.name) fallback = b.value;
      for (const std::string& e : start.effects)
        for (const auto& ep : start.effect_info(e)->parameters)
          if (ep.name == par.name) fallback = ep.value;
      if (fallback && *fallback > par.lower && *fallback < par.upper) {
        x[static_cast<std::size_t>(q)] = coords.to_z(q, *fallback);
        any = true;
      }
    }
    if (any) extra.push_back(std::move(x));
  }
  if (!std::isfinite(result.cost_start)) {
    // the start may be unusable while an extra start is fine
    double best = kInf;
    for (const auto& x : extra) {
      const double c = full.cost(x.data());
      if (c < best) {
        best = c;
        z = x;
      }
    }
    if (!std::isfinite(best))
      throw NumericalError("the start model cannot be evaluated at every scheduling value (mass matrix not positive "
                           "definite or a non-finite response); change the start values");
    result.cost_start = best;
  }

  // (1) Global start on a subsample, over the searched coordinates.
  result.cost_global = result.cost_start;
  std::vector<Index> searched;
  for (Index q = 0; q < p; ++q) {
    const std::string& name = start.parameters[static_cast<std::size_t>(engine.free()[static_cast<std::size_t>(q)])].name;
    if (options.global_parameters.empty() ||
        std::find(options.global_parameters.begin(), options.global_parameters.end(), name) !=
            options.global_parameters.end())
      searched.push_back(q);
  }
  if (options.global_start && !searched.empty()) {
    std::vector<Prepared> sub;
    for (const auto& d : sets) sub.push_back(subsample(d, options.global_subsample));
    Problem coarse{engine, coords, sub, count_residuals(sub) + static_cast<Index>(priors.size()), priors};
    std::vector<double> lo(coords.lower), hi(coords.upper);
    for (Index q = 0; q < p; ++q) {
      const auto s = static_cast<std::size_t>(q);
      const double half = coords.log[s] ? std::log(options.global_search_factor)
                                        : (coords.upper[s] - coords.lower[s]) / (2.0 * options.global_search_factor);
      lo[s] = std::max(coords.lower[s], z[s] - half);
      hi[s] = std::min(coords.upper[s], z[s] + half);
    }
    std::mt19937 rng(options.seed);
    std::vector<std::vector<double>> starts{z};
    for (const auto& x : extra) starts.push_back(x);
    for (int k = 1; k < options.global_starts; ++k) {
      std::vector<double> x = z;
      for (Index q : searched) {
        const auto s = static_cast<std::size_t>(q);
        x[s] = std::uniform_real_distribution<double>(lo[s], hi[s])(rng);
      }
      starts.push_back(std::move(x));
    }
    // BOBYQA over the searched coordinates; the others stay where the start puts them.
    struct Sub {
      Problem* problem;
      std::vector<double> full;
      const std::vector<Index>* searched;
    };
    auto sub_objective = [](unsigned n, const double* x, double* grad, void* data) -> double {
      (void)grad;
      Sub* sb = static_cast<Sub*>(data);
      for (unsigned i = 0; i < n; ++i) sb->full[static_cast<std::size_t>((*sb->searched)[i])] = x[i];
      return sb->problem->cost(sb->full.data());
    };
    std::vector<double> best = z;
    double best_cost = coarse.cost(z.data());
    std::vector<double> slo, shi;
    for (Index q : searched) {
      slo.push_back(coords.lower[static_cast<std::size_t>(q)]);
      shi.push_back(coords.upper[static_cast<std::size_t>(q)]);
    }
    for (std::size_t k = 0; k < starts.size(); ++k) {
      const std::vector<double>& x0 = starts[k];
      if (options.progress != nullptr)
        options.progress->report(
            {task, "global start", static_cast<Index>(k + 1), static_cast<Index>(starts.size()), "", -1.0});
      Sub sb{&coarse, x0, &searched};
      std::vector<double> x;
      for (Index q : searched) x.push_back(x0[static_cast<std::size_t>(q)]);
      nlopt::opt opt(nlopt::LN_BOBYQA, static_cast<unsigned>(searched.size()));
      opt.set_lower_bounds(slo);
      opt.set_upper_bounds(shi);
      opt.set_min_objective(sub_objective, &sb);
      opt.set_maxeval(options.global_max_evaluations);
      // The global stage only finds a basin for Levenberg–Marquardt: steps of 1e-4
      // (relative, log coordinates for most parameters) and cost changes of 1e-6
      // are far finer than a basin (measured: the same end points as 1e-6 with
      // 3–5x fewer evaluations, tests/idlib/diagnose).
      opt.set_xtol_rel(1e-4);
      opt.set_ftol_rel(1e-6);
      // Initial trust region: a quarter of the search box per coordinate.
      std::vector<double> step;
      for (Index q : searched) {
        const auto s = static_cast<std::size_t>(q);
        step.push_back(std::max(0.25 * (hi[s] - lo[s]), 1e-12));
      }
      opt.set_initial_step(step);
      double f = kInf;
      try {
        opt.optimize(x, f);
      } catch (const std::exception&) {
        f = sub_objective(static_cast<unsigned>(x.size()), x.data(), nullptr, &sb);  // keep the point reached
      }
      for (std::size_t i = 0; i < searched.size(); ++i) sb.full[static_cast<std::size_t>(searched[i])] = x[i];
      if (f < best_cost) {
        best_cost = f;
        best = sb.full;
      }
    }
    const double c = full.cost(best.data());
    if (c < result.cost_start) z = best;
    result.cost_global = std::min(c, result.cost_start);
  } else if (!extra.empty()) {
    for (const auto& x : extra) {
      const double c = full.cost(x.data());
      if (c < result.cost_global) {
        result.cost_global = c;
        z = x;
      }
    }
  }

  // (2) Levenberg–Marquardt on all data.
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem cp(problem_options);
  cp.AddResidualBlock(new CeresCost(full), nullptr, z.data());
  for (Index q = 0; q < p; ++q) {
    cp.SetParameterLowerBound(z.data(), static_cast<int>(q), coords.lower[static_cast<std::size_t>(q)]);
    cp.SetParameterUpperBound(z.data(), static_cast<int>(q), coords.upper[static_cast<std::size_t>(q)]);
  }
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = 1e-14;
  so.parameter_tolerance = 1e-12;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.num_threads = 1;
  // A step that leaves the bounds is projected and searched along with an Armijo
  // line search whose every trial evaluates the Jacobian (Ceres' bounded trust
  // region); a parameter pressing on its bound (an effect used as a patch) made it
  // a third of all fitting time.  A few halvings suffice: the next trust-region
  // step corrects a short one.
  so.max_num_line_search_step_size_iterations = 4;
  std::optional<IterationProgress> iteration_progress;
  if (options.progress != nullptr) {
    iteration_progress.emplace(options.progress, task);
    so.callbacks.push_back(&*iteration_progress);
  }
  ceres::Solver::Summary summary;
  ceres::Solve(so, &cp, &summary);
  if (!summary.IsSolutionUsable())
    throw NumericalError(fmt::format("the least-squares solver found no usable point: {}", summary.message));
  result.iterations = static_cast<int>(summary.iterations.size());
  result.report.termination = fmt::format("{} after {} iterations: {}",
                                          summary.termination_type == ceres::CONVERGENCE ? "converged" : "stopped",
                                          result.iterations, summary.message);
  if (summary.termination_type != ceres::CONVERGENCE)
    result.report.warnings.push_back("the solver stopped before convergence (" + summary.message +
                                     "); raise max_iterations or check the start");

  // Residuals and Jacobian at the estimate, in natural units.
  const Index N = full.residuals;
  std::vector<double> r(static_cast<std::size_t>(N)), jz(static_cast<std::size_t>(N * p));
  if (!full.residual(z.data(), r.data(), jz.data()))
    throw NumericalError("the model cannot be evaluated at the estimate; check the bounds of the centre-of-mass terms");
  Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> Jz(jz.data(), N, p);
  Eigen::MatrixXd J = Jz;
  for (Index q = 0; q < p; ++q)
    if (coords.log[static_cast<std::size_t>(q)]) J.col(q) /= std::exp(z[static_cast<std::size_t>(q)]);
  // The cost is the data's and the priors'; σ², AIC and BIC are the data's alone
  // (the same with and without priors for the same fit of the data).
  double ssr = 0.0, cost = 0.0;
  for (Index i = 0; i < N; ++i) (i < data_residuals ? ssr : cost) += r[static_cast<std::size_t>(i)] * r[static_cast<std::size_t>(i)];
  result.cost_final = ssr + cost;
  result.prior_cost = cost;
  result.residual_count = data_residuals;
  for (const auto& d : sets) result.frequencies_used += static_cast<Index>(d.omega.size());
  result.sigma2 = ssr / static_cast<double>(data_residuals - p);
  const double n_d = static_cast<double>(data_residuals);
  const double log_term = n_d * std::log(std::max(ssr, std::numeric_limits<double>::min()) / n_d);
  result.aic = log_term + 2.0 * static_cast<double>(p);
  result.bic = log_term + static_cast<double>(p) * std::log(n_d);

  // Covariance σ² (JᵀJ)⁺ via the SVD of J (relative cut 1e-12 of the largest singular value).
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(J, Eigen::ComputeThinV);
  const Eigen::VectorXd sv = svd.singularValues();
  Eigen::VectorXd inv2 = Eigen::VectorXd::Zero(p);
  for (Index q = 0; q < p; ++q)
    if (sv(q) > 1e-12 * sv(0)) inv2(q) = 1.0 / (sv(q) * sv(q));
  // With priors (the noise is then known, the residuals in its units) the covariance
  // is the posterior's, (JᵀJ)⁺ over the data's and the priors' rows, inflated by σ²
  // only when the data scatter more than their noise says (σ² > 1): scaling the
  // priors' information by the data's σ² would make a ±1 % prior ±0.00001 % on
  // noise-free data.  Without priors, σ²(JᵀJ)⁺ as always.
  const double scale = priors.empty() ? result.sigma2 : std::max(result.sigma2, 1.0);
  result.covariance = scale * svd.matrixV() * inv2.asDiagonal() * svd.matrixV().transpose();
  result.correlation = Eigen::MatrixXd::Zero(p, p);
  for (Index a = 0; a < p; ++a)
    for (Index b = 0; b < p; ++b) {
      const double den = std::sqrt(result.covariance(a, a) * result.covariance(b, b));
      result.correlation(a, b) = den > 0.0 ? result.covariance(a, b) / den : (a == b ? 1.0 : 0.0);
    }

  // Estimates and the fitted model.
  result.model = start;
  std::vector<std::string> names;
  for (Index q = 0; q < p; ++q) {
    const auto s = static_cast<std::size_t>(q);
    auto& par = result.model.parameters[static_cast<std::size_t>(engine.free()[s])];
    ParameterEstimate e;
    e.name = par.name;
    e.unit = par.unit;
    e.start = par.value;
    e.lower = par.lower;
    e.upper = par.upper;
    e.estimate = coords.to_theta(q, z[s]);
    e.estimate = std::clamp(e.estimate, par.lower, par.upper);  // exp/log round trip at a bound
    par.value = e.estimate;
    e.std_error = std::sqrt(std::max(result.covariance(q, q), 0.0));
    // At a bound: within 1e-6 of the parameter's span in its own coordinates.
    constexpr double kAtBound = 1e-6;
    const double span = std::max(coords.upper[s] - coords.lower[s], 1e-300);
    const bool at_lower = z[s] - coords.lower[s] <= kAtBound * span;
    const bool at_upper = coords.upper[s] - z[s] <= kAtBound * span;
    e.at_bound = at_lower || at_upper;
    if (e.at_bound)
      e.flags.push_back(fmt::format("at {} bound {:g}: the data want it beyond", at_lower ? "lower" : "upper",
                                    at_lower ? par.lower : par.upper));
    if (par.has_prior()) {
      e.prior_mean = par.prior_mean;
      e.prior_sigma = par.prior_sigma;
      const double pull = (e.estimate - par.prior_mean) / par.prior_sigma;
      if (std::abs(pull) > kPriorPullFlag) {
        ++result.priors_contradicted;
        e.flags.push_back(fmt::format("{:+.1f} sigma from its prior {:g} ± {:g}", pull, par.prior_mean, par.prior_sigma));
        result.report.warnings.push_back(
            fmt::format("the data pull {} to {:.4g}, {:.1f} standard deviations from its prior {:g} ± {:g}: the design "
                        "value or its uncertainty is wrong, or the model lacks an effect that this parameter is "
                        "standing in for",
                        par.name, e.estimate, std::abs(pull), par.prior_mean, par.prior_sigma));
      }
    }
    names.push_back(par.name);
    result.parameters.push_back(e);
  }

  // Identifiability: scaled, column-normalised Jacobian.
  Eigen::MatrixXd Js = J;
  for (Index q = 0; q < p; ++q) {
    const auto& par = result.model.parameters[static_cast<std::size_t>(engine.free()[static_cast<std::size_t>(q)])];
    const double scale = par.value != 0.0 ? std::abs(par.value) : 0.01 * (par.upper - par.lower);
    Js.col(q) *= scale;
    const double nrm = Js.col(q).norm();
    if (nrm > 0.0) Js.col(q) /= nrm;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> ssvd(Js, Eigen::ComputeThinV);
  result.singular_values = ssvd.singularValues() / std::max(ssvd.singularValues()(0), 1e-300);
  for (Index q = 0; q < p; ++q) {
    if (result.singular_values(q) >= options.singular_value_flag) continue;
    const std::string combo = format_combination(ssvd.matrixV().col(q), names);
    result.identifiability.push_back(
        fmt::format("the data cannot separate the direction {} (relative singular value {:.1e}): fix one of these "
                    "parameters or add data that moves it",
                    combo, result.singular_values(q)));
    for (Index a = 0; a < p; ++a)
      if (std::abs(ssvd.matrixV()(a, q)) >= 0.2)
        result.parameters[static_cast<std::size_t>(a)].flags.push_back("inseparable: " + combo);
  }
  for (Index a = 0; a < p; ++a)
    for (Index b = a + 1; b < p; ++b)
      if (std::abs(result.correlation(a, b)) > options.correlation_flag) {
        result.identifiability.push_back(fmt::format("{} and {} are correlated ({:+.3f}): the data hardly separate them",
                                                     names[static_cast<std::size_t>(a)],
                                                     names[static_cast<std::size_t>(b)], result.correlation(a, b)));
        result.parameters[static_cast<std::size_t>(a)].flags.push_back(
            fmt::format("corr {:+.3f} with {}", result.correlation(a, b), names[static_cast<std::size_t>(b)]));
        result.parameters[static_cast<std::size_t>(b)].flags.push_back(
            fmt::format("corr {:+.3f} with {}", result.correlation(a, b), names[static_cast<std::size_t>(a)]));
      }
  for (const ParameterEstimate& e : result.parameters)
    if (e.at_bound)
      result.report.warnings.push_back(fmt::format("{} ended on its {} bound: the model cannot follow the data there "
                                                   "within its physical range",
                                                   e.name,
                                                   std::abs(e.estimate - e.lower) <= std::abs(e.upper - e.estimate)
                                                       ? "lower"
                                                       : "upper"));

  // Per-channel figures at the estimate.
  full.set_z(z.data());
  score_channels(engine, sets, all.noise_known, result.channels, result.error, result.noise_floor);
  channel_names(data, base, options.target, result.output_names, result.input_names);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace

FitResult fit_physical_model(const PhysicalModel& start, const std::vector<FitDataset>& data,
                             const FitOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  auto task = [&](int round) {
    return options.restarts > 0 ? fmt::format("fit round {}", round) : std::string("fit");
  };
  FitResult r = fit_round(start, data, options, task(1));
  r.cost_first_round = r.cost_final;
  // A cost that falls by less than this fraction is the same minimum (Ceres'
  // function tolerance is 1e-12; LM from its own end point moves it by round-off).
  constexpr double kRestartGain = 1e-6;
  while (r.restarts < options.restarts) {
    FitResult again;
    try {
      again = fit_round(r.model, data, options, task(r.restarts + 2));
    } catch (const NumericalError&) {
      break;  // the rounds that ended at r stand
    }
    if (!(again.cost_final < r.cost_final * (1.0 - kRestartGain))) break;
    again.cost_start = r.cost_start;
    again.cost_global = r.cost_global;
    again.cost_first_round = r.cost_first_round;
    for (std::size_t k = 0; k < again.parameters.size() && k < r.parameters.size(); ++k)
      again.parameters[k].start = r.parameters[k].start;
    again.iterations += r.iterations;
    again.restarts = r.restarts + 1;
    r = std::move(again);
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

void check_controller_lines(const FrequencyResponse& controller, const Eigen::VectorXd& omega,
                            const std::string& controller_name, const std::string& data_name) {
  const Index nc = controller.num_frequencies(), nd = omega.size();
  Index k = 0;
  while (k < std::min(nc, nd) && same_line(controller.omega_rad_s(k), omega(k))) ++k;
  if (k == nc && k == nd) return;
  constexpr double kHz = 1.0 / (2.0 * std::numbers::pi);
  const std::string what = "; measure the controller at the data's frequency lines (or give it as a model)";
  if (k < std::min(nc, nd))
    throw InputError(fmt::format("{}: line {} is {:.10g} Hz but line {} of {} is {:.10g} Hz (relative difference "
                                 "{:.3g} > {:g}){}",
                                 controller_name, k + 1, controller.omega_rad_s(k) * kHz, k + 1, data_name,
                                 omega(k) * kHz, std::abs(controller.omega_rad_s(k) - omega(k)) / std::abs(omega(k)),
                                 kControllerLineRelTolerance, what));
  throw InputError(fmt::format("{}: {} lines but {} has {}; line {} ({:.10g} Hz) is in {} only{}", controller_name,
                               nc, data_name, nd, k + 1,
                               (nc > nd ? controller.omega_rad_s(k) : omega(k)) * kHz,
                               nc > nd ? controller_name : data_name, what));
}

std::vector<Eigen::MatrixXcd> controller_response_at(const FitOptions& options, const Eigen::VectorXd& omega_rad_s) {
  if (options.controller) return evaluate_response(*options.controller, omega_rad_s);
  if (!options.measured_controller)
    throw InputError("no controller given; give the controller (--controller C.json, or its measured response C.csv)");
  const FrequencyResponse& c = *options.measured_controller;
  // The lines in increasing order, to look each frequency up (FRD files need not be sorted).
  std::vector<Index> order(static_cast<std::size_t>(c.num_frequencies()));
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = static_cast<Index>(k);
  std::sort(order.begin(), order.end(), [&](Index a, Index b) { return c.omega_rad_s(a) < c.omega_rad_s(b); });
  std::vector<Eigen::MatrixXcd> out;
  for (Index k = 0; k < omega_rad_s.size(); ++k) {
    const double w = omega_rad_s(k);
    const auto it = std::lower_bound(order.begin(), order.end(), w,
                                     [&](Index a, double x) { return c.omega_rad_s(a) < x; });
    Index hit = -1;
    for (auto j = it == order.begin() ? it : it - 1; j != order.end() && j <= it; ++j)
      if (same_line(c.omega_rad_s(*j), w)) hit = *j;
    if (hit < 0)
      throw InputError(fmt::format("the measured controller has no line at {:.10g} Hz (relative {:g}); the response "
                                   "through a measured controller is known only at its lines: measure the controller "
                                   "at the data's frequency lines (or give it as a model)",
                                   w / (2.0 * std::numbers::pi), kControllerLineRelTolerance));
    out.push_back(c.response[static_cast<std::size_t>(hit)]);
  }
  return out;
}

FrequencyResponse target_response(const PhysicalModel& model, double beam_position_m,
                                  const Eigen::VectorXd& omega_rad_s, const FitOptions& options) {
  return response_band(model, Eigen::MatrixXd(), beam_position_m, omega_rad_s, options).response;
}

ResponseBand response_band(const PhysicalModel& model, const Eigen::MatrixXd& covariance, double beam_position_m,
                           const Eigen::VectorXd& omega_rad_s, const FitOptions& options) {
  options.validate();
  model.validate();
  const BaseInfo& base = model.base_info();
  check_controller(options, &base);
  check_schedule(model, beam_position_m);
  Engine engine(model, options);
  const Index p = engine.num_free();
  const bool bands = covariance.size() > 0;
  if (bands && (covariance.rows() != p || covariance.cols() != p))
    throw InputError(fmt::format("covariance is {}×{}; the model has {} free parameters", covariance.rows(),
                                 covariance.cols(), p));
  if (bands && p > 48) throw InputError("at most 48 free parameters");
  Prepared d;
  d.sched = beam_position_m;
  for (Index k = 0; k < omega_rad_s.size(); ++k) {
    if (!std::isfinite(omega_rad_s(k))) throw InputError("a frequency is not finite");
    d.omega.push_back(omega_rad_s(k));
  }
  if (options.target != FitTarget::kPlant)
    for (const Eigen::MatrixXcd& c : controller_response_at(options, omega_rad_s)) d.ctrl.emplace_back(c);
  std::vector<CMat> T;
  std::vector<std::vector<CMat>> dT;
  if (!engine.evaluate(d, T, bands && p > 0 ? &dT : nullptr))
    throw InputError(fmt::format("the mass matrix at {} {} is not positive definite; check the model", beam_position_m,
                                 base.schedule_unit));
  ResponseBand out;
  out.response.omega_rad_s = omega_rad_s;
  std::vector<FitDataset> none;
  const auto [rows, cols] = target_shape(base, options.target);
  if (options.target == FitTarget::kInputSensitivity)
    for (const auto& n : base.input_names) out.response.output_names.push_back("u_" + n);
  else
    out.response.output_names = base.output_names;
  if (options.target == FitTarget::kPlant)
    out.response.input_names = base.input_names;
  else
    for (const auto& n : base.input_names) out.response.input_names.push_back("v_" + n);
  for (std::size_t k = 0; k < T.size(); ++k) {
    out.response.response.emplace_back(T[k]);
    Eigen::MatrixXd sm = Eigen::MatrixXd::Zero(rows, cols), sp = Eigen::MatrixXd::Zero(rows, cols);
    if (bands && p > 0) {
      for (Index i = 0; i < rows; ++i)
        for (Index j = 0; j < cols; ++j) {
          const double mag = std::abs(T[k](i, j));
          if (mag == 0.0) continue;
          Eigen::VectorXd g(p), h(p);
          for (Index q = 0; q < p; ++q) {
            const Cx prod = std::conj(T[k](i, j)) * dT[k][static_cast<std::size_t>(q)](i, j);
            g(q) = prod.real() / mag;
            h(q) = prod.imag() / (mag * mag);
          }
          sm(i, j) = std::sqrt(std::max(g.dot(covariance * g), 0.0));
          sp(i, j) = std::sqrt(std::max(h.dot(covariance * h), 0.0));
        }
    }
    out.magnitude_sigma.push_back(sm);
    out.phase_sigma_rad.push_back(sp);
  }
  return out;
}

}  // namespace lpvid
