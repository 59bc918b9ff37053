// The time-domain route of a mechanical base (a positioning axis, a gantry, any stage
// the user describes): `lpvid fit --log RUN.csv` and `lpvid diagnose --log RUN.csv`
// on a model of base "mechanical" fit the equation of motion sample by sample (the
// force-error route, idlib/fit/force_error.h) and run the model-error loop over its
// time-domain effects (coulomb_friction, force_offset).  The log is a CSV log (or
// .mat) with a time column and one column per base input and output, named as the
// description names them.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "idlib/physical/physical_model.h"

namespace CLI {
class App;
}

namespace lpvid::cli {

struct MechanicalTimeRequest {
  PhysicalModel model;
  std::string model_label, log, out, report;
  std::string png;  // the force overlay: fit --plot (the fitted model), diagnose --png (the model as given)
  std::string png_flag = "--plot";
  std::string history_from;  // fit: the start model's history (continued beside --out)
  std::vector<std::string> candidates;  // diagnose
  double delta_bic = 10.0;
  double window_s = 0.0;      // 0: the default (idlib/fit/force_error.h)
  bool measured_input = false;
  std::string smoothing_source;  // compare: where window_s and measured_input came from
  bool json = false;
};

// The request for a model file on a log: the label is the path, the history the
// model's own (continued beside --out).
MechanicalTimeRequest mechanical_time_request(PhysicalModel model, const std::string& model_path,
                                              const std::string& log, const std::string& out, double window_s,
                                              bool measured_input, bool json);
// compare: the smoothing window and input convention the fit that wrote the model used
// (the file's fit section, written by fit --log and diagnose --log --out), so that a
// model is checked on a new log as it was fitted; the defaults, said so, for a model
// no force-error fit wrote.
void use_recorded_smoothing(const nlohmann::json& fit_section, MechanicalTimeRequest& r);
// Declares --window-s (fit and diagnose).
void add_window_option(CLI::App* app, double* window_s);

void run_mechanical_time_fit(const MechanicalTimeRequest& r);
// `compare --log RUN --model M.json` on a mechanical model: the force error of the model as
// given (nothing refitted; a validation log), where it fails in time (windows of
// failing_window_s; 0: 0.25 s), the overlay to r.png (--out-png) and the summary to
// r.report (--out).
void run_mechanical_time_compare(const MechanicalTimeRequest& r, double failing_window_s);
void run_mechanical_time_diagnose(const MechanicalTimeRequest& r);

}  // namespace lpvid::cli
