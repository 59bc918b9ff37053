#include "formats/io/atomic_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <thread>

#include "formats/io/csv_log.h"
#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace atomic_file_test {

using test::input_error;

class AtomicFile : public test::TempDirTest {};

TEST_F(AtomicFile, Write_ReplacesTheTargetAndLeavesNoTemporary) {
  const std::string p = write("x.json", "old");
  write_file_atomic(p, "new content\n");
  EXPECT_EQ(read(p), "new content\n");
  EXPECT_EQ(entries(), std::vector<std::string>{"x.json"});
}

TEST_F(AtomicFile, MissingDirectory_SaysCheckTheDirectory) {
  const std::string p = path("out/x.json");
  EXPECT_EQ(input_error([&] { write_file_atomic(p, "x"); }),
            "cannot write '" + p + "': No such file or directory; check the directory exists and is writable");
  EXPECT_TRUE(entries().empty());
}

TEST_F(AtomicFile, TargetIsADirectory_FailsBeforeCreatingATemporary) {
  std::filesystem::create_directory(path("sub"));
  EXPECT_EQ(input_error([&] { write_file_atomic(path("sub"), "x"); }),
            "cannot write '" + path("sub") + "': it is a directory; give a file path");
  EXPECT_EQ(entries(), std::vector<std::string>{"sub"});
}

TEST_F(AtomicFile, FailedWrite_LeavesNoFileAndKeepsTheOldOne) {
  Eigen::MatrixXd data = Eigen::MatrixXd::Zero(1000, 2);
  data.col(0).setLinSpaced(0, 1);
  data(999, 1) = std::numeric_limits<double>::infinity();  // found after the first rows were written
  EXPECT_NE(input_error([&] { write_log(path("new.csv"), {"t", "a"}, data); }), "<no error>");
  EXPECT_TRUE(entries().empty());
  const std::string old = write("old.csv", "t,a\n0,1\n1,2\n");
  EXPECT_NE(input_error([&] { write_log(old, {"t", "a"}, data); }), "<no error>");
  EXPECT_EQ(read(old), "t,a\n0,1\n1,2\n");
  EXPECT_EQ(entries(), std::vector<std::string>{"old.csv"});
}

TEST_F(AtomicFile, WriterNotCommitted_RemovesItsTemporary) {
  {
    AtomicFileWriter out(path("a.txt"));
    out.write("partial");
    EXPECT_EQ(entries().size(), 1u);  // the temporary
    EXPECT_EQ(entries()[0].rfind(".a.txt.tmp.", 0), 0u);
  }
  EXPECT_TRUE(entries().empty());
}

TEST_F(AtomicFile, NotOverwriting_CatchesOnePathGivenTwoWays) {
  const std::string a = write("a.csv", "t\n");
  EXPECT_EQ(input_error([&] { check_not_overwriting({path("b.csv"), a}, dir_.string() + "/./a.csv"); }),
            "refusing to overwrite input '" + a + "' with output; choose another output path");
  std::filesystem::create_directory(path("sub"));
  EXPECT_NE(input_error([&] { check_not_overwriting({a}, path("sub/../a.csv")); }), "<no error>");
  const auto cwd = std::filesystem::current_path();
  std::filesystem::current_path(dir_);
  EXPECT_EQ(input_error([&] { check_not_overwriting({"./a.csv"}, "a.csv"); }),
            "refusing to overwrite input './a.csv' with output; choose another output path");
  std::filesystem::current_path(cwd);
}

TEST_F(AtomicFile, NotOverwriting_AllowsNewOutputsAndStdout) {
  const std::string a = write("a.csv", "t\n");
  EXPECT_EQ(input_error([&] { check_not_overwriting({a, "-"}, path("new.csv")); }), "<no error>");
  EXPECT_EQ(input_error([&] { check_not_overwriting({a, "-"}, "-"); }), "<no error>");
  write("b.csv", "t\n");
  EXPECT_EQ(input_error([&] { check_not_overwriting({a}, path("b.csv")); }), "<no error>");
}

TEST_F(AtomicFile, OutputSetNotCommitted_LeavesNothing) {
  {
    AtomicOutputSet out;
    out.stage(path("a.json"), "{}");
    out.stage(path("b.csv")).write("t\n");
    EXPECT_EQ(entries().size(), 2u);  // two temporaries
  }
  EXPECT_TRUE(entries().empty());
}

