// Every reader on its seed corpus (fuzz/corpus/<reader>/) and on the inputs the
// fuzzers once found (fuzz/regressions/<reader>/): an accepted file or a one-line
// InputError, never a crash, another exception or a runaway message (fuzz/readers.h
// aborts on those).  Under the LPVID_SANITIZE build this also checks memory.
#include "fuzz/readers.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace lpvid::fuzz {
namespace readers_test {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Feeds every file of dir (if it exists) to reader; returns how many there were.
int feed(Reader reader, const fs::path& dir) {
  if (!fs::is_directory(dir)) return 0;
  int n = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    const std::string bytes = slurp(entry.path());
    SCOPED_TRACE(entry.path().string());
    const std::string message = read_bytes(reader, reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
    EXPECT_LE(message.size(), kMaxMessageBytes);
    ++n;
  }
  return n;
}

TEST(FuzzReaders, EverySeedAndRegressionInput_IsAcceptedOrAOneLineInputError) {
  const fs::path root = fs::path(LPVID_SOURCE_DIR) / "fuzz";
  for (const Reader reader : all_readers()) {
    SCOPED_TRACE(name(reader));
    const int seeds = feed(reader, root / "corpus" / name(reader));
    EXPECT_GE(seeds, 3) << "fuzz/corpus/" << name(reader) << " needs seed files";
    feed(reader, root / "regressions" / name(reader));
  }
}

TEST(FuzzReaders, EmptyAndBinaryInput_IsAOneLineInputErrorForEveryReader) {
  const std::string binary("\x00\xff\x7f\x80\n\r{[\"", 10);
  for (const Reader reader : all_readers()) {
    SCOPED_TRACE(name(reader));
    if (reader != Reader::kHistory) {  // an empty history has no fits
      EXPECT_NE(read_bytes(reader, nullptr, 0), "");
    }
    EXPECT_NE(read_bytes(reader, reinterpret_cast<const std::uint8_t*>(binary.data()), binary.size()), "");
  }
}

}  // namespace readers_test
}  // namespace lpvid::fuzz
