#include "fuzz/readers.h"

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "formats/io/csv_detail.h"
#include "formats/io/csv_log.h"
#include "formats/io/dataset_manifest.h"
#include "formats/io/frd_csv.h"
#include "formats/io/frd_mat.h"
#include "formats/io/history.h"
#include "formats/io/mat_log.h"
#include "formats/io/markov_csv.h"
#include "formats/io/model_json.h"
#include "formats/io/physical_model_json.h"
#include "formats/io/platform_json.h"
#include "idlib/core/error.h"

namespace lpvid::fuzz {
namespace {

[[noreturn]] void finding(Reader reader, const std::string& what) {
  std::fprintf(stderr, "fuzz %s: FINDING: %s\n", name(reader), what.c_str());
  std::abort();
}

// One temporary file per process, rewritten for every input.
class Scratch {
 public:
  Scratch() {
    char pattern[] = "/tmp/lpvid_fuzz_XXXXXX";
    fd_ = ::mkstemp(pattern);
    if (fd_ < 0) {
      std::perror("lpvid fuzz: mkstemp");
      std::abort();
    }
    path_ = pattern;
  }
  ~Scratch() {
    ::close(fd_);
    ::unlink(path_.c_str());
  }
  const std::string& write(const std::uint8_t* data, std::size_t size) {
    if (::ftruncate(fd_, 0) != 0 || (size > 0 && ::pwrite(fd_, data, size, 0) != static_cast<ssize_t>(size))) {
      std::perror("lpvid fuzz: write");
      std::abort();
    }
    return path_;
  }

 private:
  int fd_ = -1;
  std::string path_;
};

void run(Reader reader, const std::string& path, std::size_t size, const std::uint8_t* data) {
  switch (reader) {
    case Reader::kLogCsv: {
      // The CSV core split into three parts read in parallel must agree with
      // the serial read: the same first error, or the same numbers.
      detail::CsvReadTuning parts;
      parts.split_offsets = {size / 3, 2 * size / 3};
      detail::NumericCsv serial, split;
      std::string serial_error, split_error;
      try {
        serial = detail::read_numeric_csv(path, "t", "give a column t");
      } catch (const InputError& e) {
        serial_error = e.what();
      }
      try {
        split = detail::read_numeric_csv(path, "t", "give a column t", parts);
      } catch (const InputError& e) {
        split_error = e.what();
      }
      if (serial_error != split_error)
        finding(reader, "serial and parallel reads disagree: '" + serial_error + "' vs '" + split_error + "'");
      if (serial_error.empty() && (serial.data.rows() != split.data.rows() || serial.data.cols() != split.data.cols() ||
                                   !(serial.data.array() == split.data.array()).all() || serial.names != split.names))
        finding(reader, "serial and parallel reads give different data");
      read_log(path);
      break;
    }
    case Reader::kLogMat:
      // v7.3 files (version 0x0200 at byte 124) go to libhdf5, which is not lpvid's code.
      if (size >= 128 && data[124] == 0x00 && data[125] == 0x02) return;
      read_log_mat(path);
      break;
    case Reader::kFrdCsv:
      read_frd_part(path);
      read_frd_csv(path);
      break;
    case Reader::kFrdMat:
      // v7.3 files (version 0x0200 at byte 124) go to libhdf5, which is not lpvid's code.
      if (size >= 128 && data[124] == 0x00 && data[125] == 0x02) return;
      read_frd_mat(path);
      break;
    case Reader::kStateSpaceJson:
      read_state_space(path);
      break;
    case Reader::kPhysicalModelJson:
      read_physical_model(path);
      break;
    case Reader::kHistory:
      read_history(path);
      break;
    case Reader::kMarkovCsv:
      read_markov_csv(path);
      break;
    case Reader::kPlatformJson:
      read_platform_parameters(path);
      break;
    case Reader::kEffectJson:
      read_effect_definition(path);
      break;
    case Reader::kDatasetManifest:
      read_dataset_manifest(path);
      break;
  }
}

}  // namespace

const std::vector<Reader>& all_readers() {
  static const std::vector<Reader> all = {Reader::kLogCsv,          Reader::kLogMat,          Reader::kFrdCsv,
                                          Reader::kFrdMat,          Reader::kStateSpaceJson,
                                          Reader::kPhysicalModelJson, Reader::kHistory,
                                          Reader::kMarkovCsv,       Reader::kPlatformJson,
                                          Reader::kEffectJson,      Reader::kDatasetManifest};
  return all;
}

const char* name(Reader reader) {
  switch (reader) {
    case Reader::kLogCsv: return "log_csv";
    case Reader::kLogMat: return "log_mat";
    case Reader::kFrdCsv: return "frd_csv";
    case Reader::kFrdMat: return "frd_mat";
    case Reader::kStateSpaceJson: return "state_space_json";
    case Reader::kPhysicalModelJson: return "physical_model_json";
    case Reader::kHistory: return "history";
    case Reader::kMarkovCsv: return "markov_csv";
    case Reader::kPlatformJson: return "platform_json";
    case Reader::kEffectJson: return "effect_json";
    case Reader::kDatasetManifest: return "dataset_manifest";
  }
  return "?";
}

std::string read_bytes(Reader reader, const std::uint8_t* data, std::size_t size) {
  static Scratch scratch;
  const std::string& path = scratch.write(data, size);
  try {
    run(reader, path, size, data);
  } catch (const InputError& e) {
    const std::string message = e.what();
    if (message.empty() || message.find('\n') != std::string::npos || message.find('\r') != std::string::npos)
      finding(reader, "an InputError message that is empty or not one line: " + message.substr(0, 300));
    if (message.size() > kMaxMessageBytes)
      finding(reader, "an InputError message of " + std::to_string(message.size()) + " bytes: " + message.substr(0, 300));
    return message;
  } catch (const std::exception& e) {
    finding(reader, std::string("an exception that is not InputError: ") + e.what());
  } catch (...) {
    finding(reader, "an exception that is not InputError");
  }
  return "";
}

}  // namespace lpvid::fuzz
