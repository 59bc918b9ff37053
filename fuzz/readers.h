// lpvid — the readers as the fuzzers and their regression tests drive them
// (fuzz/README.md): bytes in, the reader's verdict out.
//
// Every reader must either accept the bytes or throw InputError with a one-line
// message of bounded length.  Anything else is a finding and aborts the process
// (so that libFuzzer, and a test, report it): another exception type, a message
// with a line break or longer than kMaxMessageBytes, and, through the sanitizers,
// any crash, leak, out-of-bounds or uninitialised access or undefined behaviour.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace lpvid::fuzz {

enum class Reader {
  kLogCsv,             // read_log, and the CSV core split into three parts read in parallel
  kLogMat,             // read_log_mat (MATLAB v5 logs; v7.3 input is skipped: libhdf5's parser, not lpvid's)
  kFrdCsv,             // read_frd_csv and read_frd_part
  kFrdMat,             // read_frd_mat (MATLAB v5; v7.3 input is skipped: libhdf5's parser, not lpvid's)
  kStateSpaceJson,     // read_state_space
  kPhysicalModelJson,  // read_physical_model
  kHistory,            // read_history (fit-history JSON lines)
  kMarkovCsv,          // read_markov_csv
  kPlatformJson,       // read_platform_parameters
  kEffectJson,         // read_effect_definition (a user-defined effect)
  kDatasetManifest,    // read_dataset_manifest
};

// Every reader, for loops over them.
const std::vector<Reader>& all_readers();

// The harness name: "log_csv", "log_mat", "frd_csv", "frd_mat", "state_space_json",
// "physical_model_json", "history", "markov_csv", "platform_json", "effect_json",
// "dataset_manifest".
const char* name(Reader reader);

// Longest message a reader may give (values are cut to 40 bytes; paths are short here).
inline constexpr std::size_t kMaxMessageBytes = 1000;

// Writes the bytes to a private temporary file and runs the reader on it.
// Returns the InputError message, or "" when the reader accepted the bytes.
// Aborts on a finding (see above).
std::string read_bytes(Reader reader, const std::uint8_t* data, std::size_t size);

}  // namespace lpvid::fuzz
