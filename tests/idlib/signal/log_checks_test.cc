// idlib/signal/log_checks.h: saturation and drift found where they are, and not in the
// signals identification logs are made of (multisines repeated period by period, PRBS,
// quantised noise, stationary coloured noise).  The truths are the signals as built here.
#include <gtest/gtest.h>

#include <vector>

#include <fmt/format.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>
#include <numbers>
#include <random>

#include "idlib/signal/log_checks.h"

namespace lpvid {
namespace log_checks_test {

using Kind = ChannelFinding::Kind;

Eigen::VectorXd white(Index n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> d(0.0, 1.0);
  Eigen::VectorXd x(n);
  for (Index t = 0; t < n; ++t) x(t) = d(rng);
  return x;
}

// A designed dwell: an encoder (1 µm counts) following a reference that moves between
// 0 and 0.2 m and rests at each end (point-to-point).  Alone it looks clipped at both
// rails; with the log's reference as context (resting where the encoder sits) it is a
// rest, not a clip.  The clipped sine of the next test stays a finding with a varying
// context column (its drive keeps moving while it sits at the rail).
TEST(LogChecks, ADwellWhereTheLogsReferenceRestsIsNotAClip) {
  const Index n = 6000;
  const Eigen::VectorXd noise = white(n, 5);
  Eigen::MatrixXd log(n, 3);  // t, reference, encoder
  for (Index t = 0; t < n; ++t) {
    const double tau = std::fmod(static_cast<double>(t) * 1e-3, 2.0);  // 0.5 s rest, 0.5 s move, each way
    const double s = std::clamp((tau < 1.0 ? tau - 0.5 : 1.5 - tau) / 0.5, 0.0, 1.0);
    const double r = tau < 1.0 ? (tau < 0.5 ? 0.0 : 0.2 * s * s * s * (10 - 15 * s + 6 * s * s))
                               : (tau < 1.5 ? 0.2 : 0.2 * s * s * s * (10 - 15 * s + 6 * s * s));
    log(t, 0) = static_cast<double>(t) * 1e-3;
    log(t, 1) = r;
    // the axis settles a count short of the reference's end, with a count of noise while moving
    const double moving = (r > 0.0 && r < 0.2) ? 1e-6 * noise(t) : 0.0;
    log(t, 2) = std::round(std::clamp(r - 0.5e-6 + moving, 0.0, 0.2) / 1e-6) * 1e-6;
  }
  const Eigen::MatrixXd enc = log.col(2);
  ASSERT_FALSE(inspect_channels(enc).empty());          // alone: "clipped, or a designed dwell"
  EXPECT_TRUE(inspect_channels(enc, &log).empty());     // the reference rests there: a rest

  // a clipped sine with a varying second column in the context: still found
  Eigen::MatrixXd clipped(4000, 2);
  const Eigen::VectorXd w = white(4000, 3);
  for (Index t = 0; t < 4000; ++t) {
    clipped(t, 1) = std::sin(2 * std::numbers::pi * 3.0 * static_cast<double>(t) * 1e-3) + 0.01 * w(t);
    clipped(t, 0) = std::clamp(clipped(t, 1), -0.8, 0.8);
  }
  const Eigen::MatrixXd y = clipped.col(0);
  EXPECT_EQ(inspect_channels(y, &clipped).size(), 2u);
}

TEST(LogChecks, AClippedSignalIsFoundAtItsRailsWithItsRows) {
  // A 3 Hz sine at 1 kHz plus 1 % noise, clipped at +-0.8 (an amplifier's limit).
  const Index n = 4000;
  const Eigen::VectorXd noise = white(n, 3);
  Eigen::MatrixXd x(n, 1);
  Index above = 0, below = 0, first_above = -1, last_above = -1;
  for (Index t = 0; t < n; ++t) {
    const double raw = std::sin(2 * std::numbers::pi * 3.0 * static_cast<double>(t) * 1e-3) + 0.01 * noise(t);
    if (raw >= 0.8) {
      ++above;
      if (first_above < 0) first_above = t;
      last_above = t;
    }
    below += raw <= -0.8;
    x(t, 0) = std::clamp(raw, -0.8, 0.8);
  }
  const auto found = inspect_channels(x);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(found[0].kind, Kind::kSaturatedHigh);
  EXPECT_EQ(found[0].samples, above);
  EXPECT_EQ(found[0].first_row, first_above);
  EXPECT_EQ(found[0].last_row, last_above);
  EXPECT_EQ(found[0].value, 0.8);
  EXPECT_EQ(found[1].kind, Kind::kSaturatedLow);
  EXPECT_EQ(found[1].samples, below);
  EXPECT_EQ(found[1].value, -0.8);
  const std::string text = describe_finding(found[0], "u");
  EXPECT_NE(text.find("channel u sits at its maximum 0.8"), std::string::npos) << text;
  EXPECT_NE(text.find(fmt::format("rows {}..{}", first_above + 1, last_above + 1)), std::string::npos) << text;
}

TEST(LogChecks, DesignedExcitationsAreNotCalledSaturated) {
  const Index L = 1024, P = 8;
  Eigen::MatrixXd x(L * P, 3);
  // (1) a multisine repeated bit for bit: its peak recurs once per period.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> phase(0.0, 2 * std::numbers::pi);
  Eigen::VectorXd period = Eigen::VectorXd::Zero(L);
  for (int k = 1; k <= 60; ++k) {
    const double ph = phase(rng);
    for (Index t = 0; t < L; ++t) period(t) += std::cos(2 * std::numbers::pi * k * static_cast<double>(t) / L + ph);
  }
  for (Index p = 0; p < P; ++p) x.block(p * L, 0, L, 1) = period;
  // (2) a PRBS-like binary signal: runs at both levels, nothing between them.
  std::bernoulli_distribution coin(0.5);
  for (Index t = 0; t < x.rows(); ++t) x(t, 1) = coin(rng) ? 1.0 : -1.0;
  // (3) Gaussian noise quantised to 0.05 of its rms (a 16-bit converter's steps on a
  //     small signal): its extreme levels are thin tails.
  const Eigen::VectorXd w = white(x.rows(), 7);
  for (Index t = 0; t < x.rows(); ++t) x(t, 2) = 0.05 * std::round(w(t) / 0.05);
  // (4) a slow motion on a fine encoder that sticks as it reverses: 0.13 m at 0.4 Hz,
  //     1 kHz, 1 µm counts, the axis held 5 samples at each turning point (friction) —
  //     the encoder holds its top count 3.5 times as long as the next (28 samples against
  //     8: the old next-level rule called it clipped, as it did 8 against 2 on the
  //     sample's two-sine log), but less than twice as long as the three counts below it
  //     together (16), where a clip's rail outlasts them 3 times over.
  x.conservativeResize(Eigen::NoChange, 4);
  {
    std::vector<double> enc;
    for (Index t = 0; static_cast<Index>(enc.size()) < x.rows(); ++t) {
      const double v = 1e-6 * std::round(0.13 * std::sin(2 * std::numbers::pi * 0.4 * static_cast<double>(t) * 1e-3 + 0.3) / 1e-6);
      enc.push_back(v);
      const bool turning = std::abs(v) >= 0.13 - 0.5e-6 && (enc.size() < 2 || enc[enc.size() - 2] != v);
      for (int k = 0; turning && k < 5; ++k) enc.push_back(v);
    }
    for (Index t = 0; t < x.rows(); ++t) x(t, 3) = enc[static_cast<std::size_t>(t)];
  }
  const auto found = inspect_channels(x);
  for (const auto& f : found) ADD_FAILURE() << describe_finding(f, std::to_string(f.channel));
}

TEST(LogChecks, ADriftIsFoundAndStationaryNoiseIsNot) {
  const Index n = 100'000;
  const Eigen::VectorXd w = white(n, 11);
  Eigen::MatrixXd x(n, 3);
  double ar = 0.0, walk = 0.0;
  for (Index t = 0; t < n; ++t) {
    ar = 0.99 * ar + w(t);  // coloured, correlation time 100 samples: stationary
    walk += 0.05 * w(t);
    x(t, 0) = ar;
    x(t, 1) = walk;
    x(t, 2) = 0.3 * w(t) + 2.0 * static_cast<double>(t) / static_cast<double>(n - 1);  // a ramp of 2 in noise
  }
  const auto found = inspect_channels(x);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(found[0].kind, Kind::kDrift);
  EXPECT_EQ(found[0].channel, 1);  // the random walk
  EXPECT_EQ(found[1].channel, 2);
  // The ramp's change is 2; the fitted line's error is about 0.3 sqrt(12 / n) = 0.003.
  EXPECT_NEAR(found[1].value, 2.0, 0.02);
  // White noise of 1000 samples: the fitted trend's change is about sqrt(12 / 1000) = 0.11
  // of its rms, far below 1.
  EXPECT_TRUE(inspect_channels(white(1000, 13)).empty());
}

}  // namespace log_checks_test
}  // namespace lpvid
