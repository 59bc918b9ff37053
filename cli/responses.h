// Files that hold a frequency response: a state-space model (.json) or
// frequency-response data (.mat, or CSV otherwise); "-" (stdin) by its content
// (formats/io/response_file.h).  Shared by bode, compare and unloop.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid::cli {

struct LoadedResponse {
  std::string path;
  std::optional<StateSpace> model;       // set for .json
  std::optional<FrequencyResponse> frd;  // set otherwise
};

LoadedResponse load_response(const std::string& path);

// Several FRD files that each hold some input columns (one excited input per
// file, as analyzers export them) merged into one response; one file passes through.
FrequencyResponse load_frd_merged(const std::vector<std::string>& paths);

// The controller that ran (state-space JSON; "-" = stdin).  A controller whose
// response is zero at every frequency (D = 0 and B = 0 or C = 0) means the loop
// was open: no plant can be recovered through it, so it is refused
// ("ctl.json: the controller is zero at every frequency (...); give the controller that ran").
StateSpace read_controller(const std::string& path);

// A controller file that holds its measured response (FRD .csv or .mat) rather than
// a model (.json, or "-": stdin holds a model).
bool is_measured_controller(const std::string& path);

// The controller's measured response (FRD .csv/.mat; several files, one per excited
// input, are not taken: one file).  Refused when zero at every frequency, as read_controller.
FrequencyResponse read_measured_controller(const std::string& path);

// The response on omega: a model is evaluated there; FRD data must already be on
// that grid (relative 1e-9), else InputError naming the file.
FrequencyResponse response_on(const LoadedResponse& r, const Eigen::VectorXd& omega_rad_s);

}  // namespace lpvid::cli
