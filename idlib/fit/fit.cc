// lpvid — the frequency-domain fit of a physical model's parameters: a global start
// (BOBYQA on a subsample) then Levenberg–Marquardt on every line, and the statistics
// of the end point (covariance, identifiability, priors).  The response and its
// derivatives: fit_engine.cc; the data and the noise model: fit_data.cc.
#include "idlib/fit/fit.h"

#include <ceres/ceres.h>
#include <fmt/format.h>

#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <nlopt.hpp>
#include <optional>
#include <random>

#include "idlib/fit/fit_detail.h"

namespace lpvid {
namespace {

using fit_detail::channel_names;
using fit_detail::check_controller;
using fit_detail::CMat;
using fit_detail::Cx;
using fit_detail::Engine;
using fit_detail::kInf;
using fit_detail::kMaxFree;
using fit_detail::Prepared;
using fit_detail::prepare_all;
using fit_detail::PreparedAll;
using fit_detail::score_channels;
using fit_detail::subsample;

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
  // The response and its derivatives at every line, kept between calls: built anew
  // per call they were F x p fixed-capacity matrices (6 MB at the F-16's 267 lines and
  // 26 parameters) allocated and faulted in at every Jacobian, half of a diagnosis's time.
  std::vector<CMat> T = {};
  std::vector<std::vector<CMat>> dT = {};

  void set_z(const double* z) {
    for (Index q = 0; q < engine.num_free(); ++q)
      engine.full()(engine.free()[static_cast<std::size_t>(q)]) = coords.to_theta(q, z[q]);
  }

