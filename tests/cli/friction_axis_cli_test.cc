// A positioning axis through the program, as a user with a log of their own would run
// it: the description (samples/mechanical/ball_screw_axis.json) -> model init ->
// diagnose --log names Coulomb friction -> diagnose --log on its --out names the
// offset, explained -> fit --log reaches the floor.  The log comes from the
// independent simulator of tests/support/friction_axis.h (closed loop, PD on the
// quantised encoder, a reference trajectory); and the route's bad inputs.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <matio.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "formats/io/physical_model_json.h"
#include "tests/support/friction_axis.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace friction_axis_cli_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

std::string sample() { return std::string(LPVID_SOURCE_DIR) + "/samples/mechanical/ball_screw_axis.json"; }

// A lab's .mat: one top-level column vector per signal and t (docs/formats.md, layout (a)).
void write_signals_mat(const std::string& path, const std::vector<std::pair<std::string, Eigen::VectorXd>>& signals) {
  mat_t* mat = Mat_CreateVer(path.c_str(), nullptr, MAT_FT_MAT5);
  ASSERT_NE(mat, nullptr);
  for (const auto& [name, v] : signals) {
    std::size_t dims[2] = {static_cast<std::size_t>(v.size()), 1};
    matvar_t* var = Mat_VarCreate(name.c_str(), MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, const_cast<double*>(v.data()), 0);
    ASSERT_NE(var, nullptr);
    ASSERT_EQ(Mat_VarWrite(mat, var, MAT_COMPRESSION_NONE), 0);
    Mat_VarFree(var);
  }
  Mat_Close(mat);
}

// The description a lab writes for its axis: the drive's command vir in volts, the motor
// encoder qm, mass and viscous friction free at these design values, the drive's gain
// 35.15 N/V fixed from its datasheet.
void write_lab_description(const std::string& path, double mass_kg, double viscous_Ns_per_m) {
  std::ofstream(path) << fmt::format(R"({{
  "format": "lpvid-mechanical-base", "version": 1, "name": "lab_axis",
  "dofs": [{{"name": "x", "unit": "m"}}],
  "inputs": [{{"name": "vir", "unit": "V"}}],
  "outputs": [{{"name": "qm", "unit": "m"}}],
  "parameters": {{
    "M_kg": {{"value": {}, "unit": "kg", "lower": 0.1, "upper": 1000, "free": true}},
    "Fv_Ns_per_m": {{"value": {}, "unit": "N·s/m", "lower": 0, "upper": 10000, "free": true}},
    "gtau_N_per_V": {{"value": 35.15, "unit": "N/V", "lower": 1, "upper": 100, "free": false}}
  }},
  "mass": [["M_kg"]], "damping": [["Fv_Ns_per_m"]], "stiffness": [[0]],
  "input_map": [["gtau_N_per_V"]], "output_map": [[1]]
}})",
                                     mass_kg, viscous_Ns_per_m);
}

