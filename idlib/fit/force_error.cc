#include "idlib/fit/force_error.h"
#include "idlib/fit/force_error_detail.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include "idlib/core/error.h"
#include "idlib/physical/mechanical/mechanical_base.h"

namespace lpvid {

SavitzkyGolay::SavitzkyGolay(Index window) {
  if (window < 5 || window % 2 == 0)
    throw InputError(fmt::format("the smoothing window is {} samples; it must be odd and at least 5", window));
  const Index h = (window - 1) / 2;
  Eigen::MatrixXd V(window, 4);
  for (Index m = -h; m <= h; ++m)
    for (Index k = 0; k < 4; ++k) V(m + h, k) = std::pow(static_cast<double>(m), static_cast<double>(k));
  // rows of (VᵀV)⁻¹Vᵀ: the cubic's coefficients at the centre
  const Eigen::MatrixXd A = (V.transpose() * V).ldlt().solve(V.transpose());
  h0 = A.row(0).transpose();
  h1 = A.row(1).transpose();
  h2 = 2.0 * A.row(2).transpose();
}

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using force_error_detail::rms;
using force_error_detail::time_effect_names;
using force_error_detail::is_time_effect;
using force_error_detail::ripple_regressors;
using force_error_detail::saturated_input;
using force_error_detail::stribeck_regressor;

// y(k) = Σ_m h(m) x(k + m) for k in [from, to).
VectorXd filter(const VectorXd& h, const VectorXd& x, Index from, Index to) {
  const Index half = (h.size() - 1) / 2;
  VectorXd y(to - from);
  for (Index k = from; k < to; ++k) y(k - from) = h.dot(x.segment(k - half, h.size()));
  return y;
}


// Where each parameter enters the force balance of each DOF, per sample:
// r_i = Σ terms (coefficient × θ_param or × 1) × signal.
enum class Signal { kW, kQdd, kQd, kQ, kSign, kOne, kStribeck, kRippleSin, kRippleCos };
struct Term {
  Index param = -1;  // -1: a constant coefficient
  double coefficient = 0.0;
  Signal signal = Signal::kOne;
  Index channel = 0;
};

struct Balance {
  std::vector<std::vector<Term>> rows;  // per DOF
  // stribeck_friction: per DOF the index of its velocity scale v_s (-1: none), and the
  // regressor k ∗ (sign q' exp(−(q'/v_s)²)) at the values given to set_shapes
  std::vector<Index> stribeck_v;
  MatrixXd stribeck;
  // input_saturation: per input the index of its limit w_max (-1: none), and the input's
  // column k ∗ hold(clip(w, ±w_max)) at the values given to set_shapes, in place of d.w's
  std::vector<Index> saturation;
  MatrixXd w_sat;
  // position_ripple(_2): per ripple term (an effect's DOF) its DOF and the index of its
  // period p, and the regressors k ∗ sin(2π q/p), k ∗ cos(2π q/p) at the values given to
  // set_shapes, a column per term
  struct Ripple {
    Index dof = 0, period = -1;
  };
  std::vector<Ripple> ripples;
  MatrixXd ripple_sin, ripple_cos;
};

// The terms whose shape depends on a parameter (Stribeck's v_s, a limit w_max, a ripple's
// period), built at p.
void set_shapes(Balance& b, const ForceErrorData& d, const VectorXd& p) {
  const Index nd = static_cast<Index>(b.rows.size());
  b.stribeck = MatrixXd::Zero(d.n(), nd);
  for (Index i = 0; i < nd; ++i)
    if (b.stribeck_v[static_cast<std::size_t>(i)] >= 0)
      b.stribeck.col(i) = stribeck_regressor(d, i, p(b.stribeck_v[static_cast<std::size_t>(i)]));
  b.ripple_sin.resize(d.n(), static_cast<Index>(b.ripples.size()));
  b.ripple_cos.resize(d.n(), static_cast<Index>(b.ripples.size()));
  for (std::size_t t = 0; t < b.ripples.size(); ++t) {
    const auto [sine, cosine] = ripple_regressors(d, b.ripples[t].dof, p(b.ripples[t].period));
    b.ripple_sin.col(static_cast<Index>(t)) = sine;
    b.ripple_cos.col(static_cast<Index>(t)) = cosine;
  }
  b.w_sat.resize(0, 0);
  for (std::size_t j = 0; j < b.saturation.size(); ++j)
    if (b.saturation[j] >= 0) {
      if (b.w_sat.rows() == 0) b.w_sat = d.w;
      b.w_sat.col(static_cast<Index>(j)) = saturated_input(d, static_cast<Index>(j), p(b.saturation[j]));
    }
}

// The actuators' input j as the balance sees it (clipped when the model has a limit on it).
const MatrixXd& inputs_of(const Balance& b, const ForceErrorData& d) { return b.w_sat.rows() > 0 ? b.w_sat : d.w; }

Balance balance_of(const PhysicalModel& model) {
  const MechanicalIndices L(model);
  Balance b;
  b.rows.assign(static_cast<std::size_t>(L.n_dof), {});
  b.stribeck_v.assign(static_cast<std::size_t>(L.n_dof), -1);
  b.saturation.assign(static_cast<std::size_t>(L.n_in), -1);
  auto add = [&](const std::vector<MechanicalIndices::Entry>& entries, Signal s, double sign) {
    for (const auto& e : entries)
      b.rows[static_cast<std::size_t>(e.row)].push_back({e.parameter, sign * e.coefficient, s, e.col});
  };
  add(L.input_map, Signal::kW, 1.0);
  add(L.mass, Signal::kQdd, -1.0);
  add(L.damping, Signal::kQd, -1.0);
  add(L.stiffness, Signal::kQ, -1.0);
  for (const std::string& name : model.effects) {
    const EffectInfo* e = model.effect_info(name);
    if (!e->blocks.empty())
      throw InputError(fmt::format(
          "the force-error route (fit --log on a mechanical base) fits the equation of motion; the model has {}, a "
          "frequency-route effect: remove it (lpvid model remove {} --model MODEL.json) or fit it on a measured "
          "response (fit --data)",
          name, name));
    if (!is_time_effect(name))
      throw InputError(fmt::format("the force-error route has no form for the effect {}", name));
    if (name == "input_saturation") {  // a limit per input: it shapes w, adds no term
      for (Index j = 0; j < L.n_in; ++j)
        b.saturation[static_cast<std::size_t>(j)] = model.index_of(e->parameters[static_cast<std::size_t>(j)].name);
      continue;
    }
    if (name == "position_ripple" || name == "position_ripple_2") {  // per DOF: a, b; then the periods
      for (Index i = 0; i < L.n_dof; ++i) {
        auto& row = b.rows[static_cast<std::size_t>(i)];
        auto at = [&](Index k) { return model.index_of(e->parameters[static_cast<std::size_t>(k)].name); };
        const auto term = static_cast<Index>(b.ripples.size());
        row.push_back({at(i), -1.0, Signal::kRippleSin, term});
        row.push_back({at(L.n_dof + i), -1.0, Signal::kRippleCos, term});
        b.ripples.push_back({i, at(2 * L.n_dof + i)});
      }
      continue;
    }
    const Signal s = name == "coulomb_friction" ? Signal::kSign
                     : name == "force_offset"   ? Signal::kOne
                                                : Signal::kStribeck;
    for (Index i = 0; i < L.n_dof; ++i) {
      b.rows[static_cast<std::size_t>(i)].push_back(
          {model.index_of(e->parameters[static_cast<std::size_t>(i)].name), -1.0, s, i});
      if (s == Signal::kStribeck)  // its parameters: F_s per DOF, then v_s per DOF
        b.stribeck_v[static_cast<std::size_t>(i)] =
            model.index_of(e->parameters[static_cast<std::size_t>(L.n_dof + i)].name);
    }
  }
  return b;
}

double signal_at(const ForceErrorData& d, const Balance& b, Signal s, Index channel, Index k) {
  switch (s) {
    case Signal::kStribeck: return b.stribeck(k, channel);
    case Signal::kRippleSin: return b.ripple_sin(k, channel);
    case Signal::kRippleCos: return b.ripple_cos(k, channel);
    case Signal::kW: return inputs_of(b, d)(k, channel);
    case Signal::kQdd: return d.qdd(k, channel);
    case Signal::kQd: return d.qd(k, channel);
    case Signal::kQ: return d.q(k, channel);
    case Signal::kSign: return d.sign_v(k, channel);
    case Signal::kOne: return 1.0;
  }
  return 0.0;
}

// The residual, n × n_dof, at parameter values p.
MatrixXd residual_at(const Balance& b, const ForceErrorData& d, const VectorXd& p) {
  const Index nd = static_cast<Index>(b.rows.size());
  MatrixXd r = MatrixXd::Zero(d.n(), nd);
  for (Index i = 0; i < nd; ++i)
    for (const Term& t : b.rows[static_cast<std::size_t>(i)]) {
      const double c = t.coefficient * (t.param >= 0 ? p(t.param) : 1.0);
      if (c == 0.0) continue;
      for (Index k = 0; k < d.n(); ++k) r(k, i) += c * signal_at(d, b, t.signal, t.channel, k);
    }
  return r;
}

// The actuators' force B_w w, n × n_dof, at parameter values p.
MatrixXd applied_at(const Balance& b, const ForceErrorData& d, const VectorXd& p) {
  const Index nd = static_cast<Index>(b.rows.size());
  MatrixXd f = MatrixXd::Zero(d.n(), nd);
  for (Index i = 0; i < nd; ++i)
    for (const Term& t : b.rows[static_cast<std::size_t>(i)])
      if (t.signal == Signal::kW)
        f.col(i) += t.coefficient * (t.param >= 0 ? p(t.param) : 1.0) * inputs_of(b, d).col(t.channel);
  return f;
}

// rms((B_w w)_i) per DOF at parameter values p.
VectorXd force_scales(const Balance& b, const ForceErrorData& d, const VectorXd& p) {
  const Index nd = static_cast<Index>(b.rows.size());
  const MatrixXd f = applied_at(b, d, p);
  VectorXd s(nd);
  for (Index i = 0; i < nd; ++i) s(i) = rms(f.col(i));
  const double largest = s.maxCoeff();
  for (Index i = 0; i < nd; ++i)
    if (!(s(i) > 0.0)) s(i) = largest > 0.0 ? largest : 1.0;
  return s;
}

// The noise floor's force std per DOF at parameter values p (header comment).
VectorXd floor_forces(const Balance& b, const ForceErrorData& d, const VectorXd& p) {
  const Index nd = static_cast<Index>(b.rows.size());
  const double ts = d.sample_period_s;
  VectorXd out(nd);
  for (Index i = 0; i < nd; ++i) {
    // coefficients of each signal channel summed first (entries of one matrix row)
    VectorXd cw = VectorXd::Zero(d.w.cols()), ca = VectorXd::Zero(nd), cv = VectorXd::Zero(nd), cq = VectorXd::Zero(nd);
    for (const Term& t : b.rows[static_cast<std::size_t>(i)]) {
      const double c = t.coefficient * (t.param >= 0 ? p(t.param) : 1.0);
      if (t.signal == Signal::kW) cw(t.channel) += c;
      if (t.signal == Signal::kQdd) ca(t.channel) += c;
      if (t.signal == Signal::kQd) cv(t.channel) += c;
      if (t.signal == Signal::kQ) cq(t.channel) += c;
    }
    double var = 0.0;
    for (Index j = 0; j < d.w.cols(); ++j) var += std::pow(cw(j) * d.g0 * d.w_noise(j), 2);
    for (Index j = 0; j < nd; ++j)
      var += std::pow(d.q_noise(j), 2) *
             (std::pow(ca(j) * d.g2 / (ts * ts), 2) + std::pow(cv(j) * d.g1 / ts, 2) + std::pow(cq(j) * d.g0, 2));
    out(i) = std::sqrt(var);
  }
  return out;
}

// Minimises ½θᵀAθ − gᵀθ subject to lo <= θ <= hi (A symmetric positive semidefinite,
// small): an active set from a feasible θ, each free subproblem solved by the
// pseudo-inverse (a direction A does not determine stays where it is).  *state: per
// coordinate 0 free, −1 on its lower bound, +1 on its upper bound.
VectorXd bounded_least_squares(const MatrixXd& As, const VectorXd& gs, const VectorXd& lo, const VectorXd& hi,
                               VectorXd theta, std::vector<int>* state) {
  const Index nf = theta.size();
  std::vector<int>& st = *state;
  st.assign(static_cast<std::size_t>(nf), 0);
  auto solve_free = [&](const VectorXd& from) {
    // minimise ½θᵀAsθ − gsᵀθ over the free coordinates, the others held; min-norm step
    std::vector<Index> idx;
    for (Index k = 0; k < nf; ++k)
      if (st[static_cast<std::size_t>(k)] == 0) idx.push_back(k);
    VectorXd target = from;
    if (idx.empty()) return target;
    const Index m = static_cast<Index>(idx.size());
    MatrixXd Af(m, m);
    VectorXd rhs(m);
    for (Index a = 0; a < m; ++a) {
      rhs(a) = gs(idx[static_cast<std::size_t>(a)]) - As.row(idx[static_cast<std::size_t>(a)]).dot(from);
      for (Index c = 0; c < m; ++c) Af(a, c) = As(idx[static_cast<std::size_t>(a)], idx[static_cast<std::size_t>(c)]);
    }
    Eigen::SelfAdjointEigenSolver<MatrixXd> e(Af);
    const double top = std::max(e.eigenvalues().maxCoeff(), 1e-300);
    VectorXd inv = e.eigenvalues();
    for (Index a = 0; a < m; ++a) inv(a) = inv(a) > 1e-10 * top ? 1.0 / inv(a) : 0.0;
    const VectorXd step = e.eigenvectors() * inv.asDiagonal() * e.eigenvectors().transpose() * rhs;
    for (Index a = 0; a < m; ++a) target(idx[static_cast<std::size_t>(a)]) += step(a);
    return target;
  };
  for (int iter = 0; iter < 4 * static_cast<int>(nf) + 8; ++iter) {
    const VectorXd target = solve_free(theta);
    // step towards the target until the first bound
    double alpha = 1.0;
    Index hit = -1;
    for (Index k = 0; k < nf; ++k) {
      if (st[static_cast<std::size_t>(k)] != 0) continue;
      const double delta = target(k) - theta(k);
      if (target(k) < lo(k) && delta < 0.0 && (lo(k) - theta(k)) / delta < alpha) {
        alpha = (lo(k) - theta(k)) / delta;
        hit = k;
      }
      if (target(k) > hi(k) && delta > 0.0 && (hi(k) - theta(k)) / delta < alpha) {
        alpha = (hi(k) - theta(k)) / delta;
        hit = k;
      }
    }
    theta += std::max(alpha, 0.0) * (target - theta);
    if (hit >= 0) {
      st[static_cast<std::size_t>(hit)] = target(hit) < lo(hit) ? -1 : 1;
      theta(hit) = st[static_cast<std::size_t>(hit)] < 0 ? lo(hit) : hi(hit);
      continue;
    }
    // at the free optimum: release a bound whose gradient points inside
    const VectorXd grad = As * theta - gs;
    Index release = -1;
    double worst = 0.0;
    for (Index k = 0; k < nf; ++k) {
      const int s = st[static_cast<std::size_t>(k)];
      if ((s < 0 && grad(k) < -worst) || (s > 0 && grad(k) > worst)) {
        worst = std::abs(grad(k));
        release = k;
      }
    }
    if (release < 0) break;
    st[static_cast<std::size_t>(release)] = 0;
  }
  return theta;
}

// The smoothing kernel k (a Hann window of half-width h, Σk = 1) and k moved onto the
// central first and second differences, all of half-width h + 1.
std::tuple<VectorXd, VectorXd, VectorXd> hann_kernels(Index h) {
  const Index W = 2 * h + 1, H = h + 1;
  VectorXd hann(W);
  for (Index m = -h; m <= h; ++m) hann(m + h) = std::pow(std::cos(M_PI * static_cast<double>(m) / (2.0 * (h + 1))), 2);
  hann /= hann.sum();
  auto kk = [&](Index m) { return m >= -h && m <= h ? hann(m + h) : 0.0; };
  VectorXd k0(2 * H + 1), k1(2 * H + 1), k2(2 * H + 1);
  for (Index m = -H; m <= H; ++m) {
    k0(m + H) = kk(m);
    k1(m + H) = 0.5 * (kk(m - 1) - kk(m + 1));
    k2(m + H) = kk(m - 1) - 2.0 * kk(m) + kk(m + 1);
  }
  return {k0, k1, k2};
}

// Drops the rows of d within H samples of a flagged sample (still: per sample of the
// log; row r of d is sample 2H + r).  @throws InputError  fewer than 4W rows left.
void leave_out_standstill(const std::vector<char>& still, Index H, Index W, ForceErrorData* d) {
  const Index N = static_cast<Index>(still.size()), n = d->n();
  std::vector<Index> prefix(static_cast<std::size_t>(N) + 1, 0);
  for (Index k = 0; k < N; ++k)
    prefix[static_cast<std::size_t>(k) + 1] = prefix[static_cast<std::size_t>(k)] + still[static_cast<std::size_t>(k)];
  std::vector<Index> keep;
  keep.reserve(static_cast<std::size_t>(n));
  for (Index r = 0; r < n; ++r) {
    const Index k = 2 * H + r;
    if (prefix[static_cast<std::size_t>(k + H + 1)] == prefix[static_cast<std::size_t>(k - H)]) keep.push_back(r);
  }
  d->standstill = n - static_cast<Index>(keep.size());
  d->sample.resize(static_cast<Index>(keep.size()));
  for (std::size_t r = 0; r < keep.size(); ++r) d->sample(static_cast<Index>(r)) = 2 * H + keep[r];
  if (static_cast<Index>(keep.size()) < 4 * W)
    throw InputError(fmt::format(
        "the log has {} of its {} samples away from standstill (every DOF moving faster than 3x its velocity noise, "
        "a window either side); the force-error route needs at least {}: log a motion (friction at rest holds any "
        "force up to its limit, which no model of the motion predicts)",
        keep.size(), n, 4 * W));
  if (d->standstill > 0) {
    auto compact = [&](MatrixXd& m) {
      MatrixXd out(static_cast<Index>(keep.size()), m.cols());
      for (std::size_t r = 0; r < keep.size(); ++r) out.row(static_cast<Index>(r)) = m.row(keep[r]);
      m = std::move(out);
    };
    for (MatrixXd* m : {&d->q, &d->qd, &d->qdd, &d->w, &d->sign_v}) compact(*m);
  }
}

// The figures of a fit at parameter values p: residual, actuator force, error and
// floor per DOF and over the DOFs, the rms-normalised RSS and n_eff (no BIC: a fit adds
// its parameters' count).
void score(ForceErrorFit& fit, const Balance& bal, const ForceErrorData& d, const VectorXd& p) {
  const Index nd = static_cast<Index>(bal.rows.size());
  fit.residual = residual_at(bal, d, p);
  fit.applied = applied_at(bal, d, p);
  const VectorXd scale = force_scales(bal, d, p);
  const VectorXd floor = floor_forces(bal, d, p);
  fit.error_per_dof.resize(nd);
  fit.floor_per_dof.resize(nd);
  fit.rss = 0.0;
  for (Index i = 0; i < nd; ++i) {
    fit.error_per_dof(i) = 100.0 * rms(fit.residual.col(i)) / scale(i);
    fit.floor_per_dof(i) = 100.0 * floor(i) / scale(i);
    fit.rss += fit.residual.col(i).squaredNorm() / (scale(i) * scale(i));
  }
  fit.error = std::sqrt(fit.error_per_dof.squaredNorm() / static_cast<double>(nd));
  fit.floor = std::sqrt(fit.floor_per_dof.squaredNorm() / static_cast<double>(nd));
  fit.n_eff = static_cast<double>(d.n() * nd) * d.centre_weight;
}

}  // namespace

