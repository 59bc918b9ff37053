// lpvid — Markov-parameter files, written by `lpvid markov` and read by
// `hankel` and `realize` (docs/formats.md).
//
//   # lpvid markov 1
//   # sample_period_s: 0.001
//   # inputs: v1,v2
//   # outputs: q1
//   # noise_std: 1e-06,2e-06
//   # input_rms: 0.5,0.5
//   # output_rms: 0.0001
//   lag,g_q1_v1,g_q1_v2
//   0,0,0
//   1,1.5e-06,-2e-07
//
// Metadata: "# key: value" comment lines before the header; the first must be
// "# lpvid markov 1" (format and version).  sample_period_s (> 0, s), inputs and
// outputs (comma-separated unique names) are required; noise_std (p × m,
// row-major over outputs then inputs), input_rms (m) and output_rms (p) are
// optional (empty when absent); other comments are ignored.  Header: "lag", then
// g_<output>_<input> for every output (outer) and input (inner).  One row per lag
// 0, 1, 2, ... (no gaps); cells follow the log rules (csv_log.h).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "formats/io/atomic_file.h"
#include "idlib/core/types.h"

namespace lpvid {

struct MarkovFile {
  MarkovSequence g;                  // g[k]: outputs x inputs at lag k, k = 0..L
  double sample_period_s = 0;        // > 0
  std::vector<std::string> inputs;   // m names
  std::vector<std::string> outputs;  // p names
  Eigen::MatrixXd noise_std;         // p x m standard deviation of each g entry, or empty
  Eigen::VectorXd input_rms;         // m, or empty
  Eigen::VectorXd output_rms;        // p, or empty
};

// Text of the file.  Throws InputError on inconsistent shapes, empty or
// duplicate names, a sample period <= 0, or non-finite numbers.
std::string markov_csv_text(const MarkovFile& file, const std::string& path_for_messages = "<markov>");
// Writes markov_csv_text atomically (atomic_file.h); "-" is stdout.
void write_markov_csv(const std::string& path, const MarkovFile& file);
// Reads and validates; "-" reads stdin.  Throws InputError "path:line:column: ...".
MarkovFile read_markov_csv(const std::string& path);

}  // namespace lpvid
