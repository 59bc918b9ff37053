// A stage lpvid has no base for, through the program: the user's description
// (samples/mechanical/two_mass_axis.json) -> model init -> fit on FRD data written
// from the independent oracle of tests/support/two_mass_axis.h -> diagnose names the
// missing structural mode; and the description's bad inputs.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <complex>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "formats/io/physical_model_json.h"
#include "idlib/lti/frequency_response.h"
#include "tests/support/run_lpvid.h"
#include "tests/support/two_mass_axis.h"

namespace lpvid {
namespace mechanical_cli_test {

using ::testing::HasSubstr;
using lpvid::testing::count_files;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;
using two_mass_axis::AxisValues;
using two_mass_axis::oracle;

std::string sample() { return std::string(LPVID_SOURCE_DIR) + "/samples/mechanical/two_mass_axis.json"; }

// The truth: the design (the sample's values) off by 20–40 %, and optionally a
// collocated mode at 900 rad/s (shape 0.15, 0.25; zeta 0.02).
constexpr AxisValues kTruth{2.0, 6.5, 1.6e5, 55.0, 24.0, 12.0};

// An FRD CSV by hand (freq_hz, P_<out>_<in>_re/_im, named axes): no lpvid code writes it.
// modes: 0 none, 1 the mode at 900 rad/s, 2 also a second at 2200 rad/s (zeta 0.01,
// shape 0.1, -0.2), added here as phi phiᵀ B_w / (w2² − w² + 2j zeta w2 w).
void write_oracle_frd(const std::filesystem::path& path, int modes) {
  std::ofstream f(path);
  f << "# outputs: enc,load\n# inputs: i\nfreq_hz,P_enc_i_re,P_enc_i_im,P_load_i_re,P_load_i_im\n";
  const Eigen::VectorXd w = log_frequency_grid(5.0, 4000.0, 200);
  for (Index k = 0; k < w.size(); ++k) {
    Eigen::Vector2cd p = modes >= 1 ? oracle(kTruth, w(k), 0.15, 0.25, 900.0, 0.02) : oracle(kTruth, w(k));
    if (modes >= 2) {
      const double w2 = 2200.0, z2 = 0.01, phi_m = 0.1, phi_l = -0.2;
      const std::complex<double> eta =
          phi_m * kTruth.kf / (w2 * w2 - w(k) * w(k) + std::complex<double>(0.0, 2.0 * z2 * w2 * w(k)));
      p(0) += phi_m * eta;
      p(1) += phi_l * eta;
    }
    f << fmt::format("{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}\n", w(k) / (2 * 3.141592653589793), p(0).real(),
                     p(0).imag(), p(1).real(), p(1).imag());
  }
}

TEST(MechanicalCli, InitFitAndDiagnoseAStageOfTheUsersOwn) {
  const TempDir dir("mech_cli");
  const auto model = dir / "axis_model.json";
  const auto r0 = run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", sample(), model));
  ASSERT_EQ(r0.exit_code, 0) << r0.err;
  EXPECT_THAT(r0.out, HasSubstr("base mechanical"));
  EXPECT_THAT(slurp(model), HasSubstr("\"mechanical\": {"));
  // the rigid structure alone fits the mode-free data to the oracle's precision
  write_oracle_frd(dir / "P.csv", 0);
  const auto fitted = dir / "fit1.json";
  const auto r1 = run_lpvid(fmt::format("fit --model {} --data {} --noise-level 0.01 --out {}", model,
                                        (dir / "P.csv"), fitted));
  ASSERT_EQ(r1.exit_code, 0) << r1.err;
  const PhysicalModel m1 = read_physical_model(fitted);
  // noise-free data: 1e-4 relative is the fit's own convergence, far inside
  EXPECT_NEAR(m1.parameter("m_load_kg").value, kTruth.ml, 1e-4 * kTruth.ml);
  EXPECT_NEAR(m1.parameter("k_coupling_N_per_m").value, kTruth.k, 1e-4 * kTruth.k);
  // with an unmodelled mode, diagnose names structural_mode and the error falls
  write_oracle_frd(dir / "Pm.csv", 1);
  const auto r2 = run_lpvid(fmt::format("fit --model {} --data {} --noise-level 0.01 --out {}", model,
                                        (dir / "Pm.csv"), (dir / "fit2.json")));
  ASSERT_EQ(r2.exit_code, 0) << r2.err;
  const auto r3 = run_lpvid(fmt::format("diagnose --model {} --data {} --noise-level 0.01 --json",
                                        (dir / "fit2.json"), (dir / "Pm.csv")));
  ASSERT_EQ(r3.exit_code, 0) << r3.err;
  const nlohmann::json d = nlohmann::json::parse(r3.out);
  ASSERT_TRUE(d["missing"].is_string()) << r3.out.substr(0, 3000);
  EXPECT_EQ(d["missing"].get<std::string>(), "structural_mode") << r3.out.substr(0, 3000);
  EXPECT_TRUE(d["explained"].get<bool>());
}

TEST(MechanicalCli, TwoUnmodelledModesAreNamedTogether) {
  // Two modes of similar size: neither alone leaves only noise (the better one leaves
  // 21.7 % of 32.9 %: "one of several modes"), so diagnose tries the anchor mode with the
  // next one, fitted from the anchor's fit and seeded at what it leaves, and names the pair.
  const TempDir dir("mech_modes");
  const auto model = dir / "m.json";
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", sample(), model)).exit_code, 0);
  write_oracle_frd(dir / "P2.csv", 2);
  const std::string data = fmt::format("--data {} --noise-level 0.01", dir / "P2.csv");
  const auto fit = run_lpvid(fmt::format("fit --model {} {} --out {}", model, data, dir / "fit.json"));
  ASSERT_EQ(fit.exit_code, 0) << fit.err;
  const auto r = run_lpvid(
      fmt::format("diagnose --model {} {} --json --out {}", dir / "fit.json", data, dir / "modes.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json d = nlohmann::json::parse(r.out);
  EXPECT_EQ(d["missing_effects"], nlohmann::json({"structural_mode", "structural_mode_2"})) << r.out.substr(0, 3000);
  EXPECT_TRUE(d["explained"].get<bool>());
  for (const auto& c : d["candidates"])
    if (c["effect"] == "structural_mode")
      std::printf("two hidden modes: baseline %.3g %%, the better single mode %.3g %% (%s)\n",
                  100 * d["baseline"]["error"].get<double>(), 100 * c["error"].get<double>(),
                  c["verdict"].get<std::string>().c_str());
  const PhysicalModel m2 = read_physical_model(dir / "modes.json");
  // both modes at their true frequencies; 1e-4 relative: noise-free data, the fit's convergence
  std::vector<double> found{m2.parameter("mode_frequency_rad_s").value, m2.parameter("mode_2_frequency_rad_s").value};
  std::sort(found.begin(), found.end());
  EXPECT_NEAR(found[0], 900.0, 0.09);
  EXPECT_NEAR(found[1], 2200.0, 0.22);
  // a third is offered next, not before: modes are added one after the other
  EXPECT_THAT(m2.absent_effects(), ::testing::Contains("structural_mode_3"));
  EXPECT_THAT(m2.absent_effects(), ::testing::Not(::testing::Contains("structural_mode_4")));
}

// The bundled sample (samples/mechanical-loop.sh): the axis's response with two hidden
// modes under 0.5 % noise (samples/mechanical/make_p_axis.py).  The modes' largest
// error shows well above them (the load's response falls as 1/w²: the 2200 rad/s
// mode is seen at 3270 rad/s), so diagnose seeds a mode from a scan of the residual,
// not from where the error peaks; before that seed, the pair ended with its second
// mode's damping and shape on their bounds at 21 % error.
TEST(MechanicalCli, TheSampleLoopReachesTheNoiseFloor) {
  const TempDir dir("mech_sample");
  const std::string data =
      fmt::format("--data {}/samples/mechanical/P_axis.csv --noise-level 0.005", std::string(LPVID_SOURCE_DIR));
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", sample(), dir / "m.json")).exit_code,
            0);
  ASSERT_EQ(run_lpvid(fmt::format("fit --model {} {} --out {}", dir / "m.json", data, dir / "fit1.json")).exit_code, 0);
  const auto r = run_lpvid(
      fmt::format("diagnose --model {} {} --json --out {}", dir / "fit1.json", data, dir / "step2.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json d = nlohmann::json::parse(r.out);
  EXPECT_EQ(d["missing_effects"], nlohmann::json({"structural_mode", "structural_mode_2"})) << r.out.substr(0, 3000);
  const auto f = run_lpvid(fmt::format("fit --model {} {} --out {} --json", dir / "step2.json", data, dir / "fit2.json"));
  ASSERT_EQ(f.exit_code, 0) << f.err;
  const nlohmann::json j = nlohmann::json::parse(f.out);
  // within 1.5x the stated floor (diagnose's "explained"); seen: 0.496 % for 0.5 %
  EXPECT_LT(j["error"].get<double>(), 1.5 * 0.005) << f.out.substr(0, 2000);
  // the truth (make_p_axis.py) within 3 reported standard errors
  const PhysicalModel m = read_physical_model(dir / "fit2.json");
  const nlohmann::json fit = nlohmann::json::parse(slurp(dir / "fit2.json"))["fit"]["parameters"];
  for (const auto& [name, truth] : std::vector<std::pair<std::string, double>>{
           {"m_load_kg", 6.5}, {"k_coupling_N_per_m", 1.6e5}, {"c_coupling_Ns_per_m", 55.0}, {"c_guide_Ns_per_m", 24.0}})
    EXPECT_LT(std::abs(m.parameter(name).value - truth), 3.0 * fit[name]["std_error"].get<double>()) << name;
}

TEST(MechanicalCli, BadDescriptionsFailAtTheirKeyAndWriteNothing) {
  const TempDir dir("mech_bad");
  std::string text = slurp(sample());
  const std::string good = "\"stiffness\": [[\"k_coupling_N_per_m\", ";
  ASSERT_NE(text.find(good), std::string::npos);
  text.replace(text.find(good), good.size(), "\"stiffness\": [[\"k_coupling_N_per_m k\", ");
  {
    std::ofstream f(dir / "bad.json");
    f << text;
  }
  const auto r = run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", (dir / "bad.json"),
                                       (dir / "m.json")));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("bad.json:20:3: mechanical base: 'stiffness': expression"));
  EXPECT_THAT(r.err, HasSubstr("expected + or - between terms"));
  EXPECT_EQ(count_files(dir.path()), 1);  // bad.json alone: nothing written
  const auto r2 = run_lpvid(fmt::format("model init --base mechanical --out {}", (dir / "m.json")));
  EXPECT_EQ(r2.exit_code, 2);
  EXPECT_THAT(r2.err, HasSubstr("--from DESCRIPTION.json"));
  const auto r3 = run_lpvid(fmt::format("model init --from {} --out {}", sample(), (dir / "m.json")));
  EXPECT_EQ(r3.exit_code, 2);
  EXPECT_THAT(r3.err, HasSubstr("goes with --base mechanical"));
  EXPECT_EQ(count_files(dir.path()), 1);
}

}  // namespace mechanical_cli_test
}  // namespace lpvid