// A real axis is never the model, and its log is the lab's: an industrial drive's
// cascade, point-to-point moves with rests, a Stribeck rise and a position ripple (the
// idlib test's axis, tests/idlib/fit/force_error_test.cc), the drive's command in volts
// with the amplifier's gain fixed in the description, one .mat variable per signal.  The
// loop names Coulomb friction, then the offset, the Stribeck rise and the ripple, then
// says nothing is missing; fit --log reports the ripple's period; --png and --plot draw
// where the model fails.
TEST(FrictionAxisCli, ARealisticAxisFromALabMatFileThroughTheLoopWithFigures) {
  const TempDir dir("friction_real");
  friction_axis::Truth truth = friction_axis::realistic_truth();
  truth.k_f_N_per_A = 35.15;  // N/V: the drive's gain, from its datasheet
  const auto log = friction_axis::simulate(truth, friction_axis::realistic_experiment());
  write_signals_mat(dir / "run.mat", {{"t", log.t}, {"qm", log.x}, {"qg", log.r}, {"vir", log.i}});
  write_lab_description(dir / "axis.json", 3.0, 10.0);
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", dir / "axis.json",
                                  dir / "m0.json"))
                .exit_code,
            0);
  // the loop as a user runs it: diagnose --out on the last model until nothing is named
  std::vector<std::string> named;
  std::string model = dir / "m0.json", last_out;
  for (int round = 1; round <= 6; ++round) {
    const std::string next = dir / fmt::format("m{}.json", round);
    const auto r = run_lpvid(fmt::format("diagnose --model {} --log {} --out {}{} --json", model, dir / "run.mat",
                                         next, round == 1 ? fmt::format(" --png {}", dir / "d1.png") : ""));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    // --out is written exactly when something is named, and the report says which (as on
    // the frequency route).
    EXPECT_EQ(j["out_written"].get<bool>(), !j["named"].empty());
    EXPECT_EQ(std::filesystem::exists(next), !j["named"].empty());
    if (j["named"].empty()) {
      last_out = j["summary"].get<std::string>();
      break;
    }
    for (const auto& e : j["named"]) named.push_back(e.get<std::string>());
    model = next;
  }
  ASSERT_FALSE(named.empty());
  EXPECT_EQ(named[0], "coulomb_friction");
  EXPECT_THAT(named, ::testing::UnorderedElementsAre("coulomb_friction", "force_offset", "stribeck_friction",
                                                     "position_ripple"));
  EXPECT_THAT(last_out, HasSubstr("nothing is missing"));
  const auto f = run_lpvid(fmt::format("fit --model {} --log {} --plot {} --out {} --json", model, dir / "run.mat",
                                       dir / "f.png", dir / "fitted.json"));
  ASSERT_EQ(f.exit_code, 0) << f.err;
  const nlohmann::json j = nlohmann::json::parse(f.out);
  // the idlib test's bounds (tolerances explained there): the offset to 0.05 N, the
  // ripple's period to 0.2 %
  int seen = 0;
  for (const auto& p : j["parameters"]) {
    if (p["name"] == "offset_x_N") {
      EXPECT_NEAR(p["value"].get<double>(), truth.offset_N, 0.05);
      ++seen;
    }
    if (p["name"] == "ripple_period_x_m") {
      EXPECT_NEAR(p["value"].get<double>(), truth.ripple_period_m, 0.002 * truth.ripple_period_m);
      ++seen;
    }
  }
  EXPECT_EQ(seen, 2) << j["parameters"].dump();
  for (const std::string png : {"d1.png", "f.png"}) {
    const std::string bytes = slurp(dir / png);
    ASSERT_GT(bytes.size(), 8u) << png;
    EXPECT_EQ(bytes.substr(1, 3), "PNG") << png;
  }
}

