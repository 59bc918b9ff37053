#include "idlib/physical/evaluate.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <cmath>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

Index channel_of(const std::vector<std::string>& names, const std::string& name) {
  const auto it = std::find(names.begin(), names.end(), name);
  LPVID_ASSERT(it != names.end());  // validate() checked the channel names
  return it - names.begin();
}

}  // namespace

ModelLayout::ModelLayout(const PhysicalModel& model) {
  model.validate();
  const BaseInfo& b = model.base_info();
  base = b.name;
  n_in = static_cast<Index>(b.input_names.size());
  n_out = static_cast<Index>(b.output_names.size());
  n_dof = static_cast<Index>(b.dof_names.size());
  if (b.compile) b.compile(*this, model);  // the base's own parameter positions
  delays.assign(static_cast<std::size_t>(n_in), {});
  for (const std::string& name : model.effects) {
    const EffectInfo* e = model.effect_info(name);
    if (e->time_only)
      throw InputError(fmt::format(
          "the model has {}, a nonlinear time-domain effect with no frequency response: fit and diagnose it on a "
          "log (lpvid fit --log RUN.csv), or remove it for this command (lpvid model remove {} --model MODEL.json)",
          name, name));
    for (const Block& blk : e->blocks) {
      CompiledBlock c{blk.kind, blk.side, {}, {}};
      const auto& names = blk.side == BlockSide::kOutput ? b.output_names : b.input_names;
      for (const std::string& ch : blk.channels) c.channels.push_back(channel_of(names, ch));
      const bool per_channel = blk.kind != BlockKind::kCoupling && blk.kind != BlockKind::kMode;
      if (per_channel && c.channels.empty())
        for (Index k = 0; k < static_cast<Index>(names.size()); ++k) c.channels.push_back(k);
      for (const std::string& q : blk.parameters) c.params.push_back(model.index_of(q));
      switch (blk.side) {
        case BlockSide::kBody: modes.push_back(std::move(c)); break;
        case BlockSide::kOutput: output_blocks.push_back(std::move(c)); break;
        case BlockSide::kInput:
          if (blk.kind == BlockKind::kDelay) {
            for (Index ch : c.channels) delays[static_cast<std::size_t>(ch)].push_back(c.params[0]);
          } else {
            input_blocks.push_back(std::move(c));
          }
          break;
      }
    }
  }
}

namespace {
Index chain_states(const std::vector<ModelLayout::CompiledBlock>& blocks) {
  Index n = 0;
  for (const auto& b : blocks) {
    if (b.kind == BlockKind::kFirstOrder) n += static_cast<Index>(b.channels.size());
    if (b.kind == BlockKind::kSecondOrder || b.kind == BlockKind::kResonance)
      n += 2 * static_cast<Index>(b.channels.size());
  }
  return n;
}
}  // namespace

Index ModelLayout::input_states() const { return chain_states(input_blocks); }
Index ModelLayout::output_states() const { return chain_states(output_blocks); }
bool ModelLayout::has_delay() const {
  for (const auto& d : delays)
    if (!d.empty()) return true;
  return false;
}

void check_schedule(const PhysicalModel& model, double schedule) {
  if (std::isnan(schedule)) {
    const BaseInfo& b = model.base_info();
    if (!b.schedule_name.empty())
      throw InputError(fmt::format("no {} given for a data set: base '{}' is scheduled by it; tag each data file "
                                   "FILE@VALUE (in {})",
                                   b.schedule_name, b.name, b.schedule_unit));
    return;  // a base without a scheduling variable needs none
  }
  if (const BaseInfo& b = model.base_info(); b.check_schedule) {
    b.check_schedule(model, schedule);
    return;
  }
  if (!std::isfinite(schedule)) throw InputError(fmt::format("operating point {} is not finite", schedule));
}

namespace {

void check_period(double sample_period_s) {
  if (!std::isfinite(sample_period_s) || sample_period_s < 0.0)
    throw InputError(fmt::format("sample period {} s: it must be 0 (continuous) or a positive number of seconds",
                                 sample_period_s));
}

[[noreturn]] void not_positive_definite(const PhysicalModel& model, double schedule) {
  throw InputError(fmt::format(
      "the mass matrix of base '{}' at {} {} is not positive definite; the centre-of-mass offsets or J_psitheta are "
      "too large for the inertias — check their values and units",
      model.base, schedule, model.base_info().schedule_unit));
}

}  // namespace

ModeMaps mode_maps(const PhysicalModel& model, double schedule) {
  const ModelLayout L(model);
  check_schedule(model, schedule);
  const Eigen::VectorXd p = model.values();
  Eigen::MatrixXd M, Dm, K, F;
  ModeMaps out;
  if (!base_matrices<double>(L, p.data(), schedule, M, Dm, K, out.Bw, F, out.Cq)) not_positive_definite(model, schedule);
  if (out.Cq.size() == 0) out.Cq = Eigen::MatrixXd::Identity(L.n_out, L.n_dof);
  out.output_derivative = L.mechanical ? L.mechanical->output_derivative : std::vector<int>(static_cast<std::size_t>(L.n_out), 0);
  return out;
}

