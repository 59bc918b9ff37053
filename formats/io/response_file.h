// lpvid — a file that holds a frequency response: a state-space model (JSON,
// model_json.h) or frequency-response data (FRD: .mat, frd_mat.h; else CSV,
// frd_csv.h).  Shared by bode, compare, unloop and fit.
//
// The kind follows the name: ".json" a model, ".mat" MATLAB, anything else CSV.
// Standard input ("-") has no name: its content decides (a first non-blank
// character '{' is a model, anything else FRD CSV), so that pipelines such as
// `lpvid realize g.csv --out - | lpvid unloop --closed-loop - ...` work.  Stdin is
// read whole first, at most kMaxStdinBytes.
#pragma once

#include <optional>
#include <string>

#include "idlib/core/types.h"

namespace lpvid {

inline constexpr std::size_t kMaxStdinBytes = std::size_t{1} << 30;

struct ResponseFile {
  std::optional<StateSpace> model;       // a model file
  std::optional<FrequencyResponse> frd;  // FRD data
};

// Throws InputError as the readers do.
ResponseFile read_response_file(const std::string& path);

}  // namespace lpvid
