// Cross-check of lpvid's stage simulator (`lpvid simulate stage6 --experiment`)
// against the INDEPENDENT stage simulator (tests/support/independent_stage.h: the
// paper's physics written apart from idlib/stage6, quaternion attitude, RK4 at half
// the step).  The same stage (seed 001's design values), the same excitation (the v
// columns of lpvid's noise-free log, replayed), the same controller: the two logs
// must agree.  They do to rounding once the independent simulator is switched to
// one convention of lpvid's simulator (a switch there, default off):
//  1. the controller's velocity: lpvid's law uses the exact velocity of the sensed
//     point at the sample plus the difference of the sensor noise, not the backward
//     difference of the sampled q: off by 1.5 % in the wrench (rms) without the
//     switch (docs/assumptions.md says so);
//  and before t = 0 lpvid's motors hold the first command (the independent one: the
//  hover command), which only changes the first milliseconds.
// This test found two more differences, which were lpvid's physics, not
// conventions, and are fixed in lpvid (the independent simulator keeps switches to
// reproduce them, default off): the back-EMF from the centre of mass's inertial
// velocity instead of each array's own velocity along its forces (the tilt and yaw
// rates times the lever arms: a rotational damping 4 b r^2 ~ 1.8 N·m·s/rad on the
// tilts; 20-80 % apart in q), and, with a centre-of-mass offset c, the sensors at
// p_cm - c instead of the reference point p_cm - R c (0.4-0.7 % apart in x, y).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/independent_stage.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace indep_stage_crosscheck_test {

using testing::run_lpvid;
using testing::TempDir;

struct Csv {
  Eigen::MatrixXd v, u, q;
};

Csv read_log(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::vector<std::vector<double>> rows;
  bool header = false;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    if (!header) {
      header = true;
      continue;
    }
    std::vector<double> r;
    std::stringstream ss(line);
    std::string tok;
    while (std::getline(ss, tok, ',')) r.push_back(std::stod(tok));
    rows.push_back(r);
  }
  Csv c;
  const auto n = static_cast<Eigen::Index>(rows.size());
  c.v.resize(n, 6);
  c.u.resize(n, 6);
  c.q.resize(n, 6);
  for (Eigen::Index k = 0; k < n; ++k)
    for (int j = 0; j < 6; ++j) {
      c.v(k, j) = rows[k][1 + j];
      c.u(k, j) = rows[k][7 + j];
      c.q(k, j) = rows[k][13 + j];
    }
  return c;
}

// Largest over the six channels of rms(q_indep - q_lpvid) / rms(q_lpvid - mean).
double relative_difference(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  double worst = 0;
  for (int j = 0; j < 6; ++j) {
    const Eigen::VectorXd centred = b.col(j).array() - b.col(j).mean();
    worst = std::max(worst, (a.col(j) - b.col(j)).norm() / centred.norm());
  }
  return worst;
}

struct Case {
  const char* name;
  const char* flags;
};

class IndepStageCrossCheck : public ::testing::TestWithParam<Case> {};

TEST_P(IndepStageCrossCheck, AgreesWithLpvidSimulator) {
  const Case c = GetParam();
  TempDir dir("xcheck");
  const auto r = run_lpvid("simulate stage6 --experiment --hover --duration-s 2 --noise-scale 0 --seed 3 " +
                           std::string(c.flags) + " --out " + dir.path().string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Csv lp = read_log(dir / "exp_stage6.csv");
  ASSERT_EQ(lp.q.rows(), 2001);

  // Seed 001's design values as docs/assumptions.md lists them.
  indep_stage::Stage s;
  s.arms_m = indep_stage::pinwheel_arms(0.075, 0.075, 0.015);
  const std::string name = c.name;
  if (name == "gap") s.gap = true, s.gamma_per_m = 2 * M_PI / 0.0256;
  if (name == "lag") s.lag = true;  // R 1.5 ohm, L 5 mH, k_c 3.5 V/A, k_f 20 N/A: the defaults of both
  if (name == "com") s.com_offset_m = Eigen::Vector3d(1e-4, -1e-4, 1e-3);
  if (name == "delay") s.input_delay_s = 0.5e-3;
  if (name == "kappa") s.kappa = 1.01;
  indep_stage::Controller ctl;
  ctl.arms_m = s.arms_m;
  indep_stage::Experiment e;
  e.settle_s = 0;
  e.noise_std.setZero();
  e.replay_excitation = lp.v;

  // lpvid's convention (the header's 1):
  ctl.true_velocity = true;
  e.history_from_first_command = true;
  const indep_stage::Log mine = indep_stage::run(s, ctl, e);
  // Tolerance: the two integrators differ (quaternion RK4 at 50 us, lpvid's RK4 at
  // 100 us); measured 1e-14 without the current loop and 1e-8 with it (its 1 ms time
  // constant is the stiffest mode): 1e-6 leaves room for rounding and still fails on
  // any modelling difference (the smallest found above was 4e-3).
  EXPECT_LT(relative_difference(mine.q, lp.q), 1e-6) << c.name;
  EXPECT_LT(relative_difference(mine.u, lp.u), 1e-6) << c.name;

  // The independent controller as written (the header's 1 off) differs; how much is
  // recorded, not asserted: the size depends on the excitation.
  ctl.true_velocity = false;
  const indep_stage::Log physical = indep_stage::run(s, ctl, e);
  std::printf("%s: independent vs lpvid, lpvid's conventions %.2g, independent physics %.2g (rms, relative, worst channel)\n",
              c.name, relative_difference(mine.q, lp.q), relative_difference(physical.q, lp.q));
}

INSTANTIATE_TEST_SUITE_P(Effects, IndepStageCrossCheck,
                         ::testing::Values(Case{"none", ""}, Case{"kappa", "--force-constant-scale 1.01"},
                                           Case{"gap", "--effects gap"}, Case{"lag", "--effects lag"},
                                           Case{"com", "--com-offset-mm 0.1,-0.1,1"},
                                           Case{"delay", "--input-delay-ms 0.5"}),
                         [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.name); });

}  // namespace indep_stage_crosscheck_test
}  // namespace lpvid