PhysicalStateSpace physical_state_space(const PhysicalModel& model, double schedule, double sample_period_s) {
  const ModelLayout L(model);
  check_schedule(model, schedule);
  check_period(sample_period_s);
  const BaseInfo& b = model.base_info();
  const Eigen::VectorXd p = model.values();
  Eigen::MatrixXd A, B, C, D;
  if (!build_continuous<double>(L, p.data(), schedule, A, B, C, D)) not_positive_definite(model, schedule);
  PhysicalStateSpace out;
  out.input_delay_s = input_delays<double>(L, p.data());
  StateSpace& s = out.system;
  s.input_names = b.input_names;
  s.output_names = b.output_names;
  if (sample_period_s == 0.0) {
    s.A = A;
    s.B = B;
    s.C = C;
    s.D = D;
    return out;
  }
  const SampledModel<double> sm = sample_model<double>(A, B, C, D, out.input_delay_s, sample_period_s);
  const Index n = A.rows(), m = B.cols();
  Index L_reg = 0;  // registers: b_i = u[k − i], i = 1..L_reg
  for (Index j = 0; j < m; ++j) {
    L_reg = std::max(L_reg, sm.shift[static_cast<std::size_t>(j)] + (sm.fractional[static_cast<std::size_t>(j)] ? 1 : 0));
    out.delay_samples = std::max(out.delay_samples, sm.shift[static_cast<std::size_t>(j)]);
  }
  const Index N = n + L_reg * m;
  s.A = Eigen::MatrixXd::Zero(N, N);
  s.B = Eigen::MatrixXd::Zero(N, m);
  s.C = Eigen::MatrixXd::Zero(C.rows(), N);
  s.D = Eigen::MatrixXd::Zero(C.rows(), m);
  s.A.topLeftCorner(n, n) = sm.Ad;
  s.C.leftCols(n) = C;
  // x[k+1] += G u[k − lag] (lag 0: the input itself); y[k] += D_j u[k − lag_D]
  auto add_state_term = [&](Index j, Index lag, const Eigen::VectorXd& g) {
    if (lag == 0)
      s.B.block(0, j, n, 1) += g;
    else
      s.A.block(0, n + (lag - 1) * m + j, n, 1) += g;
  };
  for (Index j = 0; j < m; ++j) {
    const Index k = sm.shift[static_cast<std::size_t>(j)];
    const bool frac = sm.fractional[static_cast<std::size_t>(j)];
    add_state_term(j, k, sm.B_new.col(j));
    if (frac) add_state_term(j, k + 1, sm.B_old.col(j));
    const Index lag_d = k + (frac ? 1 : 0);
    if (lag_d == 0)
      s.D.col(j) = D.col(j);
    else
      s.C.block(0, n + (lag_d - 1) * m + j, C.rows(), 1) += D.col(j);
  }
  if (L_reg > 0) {
    s.B.block(n, 0, m, m).setIdentity();
    for (Index i = 1; i < L_reg; ++i) s.A.block(n + i * m, n + (i - 1) * m, m, m).setIdentity();
  }
  s.sample_period_s = sample_period_s;
  return out;
}

std::vector<Eigen::MatrixXcd> physical_response(const PhysicalModel& model, double schedule,
                                                const Eigen::VectorXd& omega_rad_s, double sample_period_s) {
  const ModelLayout L(model);
  check_schedule(model, schedule);
  check_period(sample_period_s);
  const Eigen::VectorXd p = model.values();
  Eigen::MatrixXd A, B, C, D;
  if (!build_continuous<double>(L, p.data(), schedule, A, B, C, D)) not_positive_definite(model, schedule);
  const std::vector<double> tau = input_delays<double>(L, p.data());
  const Index m = B.cols();
  std::optional<SampledModel<double>> sm;
  if (sample_period_s > 0.0) sm = sample_model<double>(A, B, C, D, tau, sample_period_s);
  std::vector<Eigen::MatrixXcd> out;
  out.reserve(static_cast<std::size_t>(omega_rad_s.size()));
  for (Index k = 0; k < omega_rad_s.size(); ++k) {
    const double w = omega_rad_s(k);
    if (!std::isfinite(w)) throw InputError(fmt::format("frequency {} rad/s is not finite", w));
    Eigen::MatrixXcd P;
    if (sm) {
      const Complex z = std::exp(Complex(0.0, w * sample_period_s));
      Eigen::MatrixXcd Z = -sm->Ad.cast<Complex>();
      Z.diagonal().array() += z;
      const Eigen::MatrixXcd Bz = sm->B_new.cast<Complex>() + sm->B_old.cast<Complex>() / z;
      P = C.cast<Complex>() * Z.partialPivLu().solve(Bz);
      for (Index j = 0; j < m; ++j) {
        const bool frac = sm->fractional[static_cast<std::size_t>(j)];
        P.col(j) += D.col(j).cast<Complex>() * (frac ? 1.0 / z : Complex(1.0));
        P.col(j) *= std::exp(Complex(0.0, -w * sample_period_s * static_cast<double>(sm->shift[static_cast<std::size_t>(j)])));
      }
    } else {
      Eigen::MatrixXcd Z = -A.cast<Complex>();
      Z.diagonal().array() += Complex(0.0, w);
      P = C.cast<Complex>() * Z.partialPivLu().solve(B.cast<Complex>()) + D.cast<Complex>();
      for (Index j = 0; j < m; ++j) P.col(j) *= std::exp(Complex(0.0, -w * tau[static_cast<std::size_t>(j)]));
    }
    out.push_back(std::move(P));
  }
  return out;
}

}  // namespace lpvid