namespace force_error_detail {

double rms(const Eigen::VectorXd& x) {
  return x.size() > 0 ? std::sqrt(x.squaredNorm() / static_cast<double>(x.size())) : 0.0;
}

const std::vector<std::string>& time_effect_names() {
  static const std::vector<std::string> names{"coulomb_friction", "force_offset", "stribeck_friction",
                                              "input_saturation", "position_ripple", "position_ripple_2"};
  return names;
}

bool is_time_effect(const std::string& name) {
  const auto& n = time_effect_names();
  return std::find(n.begin(), n.end(), name) != n.end();
}

}  // namespace force_error_detail

namespace {

// The median absolute deviation (robust: a friction reversal's kink is not noise).
double median_abs_deviation(VectorXd x) {
  if (x.size() == 0) return 0.0;
  const auto mid = x.begin() + x.size() / 2;
  std::nth_element(x.begin(), mid, x.end());
  const double med = *mid;
  x = (x.array() - med).abs();
  std::nth_element(x.begin(), x.begin() + x.size() / 2, x.end());
  return *(x.begin() + x.size() / 2);
}

// The log checked against the base, and the DOFs' positions q = C_q⁺ y.
MatrixXd positions_from_log(const PhysicalModel& model, const MatrixXd& inputs, const MatrixXd& outputs,
                            double sample_period_s) {
  if (model.user_base == nullptr)
    throw InputError(fmt::format("the force-error route needs a mechanical base (a model of 'lpvid model init --base "
                                 "mechanical --from DESCRIPTION.json'); this model's base is {}",
                                 model.base));
  model.validate();
  const MechanicalIndices L(model);
  const BaseInfo& b = model.base_info();
  for (Index o = 0; o < L.n_out; ++o)
    if (L.output_derivative[static_cast<std::size_t>(o)] != 0)
      throw InputError(fmt::format("output {} measures a {}; the force-error route needs positions of every DOF (an "
                                   "accelerometer structure is fitted on its measured response: fit --data)",
                                   b.output_names[static_cast<std::size_t>(o)],
                                   L.output_derivative[static_cast<std::size_t>(o)] == 1 ? "velocity" : "acceleration"));
  for (const auto& e : L.output_map)
    if (e.parameter >= 0 && model.parameters[static_cast<std::size_t>(e.parameter)].free)
      throw InputError(fmt::format("the output map uses the free parameter {}; the force-error route reads the DOFs "
                                   "off the sensors, so fix it (lpvid model set --fix)",
                                   model.parameters[static_cast<std::size_t>(e.parameter)].name));
  if (!(sample_period_s > 0.0) || !std::isfinite(sample_period_s))
    throw InputError(fmt::format("the log's sample period is {} s; it must be > 0", sample_period_s));
  if (inputs.cols() != L.n_in || outputs.cols() != L.n_out || inputs.rows() != outputs.rows())
    throw InputError(fmt::format("the log gives {} input and {} output columns of {} and {} samples; the base has {} "
                                 "inputs and {} outputs",
                                 inputs.cols(), outputs.cols(), inputs.rows(), outputs.rows(), L.n_in, L.n_out));
  if (!inputs.allFinite() || !outputs.allFinite())
    throw InputError("the log has a value that is not finite in a column the force-error route reads");
  const VectorXd p = model.values();
  MatrixXd M, D, K, Bw, Cq;
  mechanical_matrices<double>(L, p.data(), M, D, K, Bw, Cq);
  Eigen::FullPivLU<MatrixXd> lu(Cq);
  if (lu.rank() < L.n_dof)
    throw InputError(fmt::format("the outputs see only {} of the {} DOFs (the output map has rank {}); the force-error "
                                 "route needs every DOF's position",
                                 lu.rank(), L.n_dof, lu.rank()));
  // q = C_q⁺ y
  return outputs * Cq * (Cq.transpose() * Cq).inverse();
}

// What prepare_force_error's stages share: the window's kernels and reaches.
struct Smoothing {
  const SavitzkyGolay& sg;
  const VectorXd &k0, &k1, &k2;
  Index h, H, N, inner;
  double noise_scale;
};

// Per DOF: the noise, the smoothed position, velocity and acceleration, the
// friction's sign, and the samples at standstill (still) or a reversal.
void dof_signals(const MatrixXd& Q, const Smoothing& sm, double sample_period_s, ForceErrorData& d, MatrixXd& q_hf,
                 std::vector<char>& still) {
  const SavitzkyGolay& sg = sm.sg;
  const VectorXd &k0 = sm.k0, &k1 = sm.k1, &k2 = sm.k2;
  const Index h = sm.h, H = sm.H, N = sm.N, inner = sm.inner, n = d.q.rows();
  const double noise_scale = sm.noise_scale;
  const auto mad = median_abs_deviation;
  for (Index i = 0; i < Q.cols(); ++i) {
    const VectorXd qi = Q.col(i);
    q_hf.col(i) = qi.segment(h, inner) - filter(sg.h0, qi, h, N - h);
    d.q_noise(i) = mad(q_hf.col(i)) * noise_scale;
    const VectorXd v = filter(k1, qi, H, N - H) / sample_period_s;  // [H, N − H)
    // The friction's sign from the unsmoothed central difference: the smoothed
    // velocity crosses zero late where the friction's step bends the motion (measured:
    // 1.02 % of the force left at the reversals by the true model on the simulated
    // axis, against 0.4 % noise).  v_eps = 3 × its noise.
    VectorXd v_raw(N - 2 * H);
    for (Index k = H; k < N - H; ++k) v_raw(k - H) = 0.5 * (qi(k + 1) - qi(k - 1)) / sample_period_s;
    const double v_noise = d.q_noise(i) * std::sqrt(0.5) / sample_period_s;
    d.v_eps(i) = std::max(3.0 * v_noise, 1e-12 * v_raw.cwiseAbs().maxCoeff());
    if (!(d.v_eps(i) > 0.0)) d.v_eps(i) = std::numeric_limits<double>::min();
    for (Index k = H; k < N - H; ++k) {
      if (std::abs(v_raw(k - H)) < d.v_eps(i)) still[static_cast<std::size_t>(k)] = 1;
      // a reversal between two samples: the friction's step falls somewhere between them
      if (k > H && v_raw(k - H) * v_raw(k - H - 1) < 0.0)
        still[static_cast<std::size_t>(k)] = still[static_cast<std::size_t>(k - 1)] = 1;
    }
    d.v_raw.col(i) = v_raw;
    const VectorXd s = (v_raw / d.v_eps(i)).cwiseMax(-1.0).cwiseMin(1.0);
    d.sign_v.col(i) = filter(k0, s, H, s.size() - H);  // s(0) is sample H
    d.q.col(i) = filter(k0, qi, 2 * H, N - 2 * H);
    d.qd.col(i) = v.segment(H, n);
    d.qdd.col(i) = filter(k2, qi, 2 * H, N - 2 * H) / (sample_period_s * sample_period_s);
  }
}

// Per input: the smoothed (held) input and its noise, what the controller's reaction
// to the position noise does not explain.
void input_signals(const MatrixXd& inputs, const MatrixXd& q_hf, const Smoothing& sm, bool held_input,
                   ForceErrorData& d) {
  const SavitzkyGolay& sg = sm.sg;
  const VectorXd& k0 = sm.k0;
  const Index h = sm.h, H = sm.H, N = sm.N, inner = sm.inner;
  const Index n_dof = q_hf.cols(), n_in = inputs.cols();
  const double noise_scale = sm.noise_scale;
  const auto mad = median_abs_deviation;
  // The position noise at lags 0 .. kNoiseLags explains the controller's reaction to
  // it in w's high-frequency content (a PD with a filtered derivative reacts over a few
  // samples); what it does not is w's own noise.  Measured on the simulated axis's
  // motion that never reverses: with lags 0 and 1 only, the floor was 2.7x the error
  // the model reached.
  constexpr Index kNoiseLags = 8;
  const Index rows = inner - kNoiseLags;
  MatrixXd X(rows, (kNoiseLags + 1) * n_dof);
  for (Index lag = 0; lag <= kNoiseLags; ++lag)
    X.middleCols(lag * n_dof, n_dof) = q_hf.middleRows(kNoiseLags - lag, rows);
  for (Index j = 0; j < n_in; ++j) {
    VectorXd wj = inputs.col(j);
    if (held_input)
      for (Index k = N - 1; k > 0; --k) wj(k) = 0.5 * (wj(k) + wj(k - 1));
    d.w.col(j) = filter(k0, wj, 2 * H, N - 2 * H);
    const VectorXd hf = (wj.segment(h, inner) - filter(sg.h0, wj, h, N - h)).tail(rows);
    // The regression on the samples where w's high-frequency content is of the bulk's
    // size: a transient (a step in the reference, a hard stop) would set the
    // coefficients, and the bulk's residual, the noise estimate, would carry it
    // (measured: a 2 cm reference step in a point-to-point log lifted the floor 32x,
    // 0.037 % to 1.18 %).
    const double spread = std::max(mad(hf) * 1.4826, 1e-300);
    std::vector<Index> bulk;
    for (Index k = 0; k < rows; ++k)
      if (std::abs(hf(k)) <= 6.0 * spread) bulk.push_back(k);
    // (normal equations: the lagged noise columns are near-orthogonal, and one pass over
    // the log costs a tenth of a pivoted QR of N × 9)
    MatrixXd G = MatrixXd::Zero(X.cols(), X.cols());
    VectorXd rhs = VectorXd::Zero(X.cols());
    const bool all = static_cast<Index>(bulk.size()) == rows || static_cast<Index>(bulk.size()) < 4 * X.cols();
    if (all) {
      G.selfadjointView<Eigen::Lower>().rankUpdate(X.transpose());
      rhs = X.transpose() * hf;
    } else {
      for (const Index k : bulk) {
        G.selfadjointView<Eigen::Lower>().rankUpdate(X.row(k).transpose());
        rhs += hf(k) * X.row(k).transpose();
      }
    }
    G = G.selfadjointView<Eigen::Lower>();
    const VectorXd coef = G.ldlt().solve(rhs);
    d.w_noise(j) = mad(hf - X * coef) * noise_scale;
  }
}

}  // namespace