  // Residuals (and jac, row-major residuals × p, d r / d z) at z.
  bool residual(const double* z, double* r, double* jac) {
    set_z(z);
    const Index p = engine.num_free();
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
// The stages in the order run() takes them; each reads and writes the round's state
// (the coordinates z, the result).
class FitRound {
 public:
  FitRound(const PhysicalModel& start, const std::vector<FitDataset>& data, const FitOptions& options,
           const std::string& task)
      : start_(start), data_(data), options_(options), task_(task), t0_(std::chrono::steady_clock::now()),
        base_(checked_base(start, options)), engine_(start, options), p_(checked_free(engine_)),
        all_(prepare_all(start, data, options)), coords_(make_coordinates(start, engine_.free())),
        priors_(prior_rows(start, engine_.free())), data_residuals_(count_residuals(all_.sets)),
        full_{engine_, coords_, all_.sets, data_residuals_ + static_cast<Index>(priors_.size()), priors_} {
    if (!priors_.empty() && !all_.noise_known)
      throw InputError(fmt::format("parameter '{}' has a prior, which weighs against the data's noise, and the noise "
                                   "of the data is unknown; give the data's variance, or coherence with the number of "
                                   "averages, or a noise level",
                                   free_parameter(priors_.front().q).name));
    if (data_residuals_ <= p_)
      throw InputError(fmt::format("{} residuals for {} free parameters: give more (unflagged) frequencies",
                                   data_residuals_, p_));
  }

  FitResult run() {
    z_.resize(static_cast<std::size_t>(p_));
    for (Index q = 0; q < p_; ++q) z_[static_cast<std::size_t>(q)] = coords_.to_z(q, free_parameter(q).value);
    result_.noise_known = all_.noise_known;
    result_.noise_source = all_.noise_source;
    result_.cost_start = full_.cost(z_.data());
    const std::vector<std::vector<double>> extra = extra_starts();
    if (!std::isfinite(result_.cost_start)) usable_start(extra);
    global_start(extra);
    levenberg_marquardt();
    statistics();
    estimates();
    identifiability();
    // Per-channel figures at the estimate.
    full_.set_z(z_.data());
    score_channels(engine_, all_.sets, all_.noise_known, result_.channels, result_.error, result_.noise_floor);
    channel_names(data_, base_, options_.target, result_.output_names, result_.input_names);
    result_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
    return std::move(result_);
  }

 private:
  static const BaseInfo& checked_base(const PhysicalModel& start, const FitOptions& options) {
    options.validate();
    start.validate();
    const BaseInfo& base = start.base_info();
    check_controller(options, &base);
    return base;
  }

  static Index checked_free(const Engine& engine) {
    const Index p = engine.num_free();
    if (p == 0)
      throw InputError(
          "the model has no free parameter; free the ones to estimate (lpvid model set --model MODEL.json --free NAME)");
    if (p > kMaxFree)
      throw InputError(fmt::format("the model has {} free parameters; at most {} can be fitted at once — fix some", p,
                                   kMaxFree));
    return p;
  }

  const PhysicalParameter& free_parameter(Index q) const {
    return start_.parameters[static_cast<std::size_t>(engine_.free()[static_cast<std::size_t>(q)])];
  }

  // Extra starts: the start with the given values (checked before anything runs), and
  // the start with its parameters on a bound moved to their library defaults.
  std::vector<std::vector<double>> extra_starts() const {
    std::vector<std::vector<double>> extra;
    for (const auto& overrides : options_.extra_starts) {
      std::vector<double> x = z_;
      for (const auto& [name, value] : overrides) {
        const Index i = start_.index_of(name);
        if (i < 0) throw InputError(fmt::format("extra start: the model has no parameter '{}'", name));
        const auto it = std::find(engine_.free().begin(), engine_.free().end(), i);
        if (it == engine_.free().end()) continue;  // a fixed parameter keeps its value
        const Index q = it - engine_.free().begin();
        const auto& par = start_.parameters[static_cast<std::size_t>(i)];
        x[static_cast<std::size_t>(q)] = coords_.to_z(q, std::clamp(value, par.lower, par.upper));
      }
      extra.push_back(std::move(x));
    }
    // A start whose free parameters sit on their bounds (a previous fit that could not
    // follow the data, e.g. before the missing effect was added) is also started from
    // the library defaults of those parameters: from the distorted values the
    // parameters often stay in the wrong basin (measured on the stage: fit1's
    // inertia_yy = 1000 at its bound, `model add gap_dependence`, refit: 16.5 % from
    // the start, 2.95 % from the defaults).
    std::vector<double> x = z_;
    bool any = false;
    for (Index q = 0; q < p_; ++q) {
      const auto& par = free_parameter(q);
      const double span = par.upper - par.lower;
      if (!(span > 0) || (par.value - par.lower > 1e-9 * span && par.upper - par.value > 1e-9 * span)) continue;
      std::optional<double> fallback;
      for (const auto& b : base_.parameters)
        if (b.name == par.name) fallback = b.value;
      for (const std::string& e : start_.effects)
        for (const auto& ep : start_.effect_info(e)->parameters)
          if (ep.name == par.name) fallback = ep.value;
      if (fallback && *fallback > par.lower && *fallback < par.upper) {
        x[static_cast<std::size_t>(q)] = coords_.to_z(q, *fallback);
        any = true;
      }
    }
    if (any) extra.push_back(std::move(x));
    return extra;
  }

  // The start may be unusable while an extra start is fine.
  void usable_start(const std::vector<std::vector<double>>& extra) {
    double best = kInf;
    for (const auto& x : extra) {
      const double c = full_.cost(x.data());
      if (c < best) {
        best = c;
        z_ = x;
      }
    }
    if (!std::isfinite(best))
      throw NumericalError("the start model cannot be evaluated at every scheduling value (mass matrix not positive "
                           "definite or a non-finite response); change the start values");
    result_.cost_start = best;
  }

  // (1) Global start on a subsample, over the searched coordinates.
  void global_start(const std::vector<std::vector<double>>& extra) {
    result_.cost_global = result_.cost_start;
    std::vector<Index> searched;
    for (Index q = 0; q < p_; ++q) {
      const std::string& name = free_parameter(q).name;
      if (options_.global_parameters.empty() ||
          std::find(options_.global_parameters.begin(), options_.global_parameters.end(), name) !=
              options_.global_parameters.end())
        searched.push_back(q);
    }
    if (options_.global_start && !searched.empty()) {
      bobyqa_starts(searched, extra);
    } else if (!extra.empty()) {
      for (const auto& x : extra) {
        const double c = full_.cost(x.data());
        if (c < result_.cost_global) {
          result_.cost_global = c;
          z_ = x;
        }
      }
    }
  }

  void bobyqa_starts(const std::vector<Index>& searched, const std::vector<std::vector<double>>& extra) {
    std::vector<Prepared> sub;
    for (const auto& d : all_.sets) sub.push_back(subsample(d, options_.global_subsample));
    Problem coarse{engine_, coords_, sub, count_residuals(sub) + static_cast<Index>(priors_.size()), priors_};
    std::vector<double> lo(coords_.lower), hi(coords_.upper);
    for (Index q = 0; q < p_; ++q) {
      const auto s = static_cast<std::size_t>(q);
      const double half = coords_.log[s] ? std::log(options_.global_search_factor)
                                         : (coords_.upper[s] - coords_.lower[s]) / (2.0 * options_.global_search_factor);
      lo[s] = std::max(coords_.lower[s], z_[s] - half);
      hi[s] = std::min(coords_.upper[s], z_[s] + half);
    }
    std::mt19937 rng(options_.seed);
    std::vector<std::vector<double>> starts{z_};
    for (const auto& x : extra) starts.push_back(x);
    for (int k = 1; k < options_.global_starts; ++k) {
      std::vector<double> x = z_;
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
    std::vector<double> best = z_;
    double best_cost = coarse.cost(z_.data());
    std::vector<double> slo, shi;
    for (Index q : searched) {
      slo.push_back(coords_.lower[static_cast<std::size_t>(q)]);
      shi.push_back(coords_.upper[static_cast<std::size_t>(q)]);
    }
    for (std::size_t k = 0; k < starts.size(); ++k) {
      const std::vector<double>& x0 = starts[k];
      if (options_.progress != nullptr)
        options_.progress->report(
            {task_, "global start", static_cast<Index>(k + 1), static_cast<Index>(starts.size()), "", -1.0});
      Sub sb{&coarse, x0, &searched};
      std::vector<double> x;
      for (Index q : searched) x.push_back(x0[static_cast<std::size_t>(q)]);
      nlopt::opt opt(nlopt::LN_BOBYQA, static_cast<unsigned>(searched.size()));
      opt.set_lower_bounds(slo);
      opt.set_upper_bounds(shi);
      opt.set_min_objective(sub_objective, &sb);
      opt.set_maxeval(options_.global_max_evaluations);
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
    const double c = full_.cost(best.data());
    if (c < result_.cost_start) z_ = best;
    result_.cost_global = std::min(c, result_.cost_start);
  }

  // (2) Levenberg–Marquardt on all data.
  void levenberg_marquardt() {
    ceres::Problem::Options problem_options;
    problem_options.cost_function_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem cp(problem_options);
    cp.AddResidualBlock(new CeresCost(full_), nullptr, z_.data());
    for (Index q = 0; q < p_; ++q) {
      cp.SetParameterLowerBound(z_.data(), static_cast<int>(q), coords_.lower[static_cast<std::size_t>(q)]);
      cp.SetParameterUpperBound(z_.data(), static_cast<int>(q), coords_.upper[static_cast<std::size_t>(q)]);
    }
    ceres::Solver::Options so;
    so.minimizer_type = ceres::TRUST_REGION;
    so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = options_.max_iterations;
    so.function_tolerance = options_.function_tolerance;
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
    if (options_.progress != nullptr) {
      iteration_progress.emplace(options_.progress, task_);
      so.callbacks.push_back(&*iteration_progress);
    }
    ceres::Solver::Summary summary;
    ceres::Solve(so, &cp, &summary);
    if (!summary.IsSolutionUsable())
      throw NumericalError(fmt::format("the least-squares solver found no usable point: {}", summary.message));
    result_.iterations = static_cast<int>(summary.iterations.size());
    result_.report.termination = fmt::format("{} after {} iterations: {}",
                                             summary.termination_type == ceres::CONVERGENCE ? "converged" : "stopped",
                                             result_.iterations, summary.message);
    if (summary.termination_type != ceres::CONVERGENCE)
      result_.report.warnings.push_back("the solver stopped before convergence (" + summary.message +
                                        "); raise max_iterations or check the start");
  }

  // Residuals and Jacobian at the estimate, in natural units; σ², AIC, BIC, the
  // covariance and the correlations.
  void statistics() {
    const Index N = full_.residuals;
    const Index p = p_;
    std::vector<double> r(static_cast<std::size_t>(N)), jz(static_cast<std::size_t>(N * p));
    if (!full_.residual(z_.data(), r.data(), jz.data()))
      throw NumericalError("the model cannot be evaluated at the estimate; check the bounds of the centre-of-mass terms");
    Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> Jz(jz.data(), N, p);
    J_ = Jz;
    for (Index q = 0; q < p; ++q)
      if (coords_.log[static_cast<std::size_t>(q)]) J_.col(q) /= std::exp(z_[static_cast<std::size_t>(q)]);
    // The cost is the data's and the priors'; σ², AIC and BIC are the data's alone
    // (the same with and without priors for the same fit of the data).
    double ssr = 0.0, cost = 0.0;
    for (Index i = 0; i < N; ++i)
      (i < data_residuals_ ? ssr : cost) += r[static_cast<std::size_t>(i)] * r[static_cast<std::size_t>(i)];
    result_.cost_final = ssr + cost;
    result_.prior_cost = cost;
    result_.residual_count = data_residuals_;
    for (const auto& d : all_.sets) result_.frequencies_used += static_cast<Index>(d.omega.size());
    result_.sigma2 = ssr / static_cast<double>(data_residuals_ - p);
    const double n_d = static_cast<double>(data_residuals_);
    const double log_term = n_d * std::log(std::max(ssr, std::numeric_limits<double>::min()) / n_d);
    result_.aic = log_term + 2.0 * static_cast<double>(p);
    result_.bic = log_term + static_cast<double>(p) * std::log(n_d);

    // Covariance σ² (JᵀJ)⁺ via the SVD of J (relative cut 1e-12 of the largest singular value).
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(J_, Eigen::ComputeThinV);
    const Eigen::VectorXd sv = svd.singularValues();
    Eigen::VectorXd inv2 = Eigen::VectorXd::Zero(p);
    for (Index q = 0; q < p; ++q)
      if (sv(q) > 1e-12 * sv(0)) inv2(q) = 1.0 / (sv(q) * sv(q));
    // With priors (the noise is then known, the residuals in its units) the covariance
    // is the posterior's, (JᵀJ)⁺ over the data's and the priors' rows, inflated by σ²
    // only when the data scatter more than their noise says (σ² > 1): scaling the
    // priors' information by the data's σ² would make a ±1 % prior ±0.00001 % on
    // noise-free data.  Without priors, σ²(JᵀJ)⁺ as always.
    const double scale = priors_.empty() ? result_.sigma2 : std::max(result_.sigma2, 1.0);
    result_.covariance = scale * svd.matrixV() * inv2.asDiagonal() * svd.matrixV().transpose();
    result_.correlation = Eigen::MatrixXd::Zero(p, p);
    for (Index a = 0; a < p; ++a)
      for (Index b = 0; b < p; ++b) {
        const double den = std::sqrt(result_.covariance(a, a) * result_.covariance(b, b));
        result_.correlation(a, b) = den > 0.0 ? result_.covariance(a, b) / den : (a == b ? 1.0 : 0.0);
      }
  }

  // Estimates and the fitted model.
  void estimates() {
    result_.model = start_;
    for (Index q = 0; q < p_; ++q) {
      const auto s = static_cast<std::size_t>(q);
      auto& par = result_.model.parameters[static_cast<std::size_t>(engine_.free()[s])];
      ParameterEstimate e;
      e.name = par.name;
      e.unit = par.unit;
      e.start = par.value;
      e.lower = par.lower;
      e.upper = par.upper;
      e.estimate = coords_.to_theta(q, z_[s]);
      e.estimate = std::clamp(e.estimate, par.lower, par.upper);  // exp/log round trip at a bound
      par.value = e.estimate;
      e.std_error = std::sqrt(std::max(result_.covariance(q, q), 0.0));
      // At a bound: within 1e-6 of the parameter's span in its own coordinates.
      constexpr double kAtBound = 1e-6;
      const double span = std::max(coords_.upper[s] - coords_.lower[s], 1e-300);
      const bool at_lower = z_[s] - coords_.lower[s] <= kAtBound * span;
      const bool at_upper = coords_.upper[s] - z_[s] <= kAtBound * span;
      e.at_bound = at_lower || at_upper;
      if (e.at_bound)
        e.flags.push_back(fmt::format("at {} bound {:g}: the data want it beyond", at_lower ? "lower" : "upper",
                                      at_lower ? par.lower : par.upper));
      if (par.has_prior()) {
        e.prior_mean = par.prior_mean;
        e.prior_sigma = par.prior_sigma;
        const double pull = (e.estimate - par.prior_mean) / par.prior_sigma;
        if (std::abs(pull) > kPriorPullFlag) {
          ++result_.priors_contradicted;
          e.prior_contradicted = true;
          e.flags.push_back(
              fmt::format("{:+.1f} sigma from its prior {:g} ± {:g}", pull, par.prior_mean, par.prior_sigma));
          result_.report.warnings.push_back(fmt::format(
              "the data pull {} to {:.4g}, {:.1f} standard deviations from its prior {:g} ± {:g}: the design value or "
              "its uncertainty is wrong, or the model lacks an effect that this parameter is standing in for",
              par.name, e.estimate, std::abs(pull), par.prior_mean, par.prior_sigma));
        }
      }
      names_.push_back(par.name);
      result_.parameters.push_back(e);
    }
  }

  // Identifiability: scaled, column-normalised Jacobian.
  void identifiability() {
    const Index p = p_;
    Eigen::MatrixXd Js = J_;
    for (Index q = 0; q < p; ++q) {
      const auto& par = result_.model.parameters[static_cast<std::size_t>(engine_.free()[static_cast<std::size_t>(q)])];
      const double scale = par.value != 0.0 ? std::abs(par.value) : 0.01 * (par.upper - par.lower);
      Js.col(q) *= scale;
      const double nrm = Js.col(q).norm();
      if (nrm > 0.0) Js.col(q) /= nrm;
    }
    const Eigen::JacobiSVD<Eigen::MatrixXd> ssvd(Js, Eigen::ComputeThinV);
    result_.singular_values = ssvd.singularValues() / std::max(ssvd.singularValues()(0), 1e-300);
    for (Index q = 0; q < p; ++q) {
      if (result_.singular_values(q) >= options_.singular_value_flag) continue;
      const std::string combo = format_combination(ssvd.matrixV().col(q), names_);
      result_.identifiability.push_back(
          fmt::format("the data cannot separate the direction {} (relative singular value {:.1e}): fix one of these "
                      "parameters or add data that moves it",
                      combo, result_.singular_values(q)));
      for (Index a = 0; a < p; ++a)
        if (std::abs(ssvd.matrixV()(a, q)) >= 0.2)
          result_.parameters[static_cast<std::size_t>(a)].flags.push_back("inseparable: " + combo);
    }
    for (Index a = 0; a < p; ++a)
      for (Index b = a + 1; b < p; ++b)
        if (std::abs(result_.correlation(a, b)) > options_.correlation_flag) {
          result_.identifiability.push_back(
              fmt::format("{} and {} are correlated ({:+.3f}): the data hardly separate them",
                          names_[static_cast<std::size_t>(a)], names_[static_cast<std::size_t>(b)],
                          result_.correlation(a, b)));
          result_.parameters[static_cast<std::size_t>(a)].flags.push_back(
              fmt::format("corr {:+.3f} with {}", result_.correlation(a, b), names_[static_cast<std::size_t>(b)]));
          result_.parameters[static_cast<std::size_t>(b)].flags.push_back(
              fmt::format("corr {:+.3f} with {}", result_.correlation(a, b), names_[static_cast<std::size_t>(a)]));
        }
    for (const ParameterEstimate& e : result_.parameters)
      if (e.at_bound)
        result_.report.warnings.push_back(
            fmt::format("{} ended on its {} bound: the model cannot follow the data there within its physical range",
                        e.name, std::abs(e.estimate - e.lower) <= std::abs(e.upper - e.estimate) ? "lower" : "upper"));
  }

  const PhysicalModel& start_;
  const std::vector<FitDataset>& data_;
  const FitOptions& options_;
  const std::string& task_;
  const std::chrono::steady_clock::time_point t0_;
  const BaseInfo& base_;
  Engine engine_;
  const Index p_;
  const PreparedAll all_;
  const Coordinates coords_;
  const std::vector<PriorRow> priors_;
  const Index data_residuals_;
  Problem full_;
  std::vector<double> z_;
  FitResult result_;
  Eigen::MatrixXd J_;               // the Jacobian at the estimate, natural units (statistics)
  std::vector<std::string> names_;  // the free parameters' names (estimates)
};

FitResult fit_round(const PhysicalModel& start, const std::vector<FitDataset>& data, const FitOptions& options,
                    const std::string& task) {
  return FitRound(start, data, options, task).run();
}

// One fit: the first round, then rounds from the estimate while they lower the cost
// (FitOptions::restarts).
FitResult fit_with_restarts(const PhysicalModel& start, const std::vector<FitDataset>& data,
                            const FitOptions& options) {
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
  return r;
}

}  // namespace

FitResult fit_physical_model(const PhysicalModel& start, const std::vector<FitDataset>& data,
                             const FitOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  FitResult r = fit_with_restarts(start, data, options);
  // Weights when the model fails (FitOptions::model_error_weighting): the model error
  // λ = sqrt(error² − floor²) joins the noise in the weights, and the fit runs again
  // from the estimate until λ moves by less than kModelErrorSettled of itself.
  if (options.model_error_weighting && r.noise_known && std::isfinite(r.noise_floor) &&
      r.error > kModelErrorRatio * r.noise_floor) {
    const double first = r.error;
    std::vector<double> starts;
    for (const ParameterEstimate& e : r.parameters) starts.push_back(e.start);
    FitResult best = r;
    FitOptions weighted = options;
    double lambda = std::sqrt(r.error * r.error - r.noise_floor * r.noise_floor);
    int rounds = 0;
    while (rounds < kModelErrorRounds) {
      weighted.noise.model_error = lambda;
      FitResult next;
      try {
        next = fit_with_restarts(r.model, data, weighted);
      } catch (const NumericalError&) {
        break;  // the fits that ended stand
      }
      ++rounds;
      next.model_error_weight = lambda;
      next.iterations += r.iterations;
      r = std::move(next);
      if (r.error < best.error) best = r;
      const double next_lambda = std::sqrt(std::max(0.0, r.error * r.error - r.noise_floor * r.noise_floor));
      const bool settled = std::abs(next_lambda - lambda) <= kModelErrorSettled * lambda;
      lambda = next_lambda;
      if (settled || !(r.error > kModelErrorRatio * r.noise_floor)) break;
    }
    r = std::move(best);
    r.noise_weighted_error = first;
    r.reweightings = rounds;
    // the starts reported stay the user's
    for (std::size_t k = 0; k < r.parameters.size() && k < starts.size(); ++k) r.parameters[k].start = starts[k];
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

}  // namespace lpvid
