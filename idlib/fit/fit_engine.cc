// lpvid — the frequency-domain fit's engine: the target response (P, G or S) of a
// physical model at the data's frequencies and its derivatives by the free parameters.
#include <ceres/jet.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "idlib/fit/fit_detail.h"

namespace lpvid {

template <int N>
struct ScalarValue<ceres::Jet<double, N>> {
  static double of(const ceres::Jet<double, N>& x) { return x.a; }
};

namespace fit_detail {

std::pair<Index, Index> target_shape(const BaseInfo& b, FitTarget t) {
  const Index ni = static_cast<Index>(b.input_names.size()), no = static_cast<Index>(b.output_names.size());
  return t == FitTarget::kInputSensitivity ? std::pair<Index, Index>{ni, ni} : std::pair<Index, Index>{no, ni};
}

Engine::Engine(const PhysicalModel& model, const FitOptions& options)
    : layout_(model), options_(options), full_(model.values()), free_(model.free_indices()) {
  // which free parameters are delays of which input (continuous route)
  delay_of_.assign(free_.size(), {});
  for (Index j = 0; j < layout_.n_in; ++j)
    for (Index q : layout_.delays[static_cast<std::size_t>(j)])
      for (std::size_t f = 0; f < free_.size(); ++f)
        if (free_[f] == q) delay_of_[f].push_back(j);
}

bool Engine::evaluate(const Prepared& d, std::vector<CMat>& T, std::vector<std::vector<CMat>>* dT) const {
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

// The model's matrices at the current parameters and, for N > 0, the derivatives
// by the free parameters q0 .. q0 + N - 1 (forward-mode Jets of N lanes); b's
// values and the derivative arrays are set by the call with q0 = 0.  Only this
// part depends on N: the response at every frequency (respond) does not.
template <int N>
bool Engine::build(const Prepared& d, Built& b, const Index q0) const {
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

namespace {

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

struct Route {
  bool modal = false;
  bool schur = false;
  Eigen::VectorXcd mu;
  Eigen::MatrixXcd V, Vinv, Ch, Bhn, Bho;
  Eigen::MatrixXcd Tq;  // the Schur route's triangular factor (Ch, Bhn, Bho: C Q, Qᴴ B)
};

Route choose_route(const Engine::Built& b) {
  const Eigen::MatrixXd& A = b.A;
  Route r;
  r.modal = A.rows() > 0;
  if (!r.modal) return r;
  const Eigen::EigenSolver<Eigen::MatrixXd> es(A);
  r.modal = es.info() == Eigen::Success;
  if (r.modal) {
    r.V = es.eigenvectors();
    r.Vinv = r.V.partialPivLu().inverse();
    r.modal = r.Vinv.allFinite() && r.V.norm() * r.Vinv.norm() < kMaxModalCondition;
    if (r.modal) {
      r.mu = es.eigenvalues();
      r.Ch = b.C.cast<Cx>() * r.V;
      r.Bhn = r.Vinv * b.Bn.cast<Cx>();
      r.Bho = r.Vinv * b.Bo.cast<Cx>();
    }
  }
  if (!r.modal) {
    const Eigen::ComplexSchur<Eigen::MatrixXd> cs(A);
    r.schur = cs.info() == Eigen::Success && cs.matrixT().allFinite();
    if (r.schur) {
      r.V = cs.matrixU();
      r.Vinv = r.V.adjoint();
      r.Tq = cs.matrixT().triangularView<Eigen::Upper>();
      r.Ch = b.C.cast<Cx>() * r.V;
      r.Bhn = r.Vinv * b.Bn.cast<Cx>();
      r.Bho = r.Vinv * b.Bo.cast<Cx>();
    }
  }
  return r;
}

// Derivatives in the route's coordinates, stacked over the parameters (q-th block):
// dAv (n·p × n) = [V⁻¹ dA_q V], dBv (n·p × n_in) = [V⁻¹ dB_q], dCv (n_out·p × n) = [dC_q V],
// so that every frequency needs three GEMMs for all parameters at once.
// Only the parameters that move A or B (inner) enter the first products and only
// those that move C (outer) the last: output blocks (gains, cross-talk) touch C
// alone, so their rows would be zeros.  pos_inner/pos_outer: a free parameter's
// row block in the stacks (-1: not there).
struct Stacks {
  std::vector<Index> pos_inner, pos_outer;
  Index n_inner = 0, n_outer = 0;
  Eigen::MatrixXcd dAv, dBvn, dBvo, dCv;
};

Stacks stack_derivatives(const Engine::Built& b, const Index p, const bool any_old, const bool derivatives,
                         const Route& route) {
  Stacks st;
  st.pos_inner.assign(static_cast<std::size_t>(p), -1);
  st.pos_outer.assign(static_cast<std::size_t>(p), -1);
  if (derivatives)
    for (Index q = 0; q < p; ++q) {
      const auto s = static_cast<std::size_t>(q);
      const auto nonzero = [](const Eigen::MatrixXd& m) { return m.size() > 0 && m.cwiseAbs().maxCoeff() > 0.0; };
      if (nonzero(b.dA[s]) || nonzero(b.dBn[s]) || (any_old && nonzero(b.dBo[s]))) st.pos_inner[s] = st.n_inner++;
      if (nonzero(b.dC[s])) st.pos_outer[s] = st.n_outer++;
    }
  if (!derivatives || p == 0) return st;
  // Stacked derivatives: in modal coordinates (V⁻¹ dA_q V, V⁻¹ dB_q, dC_q V) on the
  // modal route, in Schur coordinates (Qᴴ dA_q Q, Qᴴ dB_q, dC_q Q) on the Schur route;
  // untransformed on the resolvent route, where with X = (λI − A)⁻¹ B_z and
  // Y = C (λI − A)⁻¹ every frequency likewise needs three GEMMs for all parameters.
  const Index n = b.A.rows(), ni = b.Bn.cols(), no = b.C.rows();
  const bool transformed = route.modal || route.schur;
  const Eigen::MatrixXcd Vr = transformed ? route.V : Eigen::MatrixXcd::Identity(n, n);
  const Eigen::MatrixXcd Vl = transformed ? route.Vinv : Eigen::MatrixXcd::Identity(n, n);
  st.dAv.resize(n * st.n_inner, n);
  st.dBvn.resize(n * st.n_inner, ni);
  if (any_old) st.dBvo.resize(n * st.n_inner, ni);
  st.dCv.resize(no * st.n_outer, n);
  for (Index q = 0; q < p; ++q) {
    const auto s = static_cast<std::size_t>(q);
    if (const Index r = st.pos_inner[s]; r >= 0) {
      st.dAv.middleRows(r * n, n).noalias() = Vl * (b.dA[s].cast<Cx>() * Vr);
      st.dBvn.middleRows(r * n, n).noalias() = Vl * b.dBn[s].cast<Cx>();
      if (any_old) st.dBvo.middleRows(r * n, n).noalias() = Vl * b.dBo[s].cast<Cx>();
    }
    if (const Index r = st.pos_outer[s]; r >= 0) st.dCv.middleRows(r * no, no).noalias() = b.dC[s].cast<Cx>() * Vr;
  }
  return st;
}

// The plant response P line by line on the chosen route, and with derivatives the
// stacked products every parameter's dP is gathered from.
class LineResponder {
 public:
  LineResponder(const Engine::Built& b, const Route& route, const Stacks& st, const bool any_old)
      : route_(route), st_(st), any_old_(any_old), n_(b.A.rows()), ni_(b.Bn.cols()), no_(b.C.rows()),
        Ac_(b.A.cast<Cx>()), Bnc_(b.Bn.cast<Cx>()), Boc_(b.Bo.cast<Cx>()), Cc_(b.C.cast<Cx>()), Dc_(b.D.cast<Cx>()),
        Z_(n_, n_), Chd_(no_, n_), Bhd_(n_, ni_), Bhz_(n_, ni_), dPm_(no_, ni_) {}

  // P(λ) before the inputs' column factors; dcol: D's column factors (z⁻¹ where an
  // input's delay is fractional); with derivatives, R and S (below) for this line.
  CMat plant(const Cx lambda, const Cx zinv, const Eigen::Matrix<Cx, Eigen::Dynamic, 1, 0, kMaxDim, 1>& dcol,
             const bool derivatives) {
    const Index n = n_;
    CMat P(no_, ni_);
    if (route_.modal) {
      if (any_old_)
        Bhz_ = route_.Bhn + route_.Bho * zinv;
      else
        Bhz_ = route_.Bhn;
      for (Index a = 0; a < n; ++a) {
        const Cx da = 1.0 / (lambda - route_.mu(a));
        Chd_.col(a) = route_.Ch.col(a) * da;
      }
      dPm_.noalias() = Chd_ * Bhz_;
      P = dPm_ + Dc_ * dcol.asDiagonal();
      if (derivatives) {
        for (Index a = 0; a < n; ++a) Bhd_.row(a) = Bhz_.row(a) / (lambda - route_.mu(a));
        stacked_products(Chd_, Bhd_, zinv);  // X = Λ Bh, Y = Ch Λ
      }
    } else if (route_.schur) {
      // X = (λI − T)⁻¹ Qᴴ B_z and Y = C Q (λI − T)⁻¹ by back substitution; then as
      // on the resolvent route below, in Schur coordinates.
      Z_ = -route_.Tq;
      Z_.diagonal().array() += lambda;
      Bhz_ = any_old_ ? Eigen::MatrixXcd(route_.Bhn + route_.Bho * zinv) : route_.Bhn;
      X_ = Z_.triangularView<Eigen::Upper>().solve(Bhz_);
      if (derivatives) {
        Y_ = Z_.triangularView<Eigen::Upper>().solve<Eigen::OnTheRight>(route_.Ch);
        stacked_products(Y_, X_, zinv);
      }
      dPm_.noalias() = route_.Ch * X_;
      P = dPm_ + Dc_ * dcol.asDiagonal();
    } else {
      Z_ = -Ac_;
      Z_.diagonal().array() += lambda;
      const Eigen::PartialPivLU<Eigen::MatrixXcd> lu(Z_);
      Bz_ = any_old_ ? Eigen::MatrixXcd(Bnc_ + Boc_ * zinv) : Bnc_;
      if (!derivatives) {
        X_ = lu.solve(Bz_);
      } else {
        const Eigen::MatrixXcd Rz = lu.inverse();
        X_ = Rz * Bz_;
        Y_ = Cc_ * Rz;
        stacked_products(Y_, X_, zinv);
      }
      P = Cc_ * X_ + Dc_ * dcol.asDiagonal();
    }
    return P;
  }

  // dP_q before the column factors: Ch Λ (dAh Λ Bh + dBh) + dCh Λ Bh (modal),
  // Y (dA X + dB) + dC X (resolvent), gathered from the stacked products.
  CMat parameter_dP(const std::size_t s) {
    const Index qi = st_.pos_inner[s], qo = st_.pos_outer[s];
    for (Index j = 0; j < ni_; ++j)
      for (Index i = 0; i < no_; ++i)
        dPm_(i, j) = (qi >= 0 ? R_(i, j * st_.n_inner + qi) : Cx(0.0)) + (qo >= 0 ? S_(qo * no_ + i, j) : Cx(0.0));
    return dPm_;
  }

 private:
  // With X = (λI − A)⁻¹ B_z and Y = C (λI − A)⁻¹ in the route's coordinates (modal,
  // Schur or none): U = [dA_q X + dB_q] (n·p_in × n_in, inner q); R = Y U reshaped
  // (n_out × n_in·p_in, column j·p_in + q); S = [dC_q X] (n_out·p_out × n_in).
  void stacked_products(const Eigen::MatrixXcd& Yk, const Eigen::MatrixXcd& Xk, const Cx zinv) {
    if (st_.n_inner > 0) {
      U_.noalias() = st_.dAv * Xk;
      U_ += st_.dBvn;
      if (any_old_) U_ += st_.dBvo * zinv;
      R_.noalias() = Yk * Eigen::Map<const Eigen::MatrixXcd>(U_.data(), n_, ni_ * st_.n_inner);
    }
    if (st_.n_outer > 0) S_.noalias() = st_.dCv * Xk;
  }

  const Route& route_;
  const Stacks& st_;
  const bool any_old_;
  const Index n_, ni_, no_;
  const Eigen::MatrixXcd Ac_, Bnc_, Boc_, Cc_, Dc_;
  // work space, allocated once per evaluation
  Eigen::MatrixXcd Z_, Chd_, Bhd_, Bhz_, X_, Y_, Bz_, dPm_;
  Eigen::MatrixXcd U_, R_, S_;  // stacked derivative products
};

}  // namespace

// T (and dT) at the prepared frequencies from the built matrices; p: the number
// of parameters whose derivatives b holds (0: none).
bool Engine::respond(const Prepared& d, const Index p, const Built& b, std::vector<CMat>& T,
                     std::vector<std::vector<CMat>>* dT) const {
  const double ts = options_.sample_period_s;
  if (!b.A.allFinite() || !b.Bn.allFinite() || !b.Bo.allFinite() || !b.C.allFinite()) return false;
  const Index ni = b.Bn.cols(), no = b.C.rows();
  const bool any_old = ts > 0.0 && b.Bo.cwiseAbs().maxCoeff() > 0.0;
  const std::size_t F = d.omega.size();
  T.resize(F);
  if (dT != nullptr) dT->resize(F);
  const bool derivatives = dT != nullptr && p > 0;
  const Route route = choose_route(b);
  const Stacks stacks = stack_derivatives(b, p, any_old, dT != nullptr, route);
  // dD is zero unless a block has feedthrough depending on a parameter (resonance gains)
  std::vector<bool> dD_nonzero;
  for (const auto& m : b.dD) dD_nonzero.push_back(m.cwiseAbs().maxCoeff() > 0.0);
  LineResponder line(b, route, stacks, any_old);
  for (std::size_t k = 0; k < F; ++k) {
    const double w = d.omega[k];
    const Cx lambda = ts > 0.0 ? std::exp(Cx(0.0, w * ts)) : Cx(0.0, w);
    const Cx zinv = ts > 0.0 ? 1.0 / lambda : Cx(0.0);
    // column factors: z^-k_j (sampled) or e^{-jω tau_j} (continuous); D_f column j × z⁻¹ when fractional
    Eigen::Matrix<Cx, Eigen::Dynamic, 1, 0, kMaxDim, 1> colf(ni), dcol(ni);
    for (Index j = 0; j < ni; ++j) {
      const auto jj = static_cast<std::size_t>(j);
      colf(j) = ts > 0.0 ? std::exp(Cx(0.0, -w * ts * static_cast<double>(b.shift[jj])))
                         : std::exp(Cx(0.0, -w * b.tau[jj]));
      dcol(j) = ts > 0.0 && b.frac[jj] ? zinv : Cx(1.0);
    }
    const CMat P0 = line.plant(lambda, zinv, dcol, derivatives);  // before the column factors
    const CMat P = P0 * colf.asDiagonal();
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
    if (!derivatives) continue;
    auto& out = (*dT)[k];
    out.resize(static_cast<std::size_t>(p));
    for (Index q = 0; q < p; ++q) {
      const auto s = static_cast<std::size_t>(q);
      CMat dP = line.parameter_dP(s);
      if (dD_nonzero[s]) dP += b.dD[s].cast<Cx>() * dcol.asDiagonal();
      dP = dP * colf.asDiagonal();
      if (ts == 0.0)
        for (Index j : delay_of_[s]) dP.col(j) += Cx(0.0, -w) * P0.col(j) * colf(j);
      out[s] = plant ? dP : CMat(Lm * dP * Rm);
    }
  }
  return true;
}

}  // namespace fit_detail
}  // namespace lpvid