ForceErrorData prepare_force_error(const PhysicalModel& model, const MatrixXd& inputs, const MatrixXd& outputs,
                                   double sample_period_s, const ForceErrorOptions& options) {
  const MatrixXd Q = positions_from_log(model, inputs, outputs, sample_period_s);
  const MechanicalIndices L(model);

  ForceErrorData d;
  d.sample_period_s = sample_period_s;
  const double window_s = options.window_s > 0.0 ? options.window_s : kForceErrorDefaultWindowS;
  Index W = static_cast<Index>(std::llround(window_s / sample_period_s));
  if (W % 2 == 0) ++W;
  W = std::max<Index>(W, 5);
  d.window = W;
  const Index N = inputs.rows();
  if (N < 4 * W)
    throw InputError(fmt::format("the log has {} samples; the force-error route with a {}-sample window ({} s) needs "
                                 "at least {} (give a longer log, or a shorter --window-s)",
                                 N, W, window_s, 4 * W));
  // The noise: what a local cubic over the window does not follow (robust: the
  // median absolute deviation, so that a friction reversal's kink is not noise)
  const SavitzkyGolay sg(W);
  const Index h = sg.half();
  const double noise_scale = 1.4826 / std::sqrt(std::max(1.0 - sg.h0(h), 1e-12));
  // The smoothing kernel k: a Hann window, Σk = 1.  The derivatives are k moved onto
  // central differences by summation by parts, Σ k(m) Δ²q(j + m) = Σ (Δ²k)(n) q(j + n):
  // Δ²q/Ts² is the acceleration averaged under a ±Ts triangle, as (w(k−1) + w(k))/2 is
  // a held input's force, so that both sides of the balance see the same filter even
  // across a friction reversal (the cubic's own second derivative does not: measured,
  // 1.29 % of the force left by the true model on the simulated axis, all of it at the
  // reversals, against 0.4 % with this kernel).
  const Index H = h + 1;
  const auto [k0, k1, k2] = hann_kernels(h);
  d.centre_weight = k0.squaredNorm();
  d.g0 = k0.norm();
  d.g1 = k1.norm();
  d.g2 = k2.norm();
  const Index n_dof = L.n_dof, n_in = L.n_in;
  const Index n = N - 4 * H;  // [2H, N − 2H): the smoothed sign too
  d.first = 2 * H;
  d.q.resize(n, n_dof);
  d.qd.resize(n, n_dof);
  d.qdd.resize(n, n_dof);
  d.sign_v.resize(n, n_dof);
  d.w.resize(n, n_in);
  d.q_noise.resize(n_dof);
  d.v_eps.resize(n_dof);
  d.v_raw.resize(N - 2 * H, n_dof);
  d.kernel = k0;
  d.kernel_reach = H;
  d.w_noise.resize(n_in);
  d.w_log = inputs;
  d.held_input = options.held_input;
  d.q_raw = Q;
  const Index inner = N - 2 * h;  // [h, N − h): the cubic's residuals
  MatrixXd q_hf(inner, n_dof);
  const Smoothing sm{sg, k0, k1, k2, h, H, N, inner, noise_scale};
  std::vector<char> still(static_cast<std::size_t>(N), 0);  // a DOF at standstill
  dof_signals(Q, sm, sample_period_s, d, q_hf, still);
  input_signals(inputs, q_hf, sm, options.held_input, d);
  // Standstill: while a DOF rests, its friction holds any force up to F_c, which no
  // sign law predicts (measured on the simulated axis with a sticking Coulomb law: the
  // true model left 1.39 % of the force, all of it in the dwells at the reversals); and
  // at a reversal between two samples the friction's step falls at an instant the
  // samples do not resolve (0.129 % left with the noise 100x finer, against a floor of
  // 0.0025 %).  Samples within the kernel's reach of either are left out of the fit and
  // the figures.
  leave_out_standstill(still, H, W, &d);
  return d;
}

