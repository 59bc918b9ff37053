// The stage's time-domain route, shared by `lpvid fit --log`, `lpvid diagnose
// --log`, `lpvid compare --log` (with a stage6 model) and the aliases `lpvid
// stage6 fit/diagnose`: one implementation, so the loop is the same whichever
// command a user learnt.  Numerics: idlib/stage6/stage6_time.h (the
// model <-> fit mapping), idlib/stage6/stage6_fit.h (equation error),
// idlib/stage6/stage6_output_error.h (output error).  The log is the stage's:
// t, v1..v6, u1..u6 (commanded wrench F_x F_y F_z tau_x tau_y tau_z), q1..q6
// (x y z psi theta phi).
#pragma once

#include <string>
#include <vector>

#include "idlib/physical/physical_model.h"

namespace CLI {
class App;
}

namespace lpvid::cli {

struct StageTimeFitRequest {
  PhysicalModel start;
  std::string model_label;   // where the start came from (a file, or "stage6 fit --effects ...")
  std::string log, out;      // out "" = print only
  std::string method = "output";  // equation | output | both
  std::string command;       // "fit" or "stage6 fit" (messages)
  // The lineage the new record is appended to (read if it exists): `fit` the
  // start model's history (as the frequency fit), `stage6 fit` the --out file's.
  std::string history_from;
  bool json = false;
};
void run_stage_time_fit(const StageTimeFitRequest& r);

struct StageTimeDiagnoseRequest {
  PhysicalModel current;
  std::string model_label, log, out, command;
  std::vector<std::string> candidates;  // framework effect names; empty = every time-domain effect it lacks
  double delta_bic = 10.0;
  bool json = false;
};
void run_stage_time_diagnose(const StageTimeDiagnoseRequest& r);

struct StageTimeCompareRequest {
  PhysicalModel model;
  std::string model_label, log, out_png, out_json;
  double window_s = 0.5, threshold_percent = 10.0;
  bool json = false;
};
void run_stage_time_compare(const StageTimeCompareRequest& r);

}  // namespace lpvid::cli