TEST_F(AtomicFile, OutputSetCommitted_WritesAllFiles) {
  AtomicOutputSet out;
  out.stage(path("a.json"), "{}");
  Eigen::MatrixXd data(2, 1);
  data << 0, 1;
  write_log(out.stage(path("b.csv")), {"t"}, data);
  EXPECT_EQ(input_error([&] { out.stage(dir_.string() + "/./a.json"); }),
            "output '" + dir_.string() + "/./a.json' is given twice (also as '" + path("a.json") +
                "'); give each output its own path");
  out.commit();
  EXPECT_EQ(entries(), (std::vector<std::string>{"a.json", "b.csv"}));
  EXPECT_EQ(read(path("b.csv")), "t\n0\n1\n");
}

TEST_F(AtomicFile, OutputSetWithADirectoryTarget_RenamesNothing) {
  std::filesystem::create_directory(path("b"));
  {
    AtomicOutputSet out;
    out.stage(path("a.json"), "{}");
    EXPECT_EQ(input_error([&] { out.stage(path("b"), "x"); }),
              "cannot write '" + path("b") + "': it is a directory; give a file path");
  }
  EXPECT_EQ(entries(), std::vector<std::string>{"b"});
}

TEST_F(AtomicFile, DirectoryTurnedUpBeforeCommit_RenamesNothing) {
  {
    AtomicOutputSet out;
    out.stage(path("a.json"), "{}");
    out.stage(path("b"), "x");
    std::filesystem::create_directory(path("b"));  // appears after the check
    EXPECT_EQ(input_error([&] { out.commit(); }),
              "cannot write '" + path("b") + "': Is a directory; check the directory exists and is writable");
  }
  EXPECT_EQ(entries(), std::vector<std::string>{"b"});
}

}  // namespace atomic_file_test
}  // namespace lpvid

namespace lpvid {
namespace atomic_file_test {

class AtomicTargets : public test::TempDirTest {};

TEST_F(AtomicTargets, StaleTemporaryOfADeadProcess_IsRemovedWhenTheTargetIsWrittenAgain) {
  // A pid that cannot be alive (above pid_max on Linux: 2^22) and a live one (ours is skipped; pid 1 is alive).
  write(".x.json.tmp.99999999.0", "half");
  write(".x.json.tmp.1.3", "someone else's, still running");
  write(".x.json.tmp.99999999.notanumber", "not our pattern");
  write(".y.json.tmp.99999999.0", "another target's");
  write_file_atomic(path("x.json"), "new\n");
  EXPECT_EQ(entries(), (std::vector<std::string>{".x.json.tmp.1.3", ".x.json.tmp.99999999.notanumber",
                                                 ".y.json.tmp.99999999.0", "x.json"}));
}

TEST_F(AtomicTargets, Fifo_IsWrittenIntoAndNeverReplaced) {
  const std::string fifo = path("pipe");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string got;
  std::thread reader([&] { got = read(fifo); });
  write_file_atomic(fifo, "through the pipe\n");
  reader.join();
  EXPECT_EQ(got, "through the pipe\n");
  struct stat st;
  ASSERT_EQ(::stat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  EXPECT_EQ(entries(), std::vector<std::string>{"pipe"});  // no temporary, no regular file
}

TEST_F(AtomicTargets, DevNull_StaysACharacterDevice) {
  EXPECT_EQ(output_target_kind("/dev/null"), OutputTargetKind::kStream);
  write_file_atomic("/dev/null", "discarded\n");
  struct stat st;
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
}

TEST_F(AtomicTargets, MissingDirectories_AreCreatedAtCommitOnly) {
  AtomicWriteOptions options;
  options.create_directories = true;
  {
    AtomicOutputSet out;
    out.stage(path("a/b/x.json"), "{}", options);
    EXPECT_FALSE(std::filesystem::exists(path("a")));  // the temporary waits in the test's directory
    EXPECT_EQ(entries().size(), 1u);
  }
  EXPECT_TRUE(entries().empty());  // not committed: nothing, not even the directories
  AtomicOutputSet out;
  out.stage(path("a/b/x.json"), "{}", options);
  out.stage(path("a/y.json"), "[]", options);
  out.commit();
  EXPECT_EQ(read(path("a/b/x.json")), "{}");
  EXPECT_EQ(read(path("a/y.json")), "[]");
  EXPECT_EQ(entries(), std::vector<std::string>{"a"});
}

TEST_F(AtomicTargets, DirectoryUnderAFile_IsRefused) {
  write("f", "a file");
  AtomicWriteOptions options;
  options.create_directories = true;
  EXPECT_EQ(input_error([&] { AtomicFileWriter w(path("f/x.json"), options); }),
            "cannot write '" + path("f/x.json") + "': '" + path("f") + "' is a file, not a directory; choose another "
            "output directory");
}

}  // namespace atomic_file_test
}  // namespace lpvid