namespace force_error_detail {

ForceErrorFit fit_with_fixed_shape(const PhysicalModel& start, const ForceErrorData& d) {
  start.validate();
  Balance bal = balance_of(start);
  set_shapes(bal, d, start.values());
  const std::vector<Index> free = start.free_indices();
  if (free.empty()) throw InputError("the model has no free parameter to fit (lpvid model set --model MODEL.json --free NAME)");
  const Index P = static_cast<Index>(start.parameters.size()), nf = static_cast<Index>(free.size());
  const Index nd = static_cast<Index>(bal.rows.size());
  VectorXd p = start.values();
  std::vector<Index> slot(static_cast<std::size_t>(P), -1);
  for (Index k = 0; k < nf; ++k) slot[static_cast<std::size_t>(free[static_cast<std::size_t>(k)])] = k;
  // A balance with every term free is homogeneous: the log fixes only ratios (a force
  // constant and a mass scaled together leave the residual scaled, zero at zero), and
  // a prior cannot anchor it (the data's cost falls with the scale).
  bool anchored = false;
  std::vector<std::string> in_balance;
  for (const auto& terms : bal.rows)
    for (const Term& t : terms) {
      const bool fixed = t.param < 0 || slot[static_cast<std::size_t>(t.param)] < 0;
      if (fixed && t.coefficient * (t.param >= 0 ? p(t.param) : 1.0) != 0.0) anchored = true;
      if (t.param >= 0 && std::find(in_balance.begin(), in_balance.end(),
                                    start.parameters[static_cast<std::size_t>(t.param)].name) == in_balance.end())
        in_balance.push_back(start.parameters[static_cast<std::size_t>(t.param)].name);
    }
  if (!anchored)
    throw InputError(fmt::format(
        "every term of the force balance is free ({}): a log fixes only their ratios (a force constant and the "
        "masses scaled together leave the same residual); fix one at a known value (a datasheet force constant, a "
        "weighed mass: lpvid model set); a prior does not decide it (the balance's residual shrinks with the scale, so "
        "the least-squares fit would shrink every term towards zero)",
        fmt::join(in_balance, ", ")));
  // Weights: 1 / (the start's noise force × sqrt(window)), a χ² with the priors
  const VectorXd scale0 = force_scales(bal, d, p);
  VectorXd floor0 = floor_forces(bal, d, p);
  const double correlation = 1.0 / d.centre_weight;
  VectorXd weight(nd);
  for (Index i = 0; i < nd; ++i) {
    const double s = floor0(i) > 1e-9 * scale0(i) ? floor0(i) : 1e-9 * scale0(i);
    weight(i) = 1.0 / (s * std::sqrt(correlation));
  }
  // Normal equations of r = c + Φ θ_free (one pass; c collects fixed terms)
  MatrixXd A = MatrixXd::Zero(nf, nf);
  VectorXd g = VectorXd::Zero(nf);
  VectorXd row(nf);
  for (Index i = 0; i < nd; ++i) {
    const auto& terms = bal.rows[static_cast<std::size_t>(i)];
    for (Index k = 0; k < d.n(); ++k) {
      row.setZero();
      double c = 0.0;
      for (const Term& t : terms) {
        const double s = t.coefficient * signal_at(d, bal, t.signal, t.channel, k) * weight(i);
        const Index f = t.param >= 0 ? slot[static_cast<std::size_t>(t.param)] : -1;
        if (f >= 0)
          row(f) += s;
        else
          c += s * (t.param >= 0 ? p(t.param) : 1.0);
      }
      A.selfadjointView<Eigen::Lower>().rankUpdate(row);
      g -= c * row;
    }
  }
  A = A.selfadjointView<Eigen::Lower>();
  for (Index k = 0; k < nf; ++k) {
    const PhysicalParameter& q = start.parameters[static_cast<std::size_t>(free[static_cast<std::size_t>(k)])];
    if (q.has_prior()) {
      A(k, k) += 1.0 / (q.prior_sigma * q.prior_sigma);
      g(k) += q.prior_mean / (q.prior_sigma * q.prior_sigma);
    }
  }
  // Scaled to unit diagonal; the null space (what the log cannot separate) found and
  // left at the start values
  VectorXd col_scale(nf);
  for (Index k = 0; k < nf; ++k) col_scale(k) = A(k, k) > 0.0 ? 1.0 / std::sqrt(A(k, k)) : 1.0;
  const MatrixXd As = col_scale.asDiagonal() * A * col_scale.asDiagonal();
  ForceErrorFit fit;
  Eigen::SelfAdjointEigenSolver<MatrixXd> eig(As);
  const double largest = std::max(eig.eigenvalues().maxCoeff(), 1e-300);
  for (Index k = 0; k < nf; ++k) {
    if (eig.eigenvalues()(k) > 1e-10 * largest) continue;
    std::vector<std::string> names;
    const VectorXd v = eig.eigenvectors().col(k);
    for (Index j = 0; j < nf; ++j)
      if (std::abs(v(j)) > 0.2) names.push_back(start.parameters[static_cast<std::size_t>(free[static_cast<std::size_t>(j)])].name);
    fit.unidentifiable.push_back(
        names.size() == 1
            ? fmt::format("{} has no effect on the force balance of this log; it is left at its start value", names[0])
            : fmt::format("{} move together on this log (their combination is not determined; fix one of them or "
                          "give a prior: lpvid model set)",
                          fmt::join(names, ", ")));
  }
  // Bounded least squares: active set from the start clipped to its bounds
  VectorXd lo(nf), hi(nf), theta(nf);
  for (Index k = 0; k < nf; ++k) {
    const PhysicalParameter& q = start.parameters[static_cast<std::size_t>(free[static_cast<std::size_t>(k)])];
    lo(k) = q.lower / col_scale(k);
    hi(k) = q.upper / col_scale(k);
    theta(k) = std::clamp(q.value, q.lower, q.upper) / col_scale(k);
  }
  const VectorXd gs = col_scale.asDiagonal() * g;
  std::vector<int> state;
  theta = bounded_least_squares(As, gs, lo, hi, theta, &state);
  for (Index k = 0; k < nf; ++k) p(free[static_cast<std::size_t>(k)]) = theta(k) * col_scale(k);

  fit.model = start;
  for (Index k = 0; k < nf; ++k)
    fit.model.parameters[static_cast<std::size_t>(free[static_cast<std::size_t>(k)])].value =
        std::clamp(p(free[static_cast<std::size_t>(k)]),
                   start.parameters[static_cast<std::size_t>(free[static_cast<std::size_t>(k)])].lower,
                   start.parameters[static_cast<std::size_t>(free[static_cast<std::size_t>(k)])].upper);
  p = fit.model.values();
  score(fit, bal, d, p);
  double chi2 = 0.0;
  for (Index i = 0; i < nd; ++i) chi2 += fit.residual.col(i).squaredNorm() * weight(i) * weight(i);
  const double n_total = static_cast<double>(d.n() * nd);
  fit.bic = fit.n_eff * std::log(std::max(fit.rss, 1e-300) / n_total) + static_cast<double>(nf) * std::log(fit.n_eff);
  // Covariance: (ΦᵀWΦ)⁻¹ scaled by the reduced χ² (the floor is an estimate)
  const double reduced = chi2 / std::max(fit.n_eff - static_cast<double>(nf), 1.0);
  VectorXd inv = eig.eigenvalues();
  for (Index k = 0; k < nf; ++k) inv(k) = inv(k) > 1e-10 * largest ? 1.0 / inv(k) : 0.0;
  const MatrixXd cov_s = eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose();
  for (Index k = 0; k < nf; ++k) {
    const PhysicalParameter& q = fit.model.parameters[static_cast<std::size_t>(free[static_cast<std::size_t>(k)])];
    ForceErrorParameter e;
    e.name = q.name;
    e.unit = q.unit;
    e.value = q.value;
    e.std_error = std::sqrt(std::max(cov_s(k, k) * reduced, 0.0)) * col_scale(k);
    if (inv(k) == 0.0 && cov_s(k, k) == 0.0) e.std_error = std::numeric_limits<double>::quiet_NaN();
    // from the final θ, not the active set's last state (a bound released on the last
    // pass, or a partial step, leaves the state behind the value)
    e.at_bound = theta(k) <= lo(k) || theta(k) >= hi(k);
    fit.parameters.push_back(e);
  }
  return fit;
}

}  // namespace force_error_detail

