// Files that hold a frequency response: a state-space model (.json) or
// frequency-response data (.mat, or CSV otherwise).  Shared by bode, compare and unloop.
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

// The response on omega: a model is evaluated there; FRD data must already be on
// that grid (relative 1e-9), else InputError naming the file.
FrequencyResponse response_on(const LoadedResponse& r, const Eigen::VectorXd& omega_rad_s);

bool is_model_path(const std::string& path);

}  // namespace lpvid::cli