// Scale is not a tolerance: a heavy axis (110 kg on a ball screw, friction of tens of
// newtons) under a drive's P/P cascade whose command is limited at 10 V, logged as the
// lab logs it (the command in volts, one .mat variable per signal), with a design 45 %
// light and viscous friction 3.6x low.  Every threshold of the route is relative (to the
// force's rms, to the floor, to the speeds the log holds), so the loop must name the
// same effects as on the 4 kg axis and reach the floor.
TEST(FrictionAxisCli, AHeavyAxisWithAVoltageLimitNamesTheSameEffectsAndReachesTheFloor) {
  const TempDir dir("friction_heavy");
  friction_axis::Truth truth;
  truth.m_kg = 110.0;
  truth.c_Ns_per_m = 180.0;
  truth.coulomb_N = 18.0;
  truth.offset_N = -4.5;
  truth.k_f_N_per_A = 35.15;  // N/V
  friction_axis::Experiment e;
  e.point_to_point = true;
  e.cascade = true;
  e.kx_per_s = 160.0;
  e.kv_N_per_mps = 243.45 * 35.15;
  e.integral_corner_hz = 0.0;
  e.saturation_N = 6.0 * 35.15;  // 6 V: the hardest accelerations reach it
  e.encoder_m = 0.5e-6;
  e.current_noise_A = 0.0;
  e.seconds = 24.8;
  const auto log = friction_axis::simulate(truth, e);
  // the limit is reached (the logged command is the limited one, as the drive applies it)
  ASSERT_GT((log.i.array().abs() >= 6.0 - 1e-12).count(), 100);
  write_signals_mat(dir / "run.mat", {{"t", log.t}, {"qm", log.x}, {"qg", log.r}, {"vir", log.i}});
  write_lab_description(dir / "axis.json", 60.0, 50.0);
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", dir / "axis.json",
                                  dir / "m0.json"))
                .exit_code,
            0);
  // the loop as a user runs it, from the design: diagnose --out on the last model until
  // nothing is named; then fit --log
  struct Loop {
    std::vector<std::string> named;
    std::string last_summary, fit_err;
    nlohmann::json fit;
  };
  auto loop = [&](const std::string& mat, const std::string& tag) {
    Loop out;
    std::string model = dir / "m0.json";
    for (int round = 1; round <= 5; ++round) {
      const std::string next = dir / fmt::format("{}{}.json", tag, round);
      const auto r = run_lpvid(fmt::format("diagnose --model {} --log {} --out {} --json", model, mat, next));
      EXPECT_EQ(r.exit_code, 0) << r.err;
      const nlohmann::json j = nlohmann::json::parse(r.out);
      if (j["named"].empty()) {
        out.last_summary = j["summary"].get<std::string>();
        break;
      }
      for (const auto& n : j["named"]) out.named.push_back(n.get<std::string>());
      model = next;
    }
    const auto f = run_lpvid(fmt::format("fit --model {} --log {} --out {} --json", model, mat,
                                         dir / (tag + "-fitted.json")));
    EXPECT_EQ(f.exit_code, 0) << f.err;
    out.fit_err = f.err;
    out.fit = nlohmann::json::parse(f.out);
    return out;
  };
  // the light axis's tolerances (0.2 % mass, 0.5 % forces: tests/idlib/fit/force_error_test.cc)
  auto check_estimates = [&](const std::string& fitted) {
    const PhysicalModel m = read_physical_model(fitted);
    EXPECT_NEAR(m.parameter("M_kg").value, truth.m_kg, 0.002 * truth.m_kg);
    EXPECT_NEAR(m.parameter("Fv_Ns_per_m").value, truth.c_Ns_per_m, 0.005 * truth.c_Ns_per_m);
    EXPECT_NEAR(m.parameter("coulomb_x_N").value, truth.coulomb_N, 0.005 * truth.coulomb_N);
    EXPECT_NEAR(m.parameter("offset_x_N").value, truth.offset_N, 0.005 * std::abs(truth.offset_N));
    return m;
  };
  const Loop a = loop(dir / "run.mat", "a");
  EXPECT_EQ(a.named, (std::vector<std::string>{"coulomb_friction", "force_offset"}));
  EXPECT_THAT(a.last_summary, HasSubstr("nothing is missing"));
  EXPECT_THAT(a.fit_err, HasSubstr("channel vir sits at its minimum -6"));  // the limit, said with its rows
  // the encoder's rests where the logged reference qg rests: a designed dwell, not a clip
  EXPECT_THAT(a.fit_err, ::testing::Not(HasSubstr("channel qm sits")));
  EXPECT_LE(a.fit["error_percent"].get<double>(), 1.5 * a.fit["noise_floor_percent"].get<double>());
  check_estimates(dir / "a-fitted.json");

  // The same drive logging its controller's command (before the limit): the loop adds
  // input_saturation to the two, and the profile search finds the 6 V (1 %: a clipped
  // stretch is a few hundred samples).
  e.log_unlimited = true;
  const auto unlimited = friction_axis::simulate(truth, e);
  ASSERT_GT(unlimited.i.cwiseAbs().maxCoeff(), 6.5);
  write_signals_mat(dir / "unlimited.mat", {{"t", unlimited.t}, {"qm", unlimited.x}, {"qg", unlimited.r}, {"vir", unlimited.i}});
  const Loop b = loop(dir / "unlimited.mat", "b");
  EXPECT_THAT(b.named, ::testing::UnorderedElementsAre("input_saturation", "coulomb_friction", "force_offset"));
  EXPECT_THAT(b.last_summary, HasSubstr("nothing is missing"));
  EXPECT_LE(b.fit["error_percent"].get<double>(), 1.5 * b.fit["noise_floor_percent"].get<double>());
  const PhysicalModel mb = check_estimates(dir / "b-fitted.json");
  EXPECT_NEAR(mb.parameter("saturation_vir_V").value, 6.0, 0.06);
}

