// The bad-input suite of issue 12: every class of failure found by the held-out
// corpus and the fuzzer, with cases of our own.  Each refused run must exit 2
// (or 1 for a failed computation) with exactly one line on stderr that names the
// value or place and says what to do, create nothing and change nothing: the
// whole working directory, inputs included, is compared before and after.
#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <thread>

#include "formats/io/model_json.h"
#include "tests/cli/effect_fixture.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace bad_input_test {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::StartsWith;
using lpvid::testing::run_lpvid;
using lpvid::testing::RunResult;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

void write_text(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

// Everything under a directory: path -> content (files), kind (others).
std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string rel = fs::relative(e.path(), dir).string();
    const auto status = fs::symlink_status(e.path());
    if (fs::is_symlink(status)) out[rel] = "<link " + fs::read_symlink(e.path()).string() + ">";
    else if (fs::is_regular_file(status)) out[rel] = slurp(e.path());
    else if (fs::is_directory(status)) out[rel] = "<dir>";
    else out[rel] = "<special>";
  }
  return out;
}

// Data shared by the suite: one simulated dataset, its Markov parameters and model.
class BadInput : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    data_ = std::make_unique<TempDir>("badin");
    RunResult r = run_lpvid("simulate platform --out " + data_->path().string() +
                            " --positions middle --duration-s 2 --analyzer --analyzer-points 20 --analyzer-mat");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = run_lpvid("markov --excitation v1,v2,v3 --output q1,q2,q3 --lags 200 --out " + at("g.csv") + " " + logs());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = run_lpvid("realize " + at("g.csv") + " --out " + at("G.json"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    r = run_lpvid("model init --out " + at("start.json"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  static void TearDownTestSuite() { data_.reset(); }

  void SetUp() override { work_ = std::make_unique<TempDir>("badwork"); }

  static std::string data(const std::string& name) { return (data_->path() / "middle_1000hz" / name).string(); }
  static std::string at(const std::string& name) { return (data_->path() / name).string(); }
  static std::string logs() { return data("exp_T_psi.csv") + " " + data("exp_T_theta.csv") + " " + data("exp_F_z.csv"); }
  std::string work(const std::string& name) const { return *work_ / name; }

  // Runs lpvid in the work directory; expects `code`, one stderr line holding
  // `what` and a remedy, and no change at all to the data and work directories.
  RunResult refused(const std::string& args, const std::string& what, int code = 2) const {
    const auto data_before = snapshot(data_->path());
    const auto work_before = snapshot(work_->path());
    const RunResult r = run_lpvid(args, "", work_->path().string());
    EXPECT_EQ(r.exit_code, code) << args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_THAT(r.err, StartsWith("lpvid")) << r.err;
    EXPECT_THAT(r.err, HasSubstr(what)) << args;
    // "what; what to do": a remedy, said with one of these verbs.
    static const char* const kRemedies[] = {"give ", "use ", "check ", "choose ", "fix ", "excite ", "write ",
                                            "save ", "rename ", "drop ", "create ", "make ", "lower ", "raise ",
                                            "shorten ", "add ", "remove ", "split ", "reduce ", "run ", "send ",
                                            "leave ", "resample ", "record "};
    EXPECT_TRUE(std::any_of(std::begin(kRemedies), std::end(kRemedies),
                            [&](const char* verb) { return r.err.find(verb) != std::string::npos; }))
        << "no remedy in: " << r.err;
    EXPECT_LT(r.err.size(), 2100u);
    EXPECT_EQ(snapshot(data_->path()), data_before) << args;
    EXPECT_EQ(snapshot(work_->path()), work_before) << args;
    return r;
  }

  static std::unique_ptr<TempDir> data_;
  std::unique_ptr<TempDir> work_;
};
std::unique_ptr<TempDir> BadInput::data_;

// ---- 1. an input overwritten ---------------------------------------------

TEST_F(BadInput, OutputFlagNamingAnInput_IsRefusedForEveryOutputFlag) {
  refused("hankel " + at("g.csv") + " --out sv.csv --png " + at("g.csv"), "refusing to overwrite input");
  refused("hankel " + at("g.csv") + " --out " + at("g.csv"), "with --out");
  refused("realize " + at("g.csv") + " --out " + at("g.csv"), "refusing to overwrite input");
  refused("markov --excitation v1 --output q1 --out " + data("exp_T_psi.csv") + " " + data("exp_T_psi.csv"),
          "refusing to overwrite input");
  refused("unloop --closed-loop " + at("G.json") + " --controller " + data("controller.json") + " --out " +
              data("controller.json"),
          "refusing to overwrite input");
  refused("bode --out " + at("G.json") + " " + at("G.json"), "refusing to overwrite input");
  refused("frf --excitation v1 --output u1 --out " + data("exp_T_psi.csv") + " " + data("exp_T_psi.csv"),
          "refusing to overwrite input");
  refused("frf --excitation v1,v2 --input u1 --output q1 --out " + data("exp_T_psi.csv") + " " + data("exp_T_psi.csv"),
          "--input names 1 columns and --excitation 2");
  refused("compare " + at("G.json") + " " + data("truth_closed_loop.json") + " --out " + at("G.json"),
          "refusing to overwrite input");
  refused("model export --model " + at("start.json") + " --xb 0 --out " + at("start.json"),
          "refusing to overwrite input");
}

TEST_F(BadInput, OneFileSpelledTwoWays_IsTheSameFile) {
  // Relative against absolute, through "..", a symbolic link and a hard link.
  const std::string rel = fs::relative(at("g.csv"), work_->path()).string();
  refused("hankel " + at("g.csv") + " --out " + rel, "refusing to overwrite input");
  refused("hankel " + at("g.csv") + " --out " + at("../" + data_->path().filename().string() + "/g.csv"),
          "refusing to overwrite input");
  fs::create_symlink(at("g.csv"), work("link.csv"));
  refused("hankel " + at("g.csv") + " --out link.csv", "refusing to overwrite input");
  fs::create_hard_link(at("g.csv"), work("hard.csv"));
  refused("hankel " + at("g.csv") + " --out hard.csv", "refusing to overwrite input");
}

TEST_F(BadInput, TwoOutputsOnOneFile_AreRefused) {
  refused("hankel " + at("g.csv") + " --out sv.csv --png sv.csv", "name the same file");
  refused("hankel " + at("g.csv") + " --out sv.csv --png ./sv.csv", "name the same file");
  refused("hankel " + at("g.csv") + " --out - --png -", "both write to standard output");
}

TEST_F(BadInput, IdentifyIntoADirectoryHoldingALinkToAnInput_IsRefused) {
  fs::create_directory(work("res"));
  fs::create_symlink(data("controller.json"), work("res/plant.json"));
  refused("identify --controller " + data("controller.json") + " --excitation v1,v2,v3 --output q1,q2,q3 --out res " +
              logs(),
          "refusing to overwrite input");
}

// ---- 2. outputs left behind on failure ------------------------------------

TEST_F(BadInput, MissingOutputDirectory_IsFoundBeforeAnyOutputIsWritten) {
  refused("hankel " + at("g.csv") + " --out sv.csv --png nodir/x.png", "directory 'nodir' does not exist");
  refused("realize " + at("g.csv") + " --out nodir/G.json", "create it first");
}

TEST_F(BadInput, FailedIdentify_LeavesNoDirectory) {
  const std::string base = "identify --controller " + data("controller.json") + " --excitation v1,v2,v3 --output q1,q2,q3 --out res ";
  refused(base + "--order 10000 " + logs(), "--order: '10000' is out of range");
  refused(base + "--error-weights 1,2 " + logs(), "--error-weights has 2 values for 3 outputs");
  write_text(work("bad.csv"), "t,v1\n0,1\n0.001,x\n");
  refused(base + "bad.csv", "bad.csv:3:7: cannot parse 'x'");
  write_text(work("short.csv"), "t,v1,v2,v3,q1,q2,q3\n0,1,2,3,4,5,6\n0.001,1,1,1,1,1,1\n");
  refused(base + "short.csv", "too short");
  // A 2 x 2 controller for three outputs.
  StateSpace c;
  c.sample_period_s = 0.001;
  c.A = Eigen::MatrixXd::Zero(0, 0);
  c.B = Eigen::MatrixXd::Zero(0, 2);
  c.C = Eigen::MatrixXd::Zero(2, 0);
  c.D = Eigen::MatrixXd::Identity(2, 2);
  write_text(work("c22.json"), state_space_to_json(c));
  refused("identify --controller c22.json --excitation v1,v2,v3 --output q1,q2,q3 --out res " + logs(), "controller");
}

TEST_F(BadInput, FailedSimulation_LeavesNoFolderAndNoTruthFiles) {
  refused("simulate platform --out sim --duration-s 1e12", "--duration-s: '1e12' is out of range");
  refused("simulate platform --out sim --duration-s 100000 --rate-hz 1000", "samples per experiment");
  refused("simulate platform --out sim --positions 5", "outside the stroke");
  refused("simulate platform --out sim --positions left,left", "twice");
  refused("simulate stage6 --out st --step-s 0.0003", "", 2);
  refused("simulate stage6 --experiment --out st --com-offset-mm 1,2", "--com-offset-mm: 2 values");
  refused("simulate stage6 --experiment --out st --inertia-kgm2 0.03", "--inertia-kgm2: 1 values");
  refused("simulate stage6 --experiment --out st --input-delay-ms 500", "--input-delay-ms");
  refused("simulate platform --out sim --profile sweep --analyzer", "--analyzer does not apply to a moving beam");
}

// ---- 3. uninitialised memory: damaged .mat files --------------------------

TEST_F(BadInput, TruncatedMatFile_IsAnErrorEverywhereItIsRead) {
  const std::string bytes = slurp(data("S.mat"));
  write_text(work("cut.mat"), bytes.substr(0, bytes.size() * 2 / 3));
  refused("unloop --sensitivity cut.mat --controller " + data("controller.json") + " --out P.csv", "cut.mat");
  refused("compare --model " + data("truth_plant.json") + " --data cut.mat", "cut.mat");
  refused("fit --model " + at("start.json") + " --data cut.mat@0 --target S --controller " + data("controller.json") +
              " --out f.json",
          "cut.mat");
}

// ---- 4. a crash: deeply nested JSON ----------------------------------------

TEST_F(BadInput, ControllerNested200000Deep_IsAShortPositionedError) {
  write_text(work("deep.json"), std::string(200000, '[') + std::string(200000, ']'));
  const RunResult r = refused("unloop --closed-loop " + at("G.json") + " --controller deep.json --out P.json",
                              "deep.json:1:65: arrays and objects nested deeper than 64 levels");
  EXPECT_LT(r.err.size(), 300u);
}

// ---- 5. numbers out of range -------------------------------------------------

TEST_F(BadInput, NumberBeyondADouble_IsPositionedInEveryJsonReader) {
  std::string model = slurp(at("G.json"));
  model.replace(model.find("\"ts\": ") + 6, 5, "1e400");
  write_text(work("big.json"), model);
  refused("bode --out b.png big.json", "big.json:3:9: number '1e400' is out of range");
  std::string physical = slurp(at("start.json"));
  const std::size_t v = physical.find("\"value\": ") + 9;
  physical.replace(v, physical.find(',', v) - v, "1e400");
  write_text(work("p.json"), physical);
  refused("model export --model p.json --xb 0 --out x.json", "number '1e400' is out of range");
  write_text(work("h.json.history.jsonl"),
             "{\"timestamp\":\"2026-11-23T12:00:00Z\",\"model\":\"m\",\"effects\":[],\"free_parameters\":0,\"cost\":"
             "1e400,\"error_mean\":0,\"error_max\":0}\n");
  refused("history --model h.json", "h.json.history.jsonl:1:");
}

// ---- 6. unbounded work -------------------------------------------------------

TEST_F(BadInput, ReadersAndFlagsBoundTheWork) {
  std::string header = "t";
  for (int j = 0; j < 300000; ++j) header += ",c" + std::to_string(j);
  write_text(work("wide.csv"), header + "\n");
  const auto start = std::chrono::steady_clock::now();
  refused("markov --excitation c1 --output c2 --out g.csv wide.csv", "the header has more than 65536 columns");
  // Was > 60 s (quadratic); linear now.  A generous bound, not a benchmark.
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(20));
  refused("markov --excitation v1 --output q1 --out g.csv /dev/zero", "line longer than 16 MiB");
  refused("bode --points 100000000 --out b.png " + at("G.json"), "--points: '100000000' is out of range");
  // A 1000-state model (unloop took 40-74 s).
  std::string rows = "[";
  for (int i = 0; i < 1000; ++i) rows += std::string(i ? "," : "") + "[]";
  write_text(work("huge.json"), "{\"type\": \"state_space\", \"ts\": 0.001, \"A\": " + rows + "], \"B\": [], \"C\": [], \"D\": []}");
  refused("unloop --closed-loop huge.json --controller " + data("controller.json") + " --out P.json",
          "key 'A' has 1000 rows: lpvid reads models of at most 400 states");
}

// ---- 7. special files --------------------------------------------------------

TEST_F(BadInput, FifoAsOutput_IsWrittenIntoAndKept) {
  const std::string fifo = work("pipe.csv");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string got;
  std::thread reader([&] { got = slurp(fifo); });
  const RunResult r = run_lpvid("hankel " + at("g.csv") + " --out " + fifo);
  reader.join();
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(got, HasSubstr("index,singular_value,above_noise_floor"));
  struct stat st;
  ASSERT_EQ(::stat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
}

TEST_F(BadInput, DevNullAsOutput_StaysADevice) {
  const RunResult r = run_lpvid("realize " + at("g.csv") + " --out /dev/null");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  struct stat st;
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
}

TEST_F(BadInput, DirectoryOrMatIntoAPipe_IsRefused) {
  fs::create_directory(work("d"));
  refused("realize " + at("g.csv") + " --out d", "is a directory; give a file path");
  refused("identify --controller " + data("controller.json") + " --excitation v1,v2,v3 --output q1,q2,q3 --out " +
              data("controller.json") + " " + logs(),
          "is not a directory");
  refused("unloop --sensitivity /dev/null --controller " + data("controller.json") + " --out P.csv", "/dev/null");
}

// ---- 8. silent nonsense ------------------------------------------------------

TEST_F(BadInput, ZeroMeansAutomaticNoMore_AndRangesSayWhatToGive) {
  refused("realize " + at("g.csv") + " --order 0 --out x.json", "--order: '0' is out of range; give the model order");
  refused("markov --excitation v1 --output q1 --lags 0 --out g.csv " + data("exp_T_psi.csv"), "--lags: '0'");
  refused("markov --excitation v1 --output q1 --lags 99999999999999999999 --out g.csv " + data("exp_T_psi.csv"),
          "'99999999999999999999' is out of range");
  refused("fit --model " + at("start.json") + " --data " + at("G.json") + "@0 --rate-hz 0 --out f.json",
          "--rate-hz: '0' is out of range");
  refused("model export --model " + at("start.json") + " --xb 0 --rate-hz 0 --out x.json", "--rate-hz: '0'");
  // a measured input is fitted continuous, a held command sampled: not both
  refused("fit --model " + at("start.json") + " --data " + at("G.json") + "@0 --rate-hz 1000 --measured-input --out f.json",
          "--measured-input and --rate-hz 1000: a measured input is fitted with the continuous response");
  refused("bode --min -1 --out b.png " + at("G.json"), "--min: '-1' is out of range");
  refused("bode --min 0x10 --out b.png " + at("G.json"), "--min: '0x10' is not a number");
  refused("bode --max nan --out b.png " + at("G.json"), "--max: 'nan' is not a number");
  refused("simulate platform --out s --noise-scale -1", "--noise-scale: '-1' is out of range");
}

TEST_F(BadInput, ZeroController_IsNamed) {
  StateSpace c = read_state_space(data("controller.json"));
  c.B.setZero();
  c.D.setZero();
  write_text(work("zero.json"), state_space_to_json(c));
  refused("unloop --closed-loop " + at("G.json") + " --controller zero.json --out P.json",
          "zero.json: the controller is zero at every frequency");
  refused("unloop --sensitivity " + data("S.mat") + " --controller zero.json --out P.csv", "the controller is zero");
}

TEST_F(BadInput, AllZeroStageLog_IsNotFittedToItsStartValues) {
  std::string log = "t,u1,u2,u3,u4,u5,u6,q1,q2,q3,q4,q5,q6\n";
  for (int k = 0; k < 50; ++k) log += std::to_string(k * 0.001) + ",0,0,0,0,0,0,0,0,0,0,0,0\n";
  write_text(work("zero.csv"), log);
  refused("stage6 fit --log zero.csv", "is 0 throughout the log");
}

TEST_F(BadInput, UnknownSubcommand_IsNamedWithTheKnownOnes) {
  refused("frobnicate", "unknown subcommand 'frobnicate'; the subcommands are simulate, markov");
  refused("model frob", "unknown subcommand 'frob'; the subcommands are init, set, add, remove, define, export, effects");
}

TEST_F(BadInput, EmptyValue_IsNotTakenForAFlagLeftOut) {
  refused("hankel " + at("g.csv") + " --out sv.csv --png ''", "empty value for --png");
  refused("hankel " + at("g.csv") + " --out=", "empty value for --out");
}

TEST_F(BadInput, LogGivenTwiceOrStdinTwice_IsRefused) {
  refused("markov --excitation v1 --output q1 --out g.csv " + data("exp_T_psi.csv") + " " + data("exp_T_psi.csv"),
          "is given twice");
  refused("markov --excitation v1 --output q1 --out g.csv - -", "standard input ('-') is given for two inputs");
}

// ---- the model-error loop (issue 10's commands): every output, flag and reader --

using testing::kMountEffect;

TEST_F(BadInput, ModelErrorLoopOutputs_NeverOverwriteAnInputOrEachOther) {
  const std::string start = at("start.json");
  write_text(work("data.json"), "{\"format\": \"lpvid-datasets\", \"datasets\": [{\"beam_position_m\": 0, \"files\": [\"" +
                                    at("G.json") + "\"]}]}");
  refused("diagnose --model " + start + " --datasets data.json --out-effect data.json", "refusing to overwrite input");
  refused("diagnose --model " + start + " --datasets data.json --out-effect " + at("G.json"),
          "refusing to overwrite input");
  refused("diagnose --model " + start + " --datasets data.json --out d.json --out-effect d.json", "name the same file");
  refused("diagnose --model " + start + " --datasets data.json --png d.png --out-effect d.png", "name the same file");
  refused("fit --model " + start + " --datasets data.json --out data.json", "refusing to overwrite input");
  refused("fit --model " + start + " --datasets data.json --out f.json --bands " + at("G.json"),
          "refusing to overwrite input");
  refused("compare --model " + start + " --datasets data.json --out-png data.json", "refusing to overwrite input");
  refused("compare --model " + start + " --datasets data.json --out c.json --out-png c.json", "name the same file");
  write_text(work("mount.json"), kMountEffect);
  refused("model define --model " + start + " --from mount.json --add --out mount.json", "refusing to overwrite input");
  refused("model add input_delay --model " + start + " --out " + start + ".history.jsonl",
          "refusing to overwrite input");
  // --out naming the model under another spelling is not "in place": refused, not rewritten
  refused("model remove beam_gravity --model " + start + " --out " + fs::relative(start, work_->path()).string(),
          "refusing to overwrite input");
  refused("model add input_delay --model -", "cannot be rewritten in place; give --out FILE");
}

TEST_F(BadInput, ModelErrorLoopFlags_HaveRangesThatSayWhatToGive) {
  const std::string fit = "fit --model " + at("start.json") + " --data " + at("G.json") + "@0 --out f.json ";
  refused(fit + "--noise-level 2", "--noise-level: '2' is out of range");
  refused(fit + "--averages 0", "--averages: '0' is out of range");
  refused(fit + "--band-min -1", "--band-min: '-1' is out of range");
  refused(fit + "--band-min 100 --band-max 10", "--band-min 100 is not below --band-max 10");
  refused("diagnose --model " + at("start.json") + " --data " + at("G.json") + "@0 --delta-bic -1",
          "--delta-bic: '-1' is out of range");
  refused("compare --model " + at("start.json") + " --data " + at("G.json") + "@0 --confidence 1.5",
          "--confidence: '1.5' is out of range");
  refused("compare --model " + at("start.json") + " --data " + at("G.json") + "@0 --rate-hz 0",
          "--rate-hz: '0' is out of range");
  refused("model export --model " + at("start.json") + " --xb 1e9 --out x.json", "--xb: '1e9' is out of range");
}

TEST_F(BadInput, ManifestEffectAndHistoryFiles_AreReadWithTheBoundedJsonReader) {
  const std::string files = "\"datasets\": [{\"beam_position_m\": 0, \"files\": [\"" + at("G.json") + "\"]}]";
  write_text(work("big.json"), "{\"format\": \"lpvid-datasets\",\n \"rate_hz\": 1e400, " + files + "}");
  refused("fit --model " + at("start.json") + " --datasets big.json --out f.json",
          "big.json:2:13: number '1e400' is out of range");
  write_text(work("zero.json"), "{\"format\": \"lpvid-datasets\", \"rate_hz\": 0, " + files + "}");
  refused("fit --model " + at("start.json") + " --datasets zero.json --out f.json", "rate_hz 0: give the sample rate");
  write_text(work("deep.json"), std::string(100000, '[') + std::string(100000, ']'));
  refused("fit --model " + at("start.json") + " --datasets deep.json --out f.json", "deep.json:1:65: arrays and objects");
  refused("model define --model " + at("start.json") + " --from deep.json", "deep.json:1:65: arrays and objects");
  write_text(work("unknown.json"), "{\"format\": \"lpvid-datasets\", \"raet_hz\": 1, " + files + "}");
  refused("fit --model " + at("start.json") + " --datasets unknown.json --out f.json",
          "unknown key 'raet_hz'; remove it");
  std::string effect = kMountEffect;
  effect.replace(effect.find("800"), 3, "1e400");
  write_text(work("effect.json"), effect);
  refused("model define --model " + at("start.json") + " --from effect.json", "number '1e400' is out of range");
  const std::string record =
      "{\"timestamp\":\"2026-11-23T12:00:00Z\",\"model\":\"m\",\"effects\":[],\"free_parameters\":0,\"cost\":0,"
      "\"error_mean\":0,\"error_max\":0,";
  write_text(work("h.json.history.jsonl"), record + "\"error\":1e400}\n");
  refused("history --model h.json", "h.json.history.jsonl:1:");
  write_text(work("h.json.history.jsonl"), record + "\"noise_floor\":-0.5}\n");
  refused("history --model h.json", "noise_floor");
}

// ---- 9. leftovers of a killed run ----------------------------------------------

TEST_F(BadInput, StaleTemporaryOfAKilledRun_IsRemovedByTheNextRun) {
  write_text(work(".sv.csv.tmp.99999999.0"), "half a file");
  const RunResult r = run_lpvid("hankel " + at("g.csv") + " --out " + work("sv.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(fs::exists(work(".sv.csv.tmp.99999999.0")));
  EXPECT_TRUE(fs::exists(work("sv.csv")));
}

// ---- 10. pipelines ---------------------------------------------------------------

TEST_F(BadInput, ModelOnStdin_IsRecognisedByItsContent) {
  const std::string lpvid = LPVID_BINARY;
  RunResult r = run_lpvid("realize " + at("g.csv") + " --out - | " + lpvid + " unloop --closed-loop - --controller " +
                          data("controller.json") + " --out " + work("P.json"));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("unloop --closed-loop " + at("G.json") + " --controller " + data("controller.json") + " --out " +
                work("P_file.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_state_space(work("P.json")).A, read_state_space(work("P_file.json")).A);
  r = run_lpvid("model export --model " + at("start.json") + " --xb 0 --out - | " + lpvid + " bode --out " +
                work("b.png") + " -");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(work("b.png")));
}

// ---- 11. messages ----------------------------------------------------------------

TEST_F(BadInput, ChannelsAreNumberedFromOne) {
  std::string log = "t,v1,v2,q1\n";
  for (int k = 0; k < 400; ++k) log += std::to_string(k * 0.001) + "," + std::to_string((k * 7919) % 13 - 6) + ",0," + std::to_string(k % 5) + "\n";
  write_text(work("v2zero.csv"), log);
  refused("markov --excitation v1,v2 --output q1 --lags 10 --out g.csv v2zero.csv", "excitation input 2 is constant");
}

// ---- formats: text variants that must work, binary that must not ------------------

TEST_F(BadInput, EmptyFileNulBytesAndBinary_AreOneLineErrors) {
  write_text(work("empty.csv"), "");
  refused("markov --excitation v1 --output q1 --out g.csv empty.csv", "empty.csv:1:1: the file is empty");
  write_text(work("nul.csv"), std::string("t,v1,q1\n0,1\0,2\n", 16));
  refused("markov --excitation v1 --output q1 --out g.csv nul.csv", "nul.csv:2:");
  write_text(work("bin.json"), std::string("\x00\xff\xfe{", 4));
  refused("bode --out b.png bin.json", "bin.json:1:1: invalid JSON");
}

TEST_F(BadInput, ByteOrderMarkCrlfAndNoFinalNewline_AreRead) {
  std::string log = "\xEF\xBB\xBFt,v1,q1\r\n";
  for (int k = 0; k < 400; ++k)
    log += std::to_string(k * 0.001) + "," + std::to_string((k * 7919) % 13 - 6) + "," + std::to_string(k % 5) + "\r\n";
  log.pop_back();
  log.pop_back();
  write_text(work("bom.csv"), log);
  const RunResult r = run_lpvid("markov --excitation v1 --output q1 --lags 10 --out " + work("g.csv") + " " + work("bom.csv"));
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

}  // namespace bad_input_test
}  // namespace lpvid
