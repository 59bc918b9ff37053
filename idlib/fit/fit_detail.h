// lpvid — what the frequency-domain fit's three files share (internal to idlib/fit):
//   fit_engine.cc  the target response and its derivatives at the data's frequencies
//                  (Engine: the base's matrices as Jets, then modal/Schur/LU per line);
//   fit_data.cc    the data made ready (noise model, band, controller lines), the
//                  per-channel score, the response with its bands;
//   fit.cc         the optimisation (global start, Levenberg–Marquardt) and the
//                  statistics of its end point (covariance, identifiability).
#pragma once

#include <Eigen/Core>
#include <complex>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/fit/fit.h"
#include "idlib/physical/evaluate.h"

namespace lpvid::fit_detail {

using Cx = Complex;
constexpr int kMaxDim = 6;  // largest base (inputs/outputs); fixed capacity, no heap per frequency
using CMat = Eigen::Matrix<Cx, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDim, kMaxDim>;
using RMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDim, kMaxDim>;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// The largest number of free parameters a fit (and a response band) takes: the
// derivatives go kLanes at a time, so this bounds the work, not an instantiation.
constexpr Index kMaxFree = 48;

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
std::pair<Index, Index> target_shape(const BaseInfo& b, FitTarget t);

// Everything needed to evaluate the target response and its derivatives (fit_engine.cc).
class Engine {
 public:
  Engine(const PhysicalModel& model, const FitOptions& options);

  Index num_free() const { return static_cast<Index>(free_.size()); }
  const std::vector<Index>& free() const { return free_; }
  Eigen::VectorXd& full() { return full_; }
  const ModelLayout& layout() const { return layout_; }

  // T at the prepared frequencies, and when dT != nullptr its derivatives
  // (dT[k][q] = ∂T(ω_k)/∂θ_free(q)).  Returns false when the model cannot be
  // evaluated (mass matrix not positive definite, non-finite response).
  bool evaluate(const Prepared& d, std::vector<CMat>& T, std::vector<std::vector<CMat>>* dT) const;

  // The model's matrices at the current parameters and, when built with derivatives,
  // their derivatives by every free parameter.
  struct Built {
    Eigen::MatrixXd A, Bn, Bo, C, D;
    std::vector<Eigen::MatrixXd> dA, dBn, dBo, dC, dD;
    std::vector<Index> shift;
    std::vector<bool> frac;
    std::vector<double> tau;
  };

 private:
  static constexpr int kLanes = 8;

  template <int N>
  bool build(const Prepared& d, Built& b, Index q0) const;
  bool respond(const Prepared& d, Index p, const Built& b, std::vector<CMat>& T,
               std::vector<std::vector<CMat>>* dT) const;

  ModelLayout layout_;
  const FitOptions& options_;
  Eigen::VectorXd full_;
  std::vector<Index> free_;
  std::vector<std::vector<Index>> delay_of_;  // per free parameter: inputs it delays
};

// The data sets made ready, with what the noise model rests on (fit_data.cc).
struct PreparedAll {
  std::vector<Prepared> sets;
  bool noise_known = true;
  std::string noise_source;
};
PreparedAll prepare_all(const PhysicalModel& model, const std::vector<FitDataset>& data, const FitOptions& options);
// `count` lines evenly spaced over a set's (log-spaced, typically) grid.
Prepared subsample(const Prepared& d, int count);
// The controller the target needs, checked (and against the base's channels when
// base != nullptr).
void check_controller(const FitOptions& o, const BaseInfo* base);
// Channel names: the data's (first set) when complete, else the base's.
void channel_names(const std::vector<FitDataset>& data, const BaseInfo& b, FitTarget t, std::vector<std::string>& outs,
                   std::vector<std::string>& ins);
// Per-channel error and noise floor over the sets at the engine's current values.
void score_channels(Engine& engine, const std::vector<Prepared>& sets, bool noise_known,
                    std::vector<ChannelFit>& channels, double& error, double& floor);

}  // namespace lpvid::fit_detail
