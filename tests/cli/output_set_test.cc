// cli/output_set.h in process: every output checked before anything is read,
// published together, nothing created on failure.
#include "cli/output_set.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "idlib/core/error.h"
#include "tests/support/run_lpvid.h"

namespace lpvid::cli {
namespace output_set_test {

namespace fs = std::filesystem;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

std::string error_of(OutputSet& outputs) {
  try {
    outputs.check();
  } catch (const InputError& e) {
    return e.what();
  }
  return "<no error>";
}

TEST(OutputSet, OutputThatIsAnInputThroughAHardLink_IsRefused) {
  TempDir dir("os_link");
  std::ofstream(dir / "in.csv") << "t\n";
  fs::create_hard_link(dir / "in.csv", dir / "alias.csv");
  OutputSet outputs;
  outputs.input(dir / "in.csv");
  outputs.file("--out", dir / "alias.csv");
  EXPECT_EQ(error_of(outputs), "refusing to overwrite input '" + (dir / "in.csv") + "' with --out '" +
                                   (dir / "alias.csv") + "'; choose another output path");
}

TEST(OutputSet, RewriteOfAnInput_IsAllowedOnPurpose) {
  TempDir dir("os_rewrite");
  std::ofstream(dir / "m.json") << "{}";
  OutputSet outputs;
  outputs.input(dir / "m.json");
  outputs.rewrite("--model", dir / "m.json");
  outputs.check();
  outputs.stage(dir / "m.json", std::string_view("{\"new\": 1}"));
  outputs.commit();
  EXPECT_EQ(slurp(dir.path() / "m.json"), "{\"new\": 1}");
}

TEST(OutputSet, NewOutputsSpelledTwoWays_AreOneFile) {
  TempDir dir("os_dup");
  fs::create_directory(dir.path() / "sub");
  OutputSet outputs;
  outputs.file("--out", dir / "x.csv");
  outputs.file("--png", dir / "sub/../x.csv");
  EXPECT_THAT(error_of(outputs), ::testing::HasSubstr("name the same file; give each output its own path"));
}

TEST(OutputSet, DirectoryOutput_IsCreatedOnlyAtCommit) {
  TempDir dir("os_dir");
  const std::string out = dir / "res/deep";
  {
    OutputSet outputs;
    outputs.directory("--out", out);
    const std::string a = outputs.file_in(out, "a.json");
    outputs.check();
    outputs.stage(a, std::string_view("{}"));
    EXPECT_FALSE(fs::exists(dir.path() / "res"));
  }  // not committed
  EXPECT_TRUE(fs::is_empty(dir.path()));
  OutputSet outputs;
  outputs.directory("--out", out);
  const std::string a = outputs.file_in(out, "a.json");
  outputs.check();
  outputs.stage(a, std::string_view("{}"));
  outputs.commit();
  EXPECT_EQ(slurp(a), "{}");
}

TEST(OutputSet, OutputDirectoryUnderAFile_IsRefused) {
  TempDir dir("os_file");
  std::ofstream(dir / "f") << "x";
  OutputSet outputs;
  outputs.directory("--out", dir / "f/res");
  outputs.file_in(dir / "f/res", "a.json");
  EXPECT_THAT(error_of(outputs), ::testing::HasSubstr("is not a directory; choose a path inside a directory"));
}

TEST(OutputSet, ReadOnlyOutputFile_IsRefused) {
  if (::geteuid() == 0) GTEST_SKIP() << "root may write any file";
  TempDir dir("os_ro");
  std::ofstream(dir / "ro.csv") << "x";
  fs::permissions(dir.path() / "ro.csv", fs::perms::owner_read);
  OutputSet outputs;
  outputs.file("--out", dir / "ro.csv");
  EXPECT_THAT(error_of(outputs), ::testing::HasSubstr("is read-only; make it writable"));
}

TEST(OutputSet, StdinForTwoInputs_IsRefused) {
  OutputSet outputs;
  outputs.input("-");
  outputs.input("-");
  EXPECT_THAT(error_of(outputs), ::testing::HasSubstr("standard input ('-') is given for two inputs"));
}

}  // namespace output_set_test
}  // namespace lpvid::cli
