// lpvid — the time-domain route of the base "stage6": a stage6 physical model
// (idlib/physical/stage6/stage6_base.h) fitted to, diagnosed on and compared
// with a closed-loop log through the stage's nonlinear equations of motion
// (idlib/stage6/stage6_fit.h: equation error; idlib/stage6/stage6_output_error.h:
// output error).  This file maps between the framework's parameter list and the
// time-domain fits' parameter vector; `lpvid fit/diagnose/compare --log` use it
// (docs/effects.md, "Base stage6: the time-domain route").
//
// | model parameter                       | time-domain fit                        |
// |---------------------------------------|----------------------------------------|
// | mass_kg, force_constant_scale         | m, kappa: exactly one of them free     |
// | inertia_{xx,yy,zz}_kgm2               | H (always estimated: must be free)     |
// | lever_arm_*_m (held)                  | the designed arms r (allocation)       |
// | com_offset: com_{x,y,z}_m             | c                                      |
// | gap_dependence: gap_decay_per_m       | gamma                                  |
// | electrical_lag: electrical_time_constant_s, back_emf_damping_Ns_per_m | tau_e, b |
// | gravity_m_per_s2 (held)               | must equal the simulator's g (9.81)    |
// | hover_{yaw,pitch,roll}_rad            | not used: the nonlinear equations carry the attitude in their state |
//
// Effects without a time-domain form (input_delay, actuator_lag, gain_error,
// sensor_gain, sensor_crosstalk, structural_mode, user-defined ones) are refused
// with what to do (the frequency route: frf --input, then fit --data).
#pragma once

#include <algorithm>
#include <array>
#include <string>
#include <vector>

#include "idlib/physical/physical_model.h"
#include "idlib/stage6/stage6_fit.h"
#include "idlib/stage6/stage6_output_error.h"

namespace lpvid {

// The stage effects of the time-domain route, as framework effect names.
const std::vector<std::string>& stage6_time_effects();

struct Stage6TimeSetup {
  stage6::StageParameters nominal;  // start values, designed arms, reference gap
  stage6::StageFitModel model;      // which effects
  bool fix_mass = true;             // mass held, kappa free (else the reverse)
};

// @throws InputError  base not stage6; an effect without a time-domain form (the
//   message names it and the frequency route); mass and kappa both free or both
//   held; an inertia held; gravity not the simulator's 9.81 m/s².
Stage6TimeSetup stage6_time_setup(const PhysicalModel& model);

// The framework model for a time-domain effect set (`lpvid stage6 fit --effects`):
// the bare stage6 base with those effects added (com -> com_offset, gap ->
// gap_dependence, lag -> electrical_lag).
PhysicalModel stage6_model_of(const stage6::StageFitModel& effects, bool fix_mass);

// The fitted values written into a copy of `model` (values clamped into their
// bounds, with a warning each in `warnings`), and the standard error of every
// model parameter (0 for held ones and for parameters the time route does not use;
// equation-error results have none: all 0).
PhysicalModel stage6_apply_time_fit(const PhysicalModel& model, const Eigen::Matrix<double, stage6::kStageThetaSize, 1>& theta,
                                    std::vector<std::string>* warnings = nullptr);

// theta of a model (kStageThetaNames order; effect parameters 0 when absent, the
// lag's tau_e the nominal one when absent).
Eigen::Matrix<double, stage6::kStageThetaSize, 1> stage6_time_theta(const PhysicalModel& model);

// The model parameter behind theta index i ("" when the model lacks the effect).
std::string stage6_time_parameter_name(int theta_index);

// ---- the output error as the framework's error figure and noise floor ----
// Per channel c: the rms output error over the rms of the channel's motion
// (relative, a fraction), and as its noise floor the same for the residual's
// sample-to-sample part, rms(Δe)/√2: white sensor noise, which no model predicts;
// a model error of a physical effect is smooth at the sampling rate and barely
// enters it.  `error` and `noise_floor` are the rms over the six channels (as the
// frequency route's error figure is one number over every channel).
//
// lpvid's resolution: a floor of kStageOutputErrorResolution (relative) stands in for
// the noise on a noise-free log.  Measured: the true model (gap_dependence, seed 3,
// noise scale 0) leaves 4.7e-8 of the motion, its Δe floor 2.7e-9: the difference
// between lpvid's simulator and its output-error integration; 1e-6 is 20x that, and
// 100x below the noise of the default experiment (2.4e-4).
inline constexpr double kStageOutputErrorResolution = 1e-6;

struct StageErrorFigure {
  std::array<double, 6> relative{}, floor{};  // per channel (kStageChannelNames order)
  double error = 0.0, noise_floor = 0.0;      // rms over the channels
  double mean = 0.0, max = 0.0;               // of `relative`
  // The floor "within the noise" is judged against: the noise, never below lpvid's resolution.
  double effective_floor() const { return std::max(noise_floor, kStageOutputErrorResolution); }
  double ratio_to_floor() const { return error / effective_floor(); }
  // Within `ratio` times that floor (the frequency route's explained_ratio, 1.5).
  bool within(double ratio) const { return error <= ratio * effective_floor(); }
};

// residual = simulated − measured (N × 6, StageOutputErrorResult::residual), q the
// measured outputs (N × 6, N >= 2).
StageErrorFigure stage_error_figure(const Eigen::MatrixXd& residual, const Eigen::MatrixXd& q);

}  // namespace lpvid