ForceErrorFit evaluate_force_error(const PhysicalModel& model, const ForceErrorData& d) {
  model.validate();
  Balance bal = balance_of(model);
  const VectorXd p = model.values();
  set_shapes(bal, d, p);
  ForceErrorFit fit;
  fit.model = model;
  score(fit, bal, d, p);
  const double n_total = static_cast<double>(d.n() * static_cast<Index>(bal.rows.size()));
  fit.bic = fit.n_eff * std::log(std::max(fit.rss, 1e-300) / n_total);
  for (const Index k : model.free_indices()) {
    const PhysicalParameter& q = model.parameters[static_cast<std::size_t>(k)];
    fit.parameters.push_back({q.name, q.unit, q.value, std::numeric_limits<double>::quiet_NaN(), false});
  }
  return fit;
}

namespace force_error_detail {

std::vector<ShapeParameter> shape_parameters(const PhysicalModel& model) {
  const Balance b = balance_of(model);
  std::vector<ShapeParameter> out;
  for (std::size_t i = 0; i < b.stribeck_v.size(); ++i)
    if (b.stribeck_v[i] >= 0) out.push_back({b.stribeck_v[i], ShapeParameter::Kind::kStribeckScale, static_cast<Index>(i)});
  for (std::size_t j = 0; j < b.saturation.size(); ++j)
    if (b.saturation[j] >= 0) out.push_back({b.saturation[j], ShapeParameter::Kind::kInputLimit, static_cast<Index>(j)});
  for (const auto& r : b.ripples) out.push_back({r.period, ShapeParameter::Kind::kRipplePeriod, r.dof});
  return out;
}

}  // namespace force_error_detail

}  // namespace lpvid