TEST(FrictionAxisCli, TheLoopNamesCoulombThenTheOffsetAndTheFitReachesTheFloor) {
  const TempDir dir("friction_cli");
  const friction_axis::Truth truth;
  friction_axis::write_csv(friction_axis::simulate(truth, friction_axis::Experiment{}), dir / "run.csv");
  const std::string m0 = dir / "axis.json";
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", sample(), m0)).exit_code, 0);

  const auto r1 = run_lpvid(fmt::format("diagnose --model {} --log {} --out {} --report {} --json", m0,
                                        dir / "run.csv", dir / "next1.json", dir / "report1.json"));
  ASSERT_EQ(r1.exit_code, 0) << r1.err;
  const nlohmann::json d1 = nlohmann::json::parse(r1.out);
  EXPECT_EQ(d1["named"], nlohmann::json::array({"coulomb_friction"})) << d1["summary"];
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "report1.json"))["named"], d1["named"]);
  const PhysicalModel m1 = read_physical_model(dir / "next1.json");
  EXPECT_TRUE(m1.has_effect("coulomb_friction"));

  const auto r2 = run_lpvid(fmt::format("diagnose --model {} --log {} --out {}", dir / "next1.json",
                                        dir / "run.csv", dir / "next2.json"));
  ASSERT_EQ(r2.exit_code, 0) << r2.err;
  std::printf("%s\n", r2.out.c_str());
  EXPECT_THAT(r2.out, HasSubstr("missing: force_offset"));
  EXPECT_THAT(r2.out, HasSubstr("explained"));

  const auto r3 = run_lpvid(fmt::format("fit --model {} --log {} --out {} --json", dir / "next2.json",
                                        dir / "run.csv", dir / "fit3.json"));
  ASSERT_EQ(r3.exit_code, 0) << r3.err;
  const nlohmann::json f = nlohmann::json::parse(r3.out);
  EXPECT_LE(f["error_percent"].get<double>(), 1.5 * f["noise_floor_percent"].get<double>());
  const PhysicalModel m3 = read_physical_model(dir / "fit3.json");
  // 0.2 % (mass) and 0.5 % (forces): the tolerances of tests/idlib/fit/force_error_test.cc
  EXPECT_NEAR(m3.parameter("m_kg").value, truth.m_kg, 0.002 * truth.m_kg);
  EXPECT_NEAR(m3.parameter("coulomb_x_N").value, truth.coulomb_N, 0.005 * truth.coulomb_N);
  EXPECT_NEAR(m3.parameter("offset_x_N").value, truth.offset_N, 0.005 * truth.offset_N);
  // the lineage: diagnose's two --out and the fit, one history line each
  const std::string history = slurp(dir / "fit3.json.history.jsonl");
  EXPECT_EQ(std::count(history.begin(), history.end(), '\n'), 3) << history;

  // Validation on a log the fit did not see (point-to-point moves under the drive's
  // cascade, another noise seed): compare --log evaluates the model as given.  The fitted
  // model explains it within the floor; the design (the base alone) fails, and says where.
  friction_axis::Experiment other;
  other.point_to_point = true;
  other.cascade = true;
  other.seconds = 12.2;
  other.seed = 11;
  friction_axis::write_csv(friction_axis::simulate(truth, other), dir / "validation.csv");
  const auto v = run_lpvid(fmt::format("compare --model {} --log {} --out {} --out-png {}", dir / "fit3.json",
                                       dir / "validation.csv", dir / "v.json", dir / "v.png"));
  ASSERT_EQ(v.exit_code, 0) << v.err;
  EXPECT_THAT(v.out, HasSubstr("nothing refitted"));
  EXPECT_THAT(v.out, HasSubstr("the model explains this log"));
  const nlohmann::json vj = nlohmann::json::parse(slurp(dir / "v.json"));
  EXPECT_LE(vj["error_percent"].get<double>(), 1.5 * vj["noise_floor_percent"].get<double>());
  EXPECT_FALSE(vj["refitted"].get<bool>());
  EXPECT_EQ(slurp(dir / "v.png").substr(1, 3), "PNG");
  const auto d0 = run_lpvid(fmt::format("compare --model {} --log {} --json", m0, dir / "validation.csv"));
  ASSERT_EQ(d0.exit_code, 0) << d0.err;
  const nlohmann::json dj = nlohmann::json::parse(d0.out);
  EXPECT_GT(dj["error_percent"].get<double>(), 10.0 * dj["noise_floor_percent"].get<double>());
  EXPECT_FALSE(dj["failing_windows"].empty());
  // what compare --log on a mechanical model does not take: one line, nothing written
  const auto bad = run_lpvid(fmt::format("compare --model {} --log {} --controller {} --out {}", dir / "fit3.json",
                                         dir / "validation.csv", dir / "v.json", dir / "never.json"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_THAT(bad.err, HasSubstr("no controller is needed"));
  EXPECT_FALSE(std::filesystem::exists(dir / "never.json"));
}

// compare checks a model on a log as it was fitted: the smoothing window and the input
// convention the fit used travel in the model file's fit section.  Before, compare
// smoothed with the defaults whatever the fit used, so the same model on the same log
// scored differently in fit and in compare.
TEST(FrictionAxisCli, CompareSmoothsAsTheFitThatWroteTheModel) {
  const TempDir dir("friction_smoothing");
  friction_axis::Experiment e;
  e.seconds = 6.0;
  friction_axis::write_csv(friction_axis::simulate(friction_axis::Truth{}, e), dir / "run.csv");
  const std::string m0 = dir / "axis.json";
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", sample(), m0)).exit_code, 0);
  ASSERT_EQ(run_lpvid(fmt::format("model add coulomb_friction,force_offset --model {}", m0)).exit_code, 0);
  // a window 2.5x the default (0.02 s) and the measured-input convention: both change
  // the figures, so a compare that ignored them would not reproduce the fit's
  const auto f = run_lpvid(fmt::format("fit --model {} --log {} --window-s 0.05 --measured-input --out {} --json", m0,
                                       dir / "run.csv", dir / "fitted.json"));
  ASSERT_EQ(f.exit_code, 0) << f.err;
  const nlohmann::json fj = nlohmann::json::parse(f.out);
  const nlohmann::json section = nlohmann::json::parse(slurp(dir / "fitted.json"))["fit"]["smoothing"];
  EXPECT_EQ(section["window_s"].get<double>(), 0.05);
  EXPECT_EQ(section["input"], "measured");
  const auto c = run_lpvid(fmt::format("compare --model {} --log {} --out {}", dir / "fitted.json", dir / "run.csv",
                                       dir / "c.json"));
  ASSERT_EQ(c.exit_code, 0) << c.err;
  EXPECT_THAT(c.out, HasSubstr("input measured (as the fit that wrote"));
  const nlohmann::json cj = nlohmann::json::parse(slurp(dir / "c.json"));
  // the same model on the same log with the same smoothing: the same figures (the fit's
  // error is the evaluation at its estimate; 1e-9 relative is rounding)
  EXPECT_NEAR(cj["error_percent"].get<double>(), fj["error_percent"].get<double>(),
              1e-9 * fj["error_percent"].get<double>());
  EXPECT_NEAR(cj["noise_floor_percent"].get<double>(), fj["noise_floor_percent"].get<double>(),
              1e-9 * fj["noise_floor_percent"].get<double>());
  EXPECT_EQ(cj["window_samples"], fj["window_samples"]);
  // a model no force-error fit wrote: the defaults, said so
  const auto d = run_lpvid(fmt::format("compare --model {} --log {}", m0, dir / "run.csv"));
  ASSERT_EQ(d.exit_code, 0) << d.err;
  EXPECT_THAT(d.out, HasSubstr("(the defaults: "));
  EXPECT_THAT(d.out, HasSubstr("records no force-error fit"));
  // a record edited wrong: one line with file:line:column, nothing written
  std::string text = slurp(dir / "fitted.json");
  const std::string::size_type at = text.find("\"window_s\": 0.05");
  ASSERT_NE(at, std::string::npos) << text;
  text.replace(at, std::string("\"window_s\": 0.05").size(), "\"window_s\": -1");
  std::ofstream(dir / "bad.json") << text;
  const auto b = run_lpvid(fmt::format("compare --model {} --log {} --out {}", dir / "bad.json", dir / "run.csv",
                                       dir / "never.json"));
  EXPECT_NE(b.exit_code, 0);
  EXPECT_EQ(std::count(b.err.begin(), b.err.end(), '\n'), 1) << b.err;
  EXPECT_THAT(b.err, HasSubstr("bad.json:"));
  EXPECT_THAT(b.err, HasSubstr("fit.smoothing must be"));
  EXPECT_FALSE(std::filesystem::exists(dir / "never.json"));
}

TEST(FrictionAxisCli, BadInputsGetOneLineAndLoseNothing) {
  const TempDir dir("friction_bad");
  friction_axis::Experiment e;
  e.seconds = 3.0;
  friction_axis::write_csv(friction_axis::simulate(friction_axis::Truth{}, e), dir / "run.csv");
  const std::string m0 = dir / "axis.json";
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", sample(), m0)).exit_code, 0);
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", sample(), dir / "axis2.json"))
                .exit_code,
            0);
  ASSERT_EQ(run_lpvid(fmt::format("model add coulomb_friction --model {}", m0)).exit_code, 0);
  const std::string before = slurp(m0);
  auto one_line = [](const lpvid::testing::RunResult& r) {
    EXPECT_NE(r.exit_code, 0);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  };
  // the frequency route refuses a time-only effect, saying what to do
  std::ofstream(dir / "P.csv") << "# outputs: enc\n# inputs: i\nfreq_hz,P_enc_i_re,P_enc_i_im\n1,1e-3,0\n2,2e-4,0\n"
                                   "3,1e-4,0\n4,6e-5,0\n";
  const auto a = run_lpvid(fmt::format("fit --model {} --data {} --noise-level 0.01 --out {}", m0, dir / "P.csv",
                                       dir / "f.json"));
  one_line(a);
  EXPECT_THAT(a.err, HasSubstr("coulomb_friction, a nonlinear time-domain effect"));
  // nor takes one as a candidate
  const auto a2 = run_lpvid(fmt::format("diagnose --model {} --data {} --noise-level 0.01 --candidates force_offset",
                                        dir / "axis2.json", dir / "P.csv"));
  one_line(a2);
  EXPECT_THAT(a2.err, HasSubstr("'force_offset' is a nonlinear time-domain effect"));
  // a log without the base's output column
  std::ofstream(dir / "wrong.csv") << "t,i,x\n0,0,0\n0.001,0,0\n0.002,0,0\n";
  const auto b = run_lpvid(fmt::format("fit --model {} --log {} --out {}", m0, dir / "wrong.csv", dir / "f.json"));
  one_line(b);
  EXPECT_THAT(b.err, HasSubstr("enc"));
  // --method belongs to the stage
  const auto c = run_lpvid(fmt::format("fit --model {} --log {} --method equation --out {}", m0, dir / "run.csv",
                                       dir / "f.json"));
  one_line(c);
  EXPECT_THAT(c.err, HasSubstr("force error"));
  // too short for the window
  const auto d = run_lpvid(fmt::format("fit --model {} --log {} --window-s 1 --out {}", m0, dir / "run.csv",
                                       dir / "f.json"));
  one_line(d);
  EXPECT_THAT(d.err, HasSubstr("--window-s"));
  // a candidate the route has no form for
  const auto g = run_lpvid(fmt::format("diagnose --model {} --log {} --candidates actuator_lag", m0, dir / "run.csv"));
  one_line(g);
  EXPECT_THAT(g.err, HasSubstr("force-error route tries coulomb_friction, force_offset"));
  // --bands is the frequency route's; a figure in a directory that does not exist
  const auto h = run_lpvid(fmt::format("fit --model {} --log {} --bands {} --out {}", m0, dir / "run.csv",
                                       dir / "b.csv", dir / "f.json"));
  one_line(h);
  EXPECT_THAT(h.err, HasSubstr("--plot F.png"));
  const auto k = run_lpvid(fmt::format("diagnose --model {} --log {} --png {} --out {}", m0, dir / "run.csv",
                                       dir / "no/d.png", dir / "f.json"));
  one_line(k);
  EXPECT_THAT(k.err, HasSubstr("--png"));
  // the frequency route's options are refused, not ignored, by name (before, fit --log
  // and diagnose --log took --starts, --band-min, --seed, ... and fitted as without them)
  const auto m = run_lpvid(fmt::format("fit --model {} --log {} --starts 4 --band-min 2 --out {}", m0,
                                       dir / "run.csv", dir / "f.json"));
  one_line(m);
  EXPECT_THAT(m.err, HasSubstr("fit --log: --band-min and --starts are options of the frequency route"));
  EXPECT_THAT(m.err, HasSubstr("drop them"));
  const auto n = run_lpvid(fmt::format("diagnose --model {} --log {} --seed 3 --out {}", m0, dir / "run.csv",
                                       dir / "f.json"));
  one_line(n);
  EXPECT_THAT(n.err, HasSubstr("diagnose --log: --seed is an option of the frequency route"));
  // --weighting too (the force-error route weighs by its own rules); and a value it does not know
  const auto w = run_lpvid(fmt::format("diagnose --model {} --log {} --weighting auto --out {}", m0, dir / "run.csv",
                                       dir / "f.json"));
  one_line(w);
  EXPECT_THAT(w.err, HasSubstr("diagnose --log: --weighting is an option of the frequency route"));
  const auto v = run_lpvid(fmt::format("fit --model {} --log {} --weighting figure --out {}", m0, dir / "run.csv",
                                       dir / "f.json"));
  one_line(v);
  EXPECT_THAT(v.err, HasSubstr("--weighting: figure not in {noise,auto}"));
  // a ripple on a log whose travel holds fewer than three of the shortest period the
  // smoothing passes at its speed (a 2-Hz shake of ±1 cm under a 0.1-s window: 2 cm of
  // travel, 9 mm the shortest period at the median 9 cm/s)
  {
    std::ofstream f(dir / "shake.csv");
    f << "t,i,enc\n";
    for (int k = 0; k < 20000; ++k) {
      const double t = 1e-3 * k, w = 2.0 * M_PI * 2.0;
      f << fmt::format("{},{},{}\n", t, (-3.0 * w * w * 0.01 * std::sin(w * t) + 10.0 * w * 0.01 * std::cos(w * t)) / 10.0,
                       0.01 * std::sin(w * t));
    }
  }
  ASSERT_EQ(run_lpvid(fmt::format("model add position_ripple --model {}", dir / "axis2.json")).exit_code, 0);
  const auto r = run_lpvid(fmt::format("fit --model {} --log {} --window-s 0.1 --out {}", dir / "axis2.json",
                                       dir / "shake.csv", dir / "f.json"));
  one_line(r);
  EXPECT_THAT(r.err, HasSubstr("ripple_period_x_m: the log leaves no range to search"));
  EXPECT_FALSE(std::filesystem::exists(dir / "f.json"));
  EXPECT_FALSE(std::filesystem::exists(dir / "f.json.history.jsonl"));
  EXPECT_EQ(slurp(m0), before);
}

}  // namespace friction_axis_cli_test
}  // namespace lpvid
