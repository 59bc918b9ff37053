#include "idlib/realization/era.h"

#include <gtest/gtest.h>

#include "idlib/core/error.h"
#include "idlib/realization/hankel.h"
#include "test_systems.h"

namespace lpvid {
namespace era_test {

using testing::Mode;

// Exact Markov parameters: ERA is exact up to rounding amplified by the weakest
// Hankel singular value (~1e-3 of the largest here): measured ~1e-12.
constexpr double kExactResponseTolerance = 1e-8;
// Noise-free but slow (|1 - z| < 0.006) and strided: measured ~1e-10.
constexpr double kSlowExactTolerance = 1e-6;
// Noisy Markov parameters (std 3e-4 of the peak entry): measured 0.2-0.6 %.
constexpr double kNoisyResponseTolerance = 0.02;
constexpr std::uint64_t kSystemSeed = 7;
constexpr std::uint64_t kNoiseSeeds[] = {101, 202, 303, 404, 505};

// Closed-loop-like order 9: three plant resonances and three weak, slow real
// modes (the PI controller states), smallest Hankel singular value ~5e-3 of the largest.
std::vector<Mode> closed_loop_modes() {
  return {{{-20, 40}, 1}, {{-35, 80}, 1}, {{-60, 150}, 1}, {{-2, 0}, 0.03}, {{-5, 0}, 0.03}, {{-9, 0}, 0.03}};
}

EraOptions options_for(double sample_period_s) {
  EraOptions o;
  o.sample_period_s = sample_period_s;
  return o;
}

TEST(Era, ExactMarkovOfOrder6GivenOrderRecoversResponseAndMarkov) {
  const StateSpace sys = testing::modal_system({{{-50, 200}, 1}, {{-80, 700}, 1}, {{-30, 0}, 1}, {{-300, 0}, 1}}, 1e-3,
                                               3, 3, kSystemSeed);
  EraOptions o = options_for(1e-3);
  o.order = 6;
  const EraResult r = realize_era(testing::markov_of(sys, 400), o);
  EXPECT_EQ(r.model.order(), 6);
  EXPECT_EQ(r.selection.rule, "given");
  EXPECT_LT(testing::response_error(r.model, sys, testing::frequency_grid(1.0, 1e-3)), kExactResponseTolerance);
  EXPECT_LT(testing::markov_error(r.model, sys, 400), kExactResponseTolerance);
}

TEST(Era, ExactMarkovOfOrder9AutomaticOrderIs9) {
  const StateSpace sys = testing::modal_system(closed_loop_modes(), 1e-3, 3, 3, kSystemSeed);
  EraOptions o = options_for(1e-3);
  o.markov_noise_std = Eigen::MatrixXd::Zero(3, 3);
  const EraResult r = realize_era(testing::markov_of(sys, 3000), o);
  EXPECT_EQ(r.selection.order, 9);
  EXPECT_EQ(r.selection.rule, "noise-floor");
  EXPECT_GE(r.selection.singular_values.size(), 41);
  EXPECT_LT(testing::response_error(r.model, sys, testing::frequency_grid(0.5, 1e-3)), kExactResponseTolerance);
  EXPECT_LT(testing::markov_error(r.model, sys, 3000), kExactResponseTolerance);
  EXPECT_TRUE(r.report.warnings.empty());
}

TEST(Era, PaperEq13WithBAndCSwappedGivesWrongResponse) {
  // Eq (13) as printed: B = U_n S^1/2, C = S^1/2 V_n^T (swapped, not cut).  For a
  // square 3x3 system cut to one block it has the right shapes, and still fails.
  const StateSpace sys = testing::modal_system({{{-50, 200}, 1}, {{-80, 700}, 1}, {{-30, 0}, 1}, {{-300, 0}, 1}}, 1e-3,
                                               3, 3, kSystemSeed);
  const MarkovSequence g = testing::markov_of(sys, 400);
  EraOptions o = options_for(1e-3);
  o.order = 6;
  o.input_scale = o.output_scale = Eigen::VectorXd::Ones(3);
  const EraResult right = realize_era(g, o);
  const Eigen::MatrixXd H = block_hankel(g, right.block_rows, right.block_cols, 1, right.stride);
  const PartialSvd svd = leading_svd(H, 6);
  const Eigen::VectorXd sq = svd.singular_values.cwiseSqrt();
  StateSpace printed = right.model;
  printed.B = (svd.U * sq.asDiagonal()).topRows(3).transpose();      // U_n S^1/2 "as B", cut
  printed.C = (sq.asDiagonal() * svd.V.transpose()).leftCols(3).transpose();  // S^1/2 V_n^T "as C", cut
  EXPECT_EQ((svd.U * sq.asDiagonal()).rows(), H.rows());  // uncut, eq (13)'s B has Hankel rows, not n
  EXPECT_GT(testing::response_error(printed, sys, testing::frequency_grid(1.0, 1e-3)), 0.1);
  EXPECT_LT(testing::response_error(right.model, sys, testing::frequency_grid(1.0, 1e-3)), kExactResponseTolerance);
}

// Output 0 in metres, 50x smaller than the others, with its noise 50x smaller
// too; each output sees mostly its own three modes.
constexpr double kSmallChannelFactor = 1.0 / 50.0;  // metres beside radians
constexpr double kSmallChannelNoise = 1e-3;          // std relative to the peak of the large channels
struct SmallChannelCase {
  StateSpace sys;
  MarkovSequence g;
  Eigen::MatrixXd noise_std;
};
SmallChannelCase small_channel_case(std::uint64_t noise_seed) {
  SmallChannelCase c;
  const double T = 1e-3;
  // Three decoupled 1-output, 3-input subsystems of order 3; output i sees only
  // subsystem i, so output 0's modes live in the small channel alone.
  const std::vector<std::vector<Mode>> parts = {
      {{{-20, 40}, 1}, {{-9, 0}, 1}}, {{{-35, 80}, 1}, {{-5, 0}, 1}}, {{{-60, 150}, 1}, {{-2, 0}, 1}}};
  c.sys.A = Eigen::MatrixXd::Zero(9, 9);
  c.sys.B.resize(9, 3);
  c.sys.C = Eigen::MatrixXd::Zero(3, 9);
  c.sys.D = Eigen::MatrixXd::Zero(3, 3);
  c.sys.sample_period_s = T;
  for (Index i = 0; i < 3; ++i) {
    const StateSpace part = testing::modal_system(parts[static_cast<std::size_t>(i)], T, 1, 3, kSystemSeed + i, false);
    c.sys.A.block(3 * i, 3 * i, 3, 3) = part.A;
    c.sys.B.middleRows(3 * i, 3) = part.B;
    c.sys.C.block(i, 3 * i, 1, 3) = part.C;
  }
  c.sys.C.row(0) *= kSmallChannelFactor;
  c.g = testing::markov_of(c.sys, 3000);
  const double level = kSmallChannelNoise * testing::peak_entries(c.g).bottomRows(2).maxCoeff();
  c.noise_std = Eigen::MatrixXd::Constant(3, 3, level);
  c.noise_std.row(0) *= kSmallChannelFactor;
  c.g = testing::add_noise(c.g, c.noise_std, noise_seed);
  return c;
}

TEST(Era, ScaledChannelsKeepTheOrderAndTheSmallChannelAccurate) {
  const SmallChannelCase c = small_channel_case(kNoiseSeeds[0]);
  EraOptions o = options_for(1e-3);
  o.markov_noise_std = c.noise_std;
  o.output_scale = Eigen::Vector3d(kSmallChannelFactor, 1.0, 1.0);
  o.input_scale = Eigen::VectorXd::Ones(3);
  const EraResult scaled = realize_era(c.g, o);
  EXPECT_EQ(scaled.selection.order, 9) << scaled.selection.reason;
  EXPECT_LT(testing::response_error(scaled.model, c.sys, testing::frequency_grid(0.5, 1e-3), 0), kNoisyResponseTolerance);

  o.output_scale = Eigen::VectorXd::Ones(3);  // unscaled
  const EraResult unscaled = realize_era(c.g, o);
  EXPECT_LT(unscaled.selection.order, 9) << unscaled.selection.reason;
}

TEST(Era, DerivedScalesAlsoKeepTheOrder) {
  const SmallChannelCase c = small_channel_case(kNoiseSeeds[1]);
  EraOptions o = options_for(1e-3);
  o.markov_noise_std = c.noise_std;
  const EraResult r = realize_era(c.g, o);
  EXPECT_EQ(r.selection.order, 9);
  EXPECT_LT(r.output_scale(0), 0.1 * r.output_scale(1));
}

// Plain largest-gap rule over 1..max_order, for comparison.
Index largest_gap_order(const Eigen::VectorXd& s, Index max_order) {
  Index best = 1;
  for (Index n = 1; n <= max_order && n < s.size(); ++n)
    if (s(n - 1) / s(n) > s(best - 1) / s(best)) best = n;
  return best;
}

void expect_order_9_across_seeds(double sample_period_s, double relative_noise, bool given_noise,
                                 bool expect_gap_rule_fails) {
  const StateSpace sys = testing::modal_system(closed_loop_modes(), sample_period_s, 3, 3, kSystemSeed, false);
  const Index last_lag = static_cast<Index>(3.0 / sample_period_s);
  const MarkovSequence exact = testing::markov_of(sys, last_lag);
  const Eigen::MatrixXd noise_std = Eigen::MatrixXd::Constant(3, 3, relative_noise * testing::peak_entries(exact).maxCoeff());
  bool gap_rule_failed = false;
  for (std::uint64_t seed : kNoiseSeeds) {
    EraOptions o = options_for(sample_period_s);
    if (given_noise) o.markov_noise_std = noise_std;
    o.estimate_feedthrough = false;
    const EraResult r = realize_era(testing::add_noise(exact, noise_std, seed), o);
    EXPECT_EQ(r.selection.order, 9) << "seed " << seed << ": " << r.selection.reason;
    EXPECT_LT(testing::response_error(r.model, sys, testing::frequency_grid(0.5, sample_period_s)),
              kNoisyResponseTolerance)
        << "seed " << seed;
    if (largest_gap_order(r.selection.singular_values, o.max_order) != 9) gap_rule_failed = true;
  }
  if (expect_gap_rule_fails) {
    EXPECT_TRUE(gap_rule_failed);
  }
}

TEST(Era, NoisyMarkovAt1kHzAutomaticOrderIs9AcrossSeedsWhereLargestGapFails) {
  expect_order_9_across_seeds(1e-3, 3e-4, true, true);
}

TEST(Era, NoisyMarkovAt10kHzStridedAutomaticOrderIs9AcrossSeeds) {
  expect_order_9_across_seeds(1e-4, 3e-4, true, false);
}

TEST(Era, NoiseEstimatedFromTheTailStillGivesOrder9) {
  expect_order_9_across_seeds(1e-3, 3e-4, false, false);
}

// Continuous poles -2..-60 rad/s at 10 kHz: z within 0.006 of 1.
std::vector<Mode> slow_modes() {
  return {{{-2, 0}, 1}, {{-6, 25}, 1}, {{-15, 0}, 1}, {{-30, 50}, 1}, {{-60, 0}, 1}};
}

// also_orders realises further orders from the same SVD: each must equal a separate
// realisation at that order (the truth here is realize_era itself with `order` set, whose
// accuracy the tests above pin against the system), and the exact order among them must
// reproduce the system; an order the Hankel matrix cannot hold comes back empty.
TEST(Era, AlsoOrdersEqualSeparateRealisationsFromOneSvd) {
  const double T = 1e-4;
  const StateSpace sys = testing::modal_system(slow_modes(), T, 3, 3, kSystemSeed);
  const MarkovSequence g = testing::markov_of(sys, 30000);
  EraOptions o = options_for(T);
  o.order = 3;
  o.max_order = 9;
  o.also_orders = {5, 7, 9};
  const EraResult r = realize_era(g, o);
  ASSERT_EQ(r.models_at.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    EraOptions single = options_for(T);
    single.order = o.also_orders[i];
    single.max_order = 9;
    const EraResult s = realize_era(g, single);
    ASSERT_EQ(r.models_at[i].order(), s.model.order());
    EXPECT_EQ((r.models_at[i].A - s.model.A).norm(), 0.0) << "order " << o.also_orders[i];
    EXPECT_EQ((r.models_at[i].B - s.model.B).norm(), 0.0);
    EXPECT_EQ((r.models_at[i].C - s.model.C).norm(), 0.0);
  }
  EXPECT_LT(testing::response_error(r.models_at[1], sys, testing::frequency_grid(0.1, T)), kSlowExactTolerance);
  EraOptions bad = o;
  bad.also_orders = {10};
  EXPECT_THROW(realize_era(g, bad), InputError);
}

TEST(Era, StridedHankelOnSlow10kHzDataRecoversResponseWithAndWithoutLagSums) {
  const double T = 1e-4;
  const StateSpace sys = testing::modal_system(slow_modes(), T, 3, 3, kSystemSeed);
  const MarkovSequence g = testing::markov_of(sys, 30000);
  for (bool sums : {true, false}) {
    EraOptions o = options_for(T);
    o.order = 7;
    o.sum_stride_lags = sums;
    const EraResult r = realize_era(g, o);
    EXPECT_GT(r.stride, 10);
    EXPECT_LT(testing::response_error(r.model, sys, testing::frequency_grid(0.1, T)), kSlowExactTolerance)
        << "sums " << sums;
  }
}

TEST(Era, StridedHankelOnNoisySlow10kHzDataFindsTheOrder) {
  const double T = 1e-4;
  const StateSpace sys = testing::modal_system(slow_modes(), T, 3, 3, kSystemSeed, false);
  const MarkovSequence exact = testing::markov_of(sys, 30000);
  const Eigen::MatrixXd noise_std = Eigen::MatrixXd::Constant(3, 3, 3e-4 * testing::peak_entries(exact).maxCoeff());
  EraOptions o = options_for(T);
  o.markov_noise_std = noise_std;
  o.estimate_feedthrough = false;
  const EraResult r = realize_era(testing::add_noise(exact, noise_std, kNoiseSeeds[2]), o);
  EXPECT_EQ(r.selection.order, 7) << r.selection.reason;
  EXPECT_LT(testing::response_error(r.model, sys, testing::frequency_grid(0.1, T)), kNoisyResponseTolerance);
}

template <typename E>
std::string message_of(const MarkovSequence& g, const EraOptions& o) {
  try {
    realize_era(g, o);
  } catch (const E& e) {
    return e.what();
  }
  return "no exception";
}

TEST(Era, ErrorMessagesArePinned) {
  const StateSpace sys = testing::modal_system({{{-50, 200}, 1}}, 1e-3, 1, 1, kSystemSeed);
  const MarkovSequence g = testing::markov_of(sys, 100);
  EraOptions o = options_for(1e-3);
  EXPECT_EQ(message_of<InputError>({}, o), "realize_era: the Markov sequence is empty; pass g[0..L] with L >= 2");
  MarkovSequence bad = g;
  bad[5](0, 0) = std::nan("");
  EXPECT_EQ(message_of<InputError>(bad, o),
            "realize_era: g[5] holds NaN or Inf; every Markov parameter must be finite");
  bad = g;
  bad[2] = Eigen::MatrixXd::Zero(2, 1);
  EXPECT_EQ(message_of<InputError>(bad, o),
            "realize_era: g[2] is 2x1 but g[0] is 1x1; every lag must have one shape");
  EXPECT_EQ(message_of<InputError>(g, options_for(0.0)),
            "ERA: sample_period_s = 0; it must be a positive, finite sample period in seconds");
  EXPECT_EQ(message_of<InputError>(MarkovSequence(g.begin(), g.begin() + 30), o),
            "ERA: g has 30 lags (0..29) but a Hankel matrix of 41x41 blocks with stride 1 (and its one-sample shift) "
            "needs 83 lags (0..82); pass at least 83 lags, or fewer blocks, a smaller stride or a lower max_order");
  EraOptions big = o;
  big.order = 60;
  big.block_rows = big.block_cols = 40;
  EXPECT_EQ(message_of<InputError>(g, big),
            "ERA: order 60 exceeds the 40 singular values of the 40x40 Hankel matrix; raise block_rows/block_cols or "
            "lower the order");
  EraOptions wrong_scale = o;
  wrong_scale.input_scale = Eigen::VectorXd::Ones(2);
  EXPECT_EQ(message_of<InputError>(g, wrong_scale),
            "ERA: input_scale has 2 entries for 1 inputs; give one per input or none");
  // Pure noise: nothing above the floor.
  const Eigen::MatrixXd noise_std = Eigen::MatrixXd::Constant(1, 1, 1.0);
  MarkovSequence noise = testing::add_noise(MarkovSequence(200, Eigen::MatrixXd::Zero(1, 1)), noise_std, kNoiseSeeds[0]);
  EraOptions noisy = o;
  noisy.markov_noise_std = noise_std;
  const std::string msg = message_of<NumericalError>(noise, noisy);
  EXPECT_NE(msg.find("ERA: no singular value stands above the noise floor"), std::string::npos) << msg;
  EXPECT_NE(msg.find("the excitation may be too weak or the record too short"), std::string::npos) << msg;
}

}  // namespace era_test
}  // namespace lpvid
