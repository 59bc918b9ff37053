#include "idlib/fit/fit.h"

#include <ceres/ceres.h>
#include <ceres/jet.h>
#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <chrono>
#include <cmath>
#include <limits>
#include <nlopt.hpp>
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

// A data set ready for evaluation.
struct Prepared {
  double xb = 0.0;
  std::vector<double> omega;               // used frequencies only
  std::vector<Eigen::Matrix3cd> data;      // T̂ at those
  std::vector<Eigen::Matrix3cd> ctrl;      // C(λ) (G/S targets)
  std::vector<Eigen::Matrix3d> weight;     // w_ij / s_ij
  std::vector<Eigen::Matrix3d> inv_scale;  // 1 / s_ij
};

// Everything needed to evaluate the target response and its derivatives.
class Engine {
 public:
  Engine(const PhysicalModel& model, const FitOptions& options)
      : model_(model), layout_(model), options_(options), full_(model.values()), free_(model.free_indices()) {}

  Index num_free() const { return static_cast<Index>(free_.size()); }
  const std::vector<Index>& free() const { return free_; }
  Eigen::VectorXd& full() { return full_; }

  // T at the prepared frequencies, and when dT != nullptr its derivatives
  // (dT[k][q] = ∂T(ω_k)/∂θ_free(q)).  Returns false when the model cannot be
  // evaluated (M not positive definite).
  bool evaluate(const Prepared& d, std::vector<Eigen::Matrix3cd>& T,
                std::vector<std::vector<Eigen::Matrix3cd>>* dT) const {
    const Index p = num_free();
    if (dT == nullptr) return evaluate_impl<0>(d, T, nullptr);
    if (p <= 8) return evaluate_impl<8>(d, T, dT);
    if (p <= 16) return evaluate_impl<16>(d, T, dT);
    return evaluate_impl<32>(d, T, dT);
  }

 private:
  template <int N>
  bool evaluate_impl(const Prepared& d, std::vector<Eigen::Matrix3cd>& T,
                     std::vector<std::vector<Eigen::Matrix3cd>>* dT) const {
    const Index p = num_free();
    Eigen::MatrixXd A, B, C, D;
    std::vector<Eigen::MatrixXd> dA, dB, dC, dD;
    const double ts = options_.sample_period_s;
    if constexpr (N == 0) {
      if (!build_continuous<double>(layout_, full_.data(), d.xb, A, B, C, D)) return false;
      if (ts > 0.0) {
        Eigen::MatrixXd Ad, Bd;
        zoh_discretize<double>(A, B, ts, Ad, Bd);
        A = Ad;
        B = Bd;
      }
    } else {
      using J = ceres::Jet<double, N>;
      std::vector<J> x(static_cast<std::size_t>(full_.size()));
      for (Index i = 0; i < full_.size(); ++i) x[static_cast<std::size_t>(i)] = J(full_(i));
      for (Index q = 0; q < p; ++q) x[static_cast<std::size_t>(free_[static_cast<std::size_t>(q)])].v[q] = 1.0;
      MatrixT<J> Aj, Bj, Cj, Dj;
      if (!build_continuous<J>(layout_, x.data(), d.xb, Aj, Bj, Cj, Dj)) return false;
      if (ts > 0.0) {
        MatrixT<J> Ad, Bd;
        zoh_discretize<J>(Aj, Bj, ts, Ad, Bd);
        Aj = Ad;
        Bj = Bd;
      }
      auto split = [p](const MatrixT<J>& m, Eigen::MatrixXd& v, std::vector<Eigen::MatrixXd>& dv) {
        v.resize(m.rows(), m.cols());
        dv.assign(static_cast<std::size_t>(p), Eigen::MatrixXd(m.rows(), m.cols()));
        for (Index i = 0; i < m.rows(); ++i)
          for (Index j = 0; j < m.cols(); ++j) {
            v(i, j) = m(i, j).a;
            for (Index q = 0; q < p; ++q) dv[static_cast<std::size_t>(q)](i, j) = m(i, j).v[q];
          }
      };
      split(Aj, A, dA);
      split(Bj, B, dB);
      split(Cj, C, dC);
      split(Dj, D, dD);
    }
    const double tau = layout_.delay >= 0 ? full_(layout_.delay) : 0.0;
    Index tau_free = -1;
    for (Index q = 0; q < p; ++q)
      if (free_[static_cast<std::size_t>(q)] == layout_.delay) tau_free = q;
    const Index n = A.rows();
    const std::size_t F = d.omega.size();
    T.resize(F);
    if (dT != nullptr) dT->resize(F);

    // Modal route: A = V diag(μ) V⁻¹, so (λI − A)⁻¹ = V diag(1/(λ − μ)) V⁻¹ and
    // every frequency costs O(n·9) (plus O(n²·9) per parameter for the
    // derivatives) instead of a complex LU.  Used when cond(V) (Frobenius
    // estimate) is below kMaxModalCondition, so that round-off stays below
    // ~1e-16·1e6 = 1e-10 relative; otherwise (near-defective A, e.g. repeated
    // lag poles) the per-frequency LU route below.
    constexpr double kMaxModalCondition = 1e6;
    using CxN = Eigen::Matrix<Cx, Eigen::Dynamic, Eigen::Dynamic, 0, 16, 16>;
    using Cx3N = Eigen::Matrix<Cx, 3, Eigen::Dynamic, 0, 3, 16>;
    using CxN3 = Eigen::Matrix<Cx, Eigen::Dynamic, 3, 0, 16, 3>;
    bool modal = n <= 16;
    Eigen::VectorXcd mu;
    Cx3N Ch;
    CxN3 Bh;
    std::vector<CxN> dAh;
    std::vector<CxN3> dBh;
    std::vector<Cx3N> dCh;
    if (modal) {
      const Eigen::EigenSolver<Eigen::MatrixXd> es(A);
      modal = es.info() == Eigen::Success;
      if (modal) {
        const Eigen::MatrixXcd V = es.eigenvectors();
        const Eigen::MatrixXcd Vinv = V.partialPivLu().inverse();
        modal = Vinv.allFinite() && V.norm() * Vinv.norm() < kMaxModalCondition;
        if (modal) {
          mu = es.eigenvalues();
          Ch = C.cast<Cx>() * V;
          Bh = Vinv * B.cast<Cx>();
          if (dT != nullptr)
            for (Index q = 0; q < p; ++q) {
              const auto s = static_cast<std::size_t>(q);
              dAh.push_back(Vinv * dA[s].cast<Cx>() * V);
              dBh.push_back(Vinv * dB[s].cast<Cx>());
              dCh.push_back(dC[s].cast<Cx>() * V);
            }
        }
      }
    }
    const Eigen::MatrixXcd Ac = A.cast<Cx>(), Bc = B.cast<Cx>(), Cc = C.cast<Cx>();
    const Eigen::Matrix3cd Dc = D.cast<Cx>();
    Eigen::MatrixXcd Z(n, n);
    Cx3N Chd(3, n);
    CxN3 Bhd(n, 3);
    for (std::size_t k = 0; k < F; ++k) {
      const double w = d.omega[k];
      const Cx lambda = ts > 0.0 ? std::exp(Cx(0.0, w * ts)) : Cx(0.0, w);
      const Cx f = std::exp(Cx(0.0, -w * tau));
      Eigen::Matrix3cd P;
      Eigen::MatrixXcd X, Y;
      if (modal) {
        for (Index a = 0; a < n; ++a) {
          const Cx da = 1.0 / (lambda - mu(a));
          Chd.col(a) = Ch.col(a) * da;
          Bhd.row(a) = Bh.row(a) * da;
        }
        P = (Ch * Bhd + Dc) * f;
      } else {
        Z = -Ac;
        Z.diagonal().array() += lambda;
        const Eigen::PartialPivLU<Eigen::MatrixXcd> lu(Z);
        if (dT == nullptr) {
          X = lu.solve(Bc);
        } else {
          const Eigen::MatrixXcd R = lu.inverse();
          X = R * Bc;
          Y = Cc * R;
        }
        P = (Cc * X + Dc) * f;
      }
      // The target and its sensitivity to P: dT = Lm dP Rm.
      Eigen::Matrix3cd Lm = Eigen::Matrix3cd::Identity(), Rm = Eigen::Matrix3cd::Identity();
      switch (options_.target) {
        case FitTarget::kPlant:
          T[k] = P;
          break;
        case FitTarget::kClosedLoopOutput: {
          const Eigen::Matrix3cd S = (Eigen::Matrix3cd::Identity() + d.ctrl[k] * P).inverse();
          T[k] = P * S;
          Lm = Eigen::Matrix3cd::Identity() - T[k] * d.ctrl[k];
          Rm = S;
          break;
        }
        case FitTarget::kInputSensitivity: {
          const Eigen::Matrix3cd S = (Eigen::Matrix3cd::Identity() + d.ctrl[k] * P).inverse();
          T[k] = S;
          Lm = -S * d.ctrl[k];
          Rm = S;
          break;
        }
      }
      if (dT == nullptr) continue;
      auto& out = (*dT)[k];
      out.resize(static_cast<std::size_t>(p));
      for (Index q = 0; q < p; ++q) {
        const auto s = static_cast<std::size_t>(q);
        Eigen::Matrix3cd dP;
        if (modal) {
          dP = (Chd * (dAh[s] * Bhd) + Chd * dBh[s] + dCh[s] * Bhd + dD[s].cast<Cx>()) * f;
        } else {
          dP = (Y * (dA[s].cast<Cx>() * X) + Y * dB[s].cast<Cx>() + dC[s].cast<Cx>() * X + dD[s].cast<Cx>()) * f;
        }
        if (q == tau_free) dP += Cx(0.0, -w) * P;
        out[s] = Lm * dP * Rm;
      }
    }
    return true;
  }

  const PhysicalModel& model_;
  ModelLayout layout_;
  const FitOptions& options_;
  Eigen::VectorXd full_;
  std::vector<Index> free_;
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

struct Problem {
  Engine& engine;
  const Coordinates& coords;
  const std::vector<Prepared>& sets;
  Index residuals = 0;

  void set_z(const double* z) {
    for (Index q = 0; q < engine.num_free(); ++q)
      engine.full()(engine.free()[static_cast<std::size_t>(q)]) = coords.to_theta(q, z[q]);
  }

  // Residuals (and jac, row-major residuals × p, d r / d z) at z.
  bool residual(const double* z, double* r, double* jac) {
    set_z(z);
    const Index p = engine.num_free();
    std::vector<Eigen::Matrix3cd> T;
    std::vector<std::vector<Eigen::Matrix3cd>> dT;
    Index row = 0;
    for (const Prepared& d : sets) {
      if (!engine.evaluate(d, T, jac != nullptr ? &dT : nullptr)) return false;
      for (std::size_t k = 0; k < d.omega.size(); ++k)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
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
    return true;
  }

  double cost(const double* z) {
    std::vector<double> r(static_cast<std::size_t>(residuals));
    if (!residual(z, r.data(), nullptr)) return std::numeric_limits<double>::infinity();
    double c = 0.0;
    for (double x : r) c += x * x;
    return std::isfinite(c) ? c : std::numeric_limits<double>::infinity();
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
  for (const auto& d : sets) n += static_cast<Index>(d.omega.size()) * 18;
  return n;
}

std::vector<Eigen::Matrix3cd> controller_at(const StateSpace& c, const std::vector<double>& omega) {
  Eigen::VectorXd w(static_cast<Index>(omega.size()));
  for (std::size_t k = 0; k < omega.size(); ++k) w(static_cast<Index>(k)) = omega[k];
  const auto r = evaluate_response(c, w);
  std::vector<Eigen::Matrix3cd> out;
  for (const auto& m : r) out.emplace_back(m);
  return out;
}

void check_controller(const FitOptions& o) {
  if (o.target == FitTarget::kPlant) return;
  if (!o.controller)
    throw InputError(fmt::format("target {} needs the controller C (e = -q -> u_c); give it (--controller C.json)",
                                 target_name(o.target)));
  o.controller->validate();
  if (o.controller->num_inputs() != 3 || o.controller->num_outputs() != 3)
    throw InputError(fmt::format("the controller has {} inputs and {} outputs; the platform's needs 3 and 3",
                                 o.controller->num_inputs(), o.controller->num_outputs()));
}

Prepared prepare(const FitDataset& ds, const PhysicalModel& model, const FitOptions& o) {
  const FrequencyResponse& f = ds.response;
  if (f.num_frequencies() == 0 || f.response.size() != static_cast<std::size_t>(f.num_frequencies()))
    throw InputError(fmt::format("{}: no frequencies (or as many responses as frequencies are missing); give FRD data",
                                 ds.label));
  if (f.num_outputs() != 3 || f.num_inputs() != 3)
    throw InputError(fmt::format("{}: the response is {}×{}; the platform's is 3×3 (psi theta z × T_psi T_theta F_z)",
                                 ds.label, f.num_outputs(), f.num_inputs()));
  check_beam_position(model, ds.beam_position_m);
  Prepared d;
  d.xb = ds.beam_position_m;
  // Scale per channel: sqrt(|T̂_ii||T̂_jj|), floored (see header).
  const Index F = f.num_frequencies();
  double largest = 0.0;
  for (Index k = 0; k < F; ++k) {
    const double w = f.omega_rad_s(k);
    if (!std::isfinite(w) || !(w > 0.0))
      throw InputError(fmt::format("{}: frequency {} rad/s; frequencies must be finite and > 0", ds.label, w));
    if (!f.response[static_cast<std::size_t>(k)].allFinite())
      throw InputError(fmt::format("{}: a response value at {} rad/s is not finite", ds.label, w));
    for (int i = 0; i < 3; ++i) largest = std::max(largest, std::abs(f.response[static_cast<std::size_t>(k)](i, i)));
  }
  for (Index k = 0; k < F; ++k) {
    if (!f.flagged.empty() && f.flagged[static_cast<std::size_t>(k)]) continue;
    const Eigen::Matrix3cd m = f.response[static_cast<std::size_t>(k)];
    Eigen::Matrix3d inv_scale, weight;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const double s = std::max(std::sqrt(std::abs(m(i, i)) * std::abs(m(j, j))), o.scale_floor * largest);
        inv_scale(i, j) = s > 0.0 ? 1.0 / s : 0.0;
        double w = 1.0;
        if (!f.coherence.empty()) {
          const double g2 = std::clamp(f.coherence[static_cast<std::size_t>(k)](i, j), 0.0, 1.0);
          // Coherence 1 is capped at the weight of γ² = 1 − 1e-4 (a finite weight).
          w = std::sqrt(g2 / std::max(1.0 - g2, 1e-4));
        }
        weight(i, j) = w * inv_scale(i, j);
      }
    d.omega.push_back(f.omega_rad_s(k));
    d.data.push_back(m);
    d.inv_scale.push_back(inv_scale);
    d.weight.push_back(weight);
  }
  if (o.target != FitTarget::kPlant) d.ctrl = controller_at(*o.controller, d.omega);
  return d;
}

Prepared subsample(const Prepared& d, int count) {
  const std::size_t F = d.omega.size();
  if (static_cast<std::size_t>(count) >= F) return d;
  Prepared s;
  s.xb = d.xb;
  // Evenly spaced indices over the (log-spaced, typically) grid.
  for (int i = 0; i < count; ++i) {
    const auto k = static_cast<std::size_t>(std::llround(static_cast<double>(i) * static_cast<double>(F - 1) /
                                                         static_cast<double>(count - 1)));
    s.omega.push_back(d.omega[k]);
    s.data.push_back(d.data[k]);
    s.weight.push_back(d.weight[k]);
    s.inv_scale.push_back(d.inv_scale[k]);
    if (!d.ctrl.empty()) s.ctrl.push_back(d.ctrl[k]);
  }
  return s;
}

double nlopt_objective(unsigned n, const double* x, double* grad, void* data) {
  (void)n;
  (void)grad;  // BOBYQA is derivative-free
  return static_cast<Problem*>(data)->cost(x);
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

void FitOptions::validate() const {
  auto bad = [](const char* name, double v, const char* rule) {
    throw InputError(fmt::format("fit option {} = {}: {}", name, v, rule));
  };
  if (!std::isfinite(sample_period_s) || sample_period_s < 0) bad("sample_period_s", sample_period_s, "must be >= 0");
  if (global_starts < 1) bad("global_starts", global_starts, "must be >= 1");
  if (!(global_search_factor > 1.0) || !std::isfinite(global_search_factor))
    bad("global_search_factor", global_search_factor, "must be finite and > 1");
  if (global_subsample < 2) bad("global_subsample", global_subsample, "must be >= 2");
  if (global_max_evaluations < 10) bad("global_max_evaluations", global_max_evaluations, "must be >= 10");
  if (max_iterations < 1) bad("max_iterations", max_iterations, "must be >= 1");
  if (!(function_tolerance > 0.0) || !(function_tolerance < 1.0))
    bad("function_tolerance", function_tolerance, "must be in (0, 1)");
  if (!(scale_floor > 0.0) || !(scale_floor < 1.0)) bad("scale_floor", scale_floor, "must be in (0, 1)");
  if (!(correlation_flag > 0.0) || !(correlation_flag <= 1.0))
    bad("correlation_flag", correlation_flag, "must be in (0, 1]");
  if (!(singular_value_flag > 0.0) || !(singular_value_flag < 1.0))
    bad("singular_value_flag", singular_value_flag, "must be in (0, 1)");
  check_controller(*this);
}

FitResult fit_physical_model(const PhysicalModel& start, const std::vector<FitDataset>& data,
                             const FitOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  options.validate();
  start.validate();
  if (data.empty()) throw InputError("no data to fit; give at least one response with its beam position");
  Engine engine(start, options);
  const Index p = engine.num_free();
  if (p == 0) throw InputError("the model has no free parameter; set \"free\": true on the parameters to estimate");
  if (p > 32)
    throw InputError(fmt::format("the model has {} free parameters; at most 32 can be fitted at once — fix some", p));
  std::vector<Prepared> sets;
  for (const auto& ds : data) sets.push_back(prepare(ds, start, options));
  const Coordinates coords = make_coordinates(start, engine.free());
  Problem full{engine, coords, sets, count_residuals(sets)};
  if (full.residuals <= p)
    throw InputError(fmt::format("{} residuals for {} free parameters: give more (unflagged) frequencies", full.residuals,
                                 p));

  std::vector<double> z(static_cast<std::size_t>(p));
  for (Index q = 0; q < p; ++q)
    z[static_cast<std::size_t>(q)] =
        coords.to_z(q, start.parameters[static_cast<std::size_t>(engine.free()[static_cast<std::size_t>(q)])].value);
  FitResult result;
  result.cost_start = full.cost(z.data());
  if (!std::isfinite(result.cost_start))
    throw NumericalError("the start model cannot be evaluated at every x_b (mass matrix not positive definite or a "
                         "non-finite response); change the start values");

  // (1) Global start on a subsample.
  result.cost_global = result.cost_start;
  if (options.global_start) {
    std::vector<Prepared> sub;
    for (const auto& d : sets) sub.push_back(subsample(d, options.global_subsample));
    Problem coarse{engine, coords, sub, count_residuals(sub)};
    std::vector<double> lo(coords.lower), hi(coords.upper);
    for (Index q = 0; q < p; ++q) {
      const auto s = static_cast<std::size_t>(q);
      const double half = coords.log[s] ? std::log(options.global_search_factor)
                                        : (coords.upper[s] - coords.lower[s]) / (2.0 * options.global_search_factor);
      lo[s] = std::max(coords.lower[s], z[s] - half);
      hi[s] = std::min(coords.upper[s], z[s] + half);
    }
    std::mt19937 rng(options.seed);
    std::vector<double> best = z;
    double best_cost = coarse.cost(z.data());
    for (int k = 0; k < options.global_starts; ++k) {
      std::vector<double> x = z;
      if (k > 0)
        for (std::size_t s = 0; s < x.size(); ++s)
          x[s] = std::uniform_real_distribution<double>(lo[s], hi[s])(rng);
      nlopt::opt opt(nlopt::LN_BOBYQA, static_cast<unsigned>(p));
      opt.set_lower_bounds(coords.lower);
      opt.set_upper_bounds(coords.upper);
      opt.set_min_objective(nlopt_objective, &coarse);
      opt.set_maxeval(options.global_max_evaluations);
      opt.set_xtol_rel(1e-6);
      // Initial trust region: a quarter of the search box per coordinate.
      std::vector<double> step(x.size());
      for (std::size_t s = 0; s < x.size(); ++s) step[s] = std::max(0.25 * (hi[s] - lo[s]), 1e-12);
      opt.set_initial_step(step);
      double f = std::numeric_limits<double>::infinity();
      try {
        opt.optimize(x, f);
      } catch (const std::exception&) {
        f = coarse.cost(x.data());  // roundoff-limited or forced stop: keep the point reached
      }
      if (f < best_cost) {
        best_cost = f;
        best = x;
      }
    }
    const double c = full.cost(best.data());
    if (c < result.cost_start) z = best;
    result.cost_global = std::min(c, result.cost_start);
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
  double ssr = 0.0;
  for (double x : r) ssr += x * x;
  result.cost_final = ssr;
  result.residual_count = N;
  result.sigma2 = ssr / static_cast<double>(N - p);
  const double n_d = static_cast<double>(N);
  const double log_term = n_d * std::log(std::max(ssr, std::numeric_limits<double>::min()) / n_d);
  result.aic = log_term + 2.0 * static_cast<double>(p);
  result.bic = log_term + static_cast<double>(p) * std::log(n_d);

  // Covariance σ² (JᵀJ)⁺ via the SVD of J (relative cut 1e-12 of the largest singular value).
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(J, Eigen::ComputeThinV);
  const Eigen::VectorXd sv = svd.singularValues();
  Eigen::VectorXd inv2 = Eigen::VectorXd::Zero(p);
  for (Index q = 0; q < p; ++q)
    if (sv(q) > 1e-12 * sv(0)) inv2(q) = 1.0 / (sv(q) * sv(q));
  result.covariance = result.sigma2 * svd.matrixV() * inv2.asDiagonal() * svd.matrixV().transpose();
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
    e.estimate = coords.to_theta(q, z[s]);
    e.estimate = std::clamp(e.estimate, par.lower, par.upper);  // exp/log round trip at a bound
    par.value = e.estimate;
    e.std_error = std::sqrt(std::max(result.covariance(q, q), 0.0));
    const double span = std::max(par.upper - par.lower, 1e-300);
    e.at_bound = std::abs(e.estimate - par.lower) <= 1e-9 * span || std::abs(e.estimate - par.upper) <= 1e-9 * span;
    if (e.at_bound) e.flags.push_back("at bound");
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

  // Per-channel figures at the estimate.
  full.set_z(z.data());
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) result.channels.push_back(ChannelFit{i, j, 0.0, {}});
  std::vector<double> pooled_sum(9, 0.0);
  Index pooled_count = 0;
  for (const Prepared& d : sets) {
    std::vector<Eigen::Matrix3cd> T;
    engine.evaluate(d, T, nullptr);
    for (int c = 0; c < 9; ++c) {
      const int i = c / 3, j = c % 3;
      double sum = 0.0;
      for (std::size_t k = 0; k < d.omega.size(); ++k)
        sum += std::norm((T[k](i, j) - d.data[k](i, j)) * d.inv_scale[k](i, j));
      pooled_sum[static_cast<std::size_t>(c)] += sum;
      result.channels[static_cast<std::size_t>(c)].per_dataset.push_back(
          std::sqrt(sum / static_cast<double>(std::max<std::size_t>(d.omega.size(), 1))));
    }
    pooled_count += static_cast<Index>(d.omega.size());
  }
  for (int c = 0; c < 9; ++c)
    result.channels[static_cast<std::size_t>(c)].relative_rms_error =
        std::sqrt(pooled_sum[static_cast<std::size_t>(c)] / static_cast<double>(std::max<Index>(pooled_count, 1)));
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

FrequencyResponse target_response(const PhysicalModel& model, double beam_position_m,
                                  const Eigen::VectorXd& omega_rad_s, const FitOptions& options) {
  return response_band(model, Eigen::MatrixXd(), beam_position_m, omega_rad_s, options).response;
}

ResponseBand response_band(const PhysicalModel& model, const Eigen::MatrixXd& covariance, double beam_position_m,
                           const Eigen::VectorXd& omega_rad_s, const FitOptions& options) {
  options.validate();
  model.validate();
  check_beam_position(model, beam_position_m);
  Engine engine(model, options);
  const Index p = engine.num_free();
  const bool bands = covariance.size() > 0;
  if (bands && (covariance.rows() != p || covariance.cols() != p))
    throw InputError(fmt::format("covariance is {}×{}; the model has {} free parameters", covariance.rows(),
                                 covariance.cols(), p));
  if (bands && p > 32) throw InputError("at most 32 free parameters");
  Prepared d;
  d.xb = beam_position_m;
  for (Index k = 0; k < omega_rad_s.size(); ++k) {
    if (!std::isfinite(omega_rad_s(k))) throw InputError("a frequency is not finite");
    d.omega.push_back(omega_rad_s(k));
  }
  if (options.target != FitTarget::kPlant) d.ctrl = controller_at(*options.controller, d.omega);
  std::vector<Eigen::Matrix3cd> T;
  std::vector<std::vector<Eigen::Matrix3cd>> dT;
  if (!engine.evaluate(d, T, bands && p > 0 ? &dT : nullptr))
    throw InputError(fmt::format("the mass matrix at x_b = {} m is not positive definite; check the model", beam_position_m));
  ResponseBand out;
  out.response.omega_rad_s = omega_rad_s;
  const bool plant = options.target == FitTarget::kPlant;
  out.response.input_names = plant ? std::vector<std::string>{"T_psi", "T_theta", "F_z"}
                                   : std::vector<std::string>{"v_psi", "v_theta", "v_z"};
  out.response.output_names = options.target == FitTarget::kInputSensitivity
                                  ? std::vector<std::string>{"u_psi", "u_theta", "u_z"}
                                  : std::vector<std::string>{"psi", "theta", "z"};
  for (std::size_t k = 0; k < T.size(); ++k) {
    out.response.response.emplace_back(T[k]);
    Eigen::Matrix3d sm = Eigen::Matrix3d::Zero(), sp = Eigen::Matrix3d::Zero();
    if (bands && p > 0) {
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
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
