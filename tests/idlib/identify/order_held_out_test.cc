// identify_open_loop's order checked on held-out halves (order_held_out.cc).  The truth is a
// plant written here — a lightly damped mode (60 rad/s, ζ 0.05) and a real pole (20 rad/s),
// order 3 — its logs simulated here by its own recursion, white input, white sensor noise.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "idlib/identify/identify.h"
#include "idlib/identify/identify_detail.h"
#include "tests/idlib/identify/mode_and_pole.h"

namespace lpvid {
namespace order_held_out_test {

using testing::mode_and_pole::kTs;

// N samples of white u (seed 11) from rest, y plus white noise of `noise` × y's RMS.
void simulate(Index N, double noise, Eigen::MatrixXd& u, Eigen::MatrixXd& y) {
  testing::mode_and_pole::simulate_open_loop(testing::mode_and_pole::plant(), N, Eigen::Vector3d::Zero(), noise, 11, u,
                                             y);
}

const IdentifyChoices::HeldOutOrder::Row* row_of(const IdentifyChoices::HeldOutOrder& h, Index order) {
  for (const auto& r : h.rows)
    if (r.order == order) return &r;
  return nullptr;
}

TEST(HeldOutOrder, TheTrueOrderPredictsTheHeldOutHalvesBestAndIsKept) {
  Eigen::MatrixXd u, y;
  simulate(6000, 0.05, u, y);
  const IdentifyResult r = identify_open_loop({{u, y}}, kTs, IdentifyOptions{});
  const IdentifyChoices::HeldOutOrder& h = r.choices.held_out;
  std::printf("order %td; %s\n", r.plant.order(), h.reason.c_str());
  ASSERT_TRUE(h.ran) << h.reason;
  EXPECT_EQ(r.plant.order(), 3);
  EXPECT_EQ(h.chosen_order, 3);
  const auto* three = row_of(h, 3);
  const auto* one = row_of(h, 1);
  ASSERT_NE(three, nullptr);
  ASSERT_NE(one, nullptr);
  ASSERT_TRUE(three->ok) << three->failure;
  // 5 % noise on y's RMS: a perfect model predicts the held-out halves to about
  // 100 (1 − 0.05) = 95 %; the true order within 1 point of that.  Order 1 misses the
  // mode (the mode carries most of y): far below.
  EXPECT_GT(three->fit_percent, 94.0);
  if (one->ok) {
    EXPECT_LT(one->fit_percent, three->fit_percent - 10.0);
  }
}

// A ladder that stopped too low (order 1, given) is overruled: orders 1..3 are fitted on
// the halves and the true order predicts better by many standard errors.
TEST(HeldOutOrder, AnOrderTooLowIsReplacedByTheOneTheHeldOutDataProveBetter) {
  Eigen::MatrixXd u, y;
  simulate(6000, 0.05, u, y);
  IdentifyOptions given;
  given.plant_order = 1;
  const IdentifyResult low = identify_open_loop({{u, y}}, kTs, given);
  ASSERT_EQ(low.plant.order(), 1);
  const IdentifyChoices::HeldOutOrder h =
      identify_detail::check_order_held_out({{u, y}}, kTs, IdentifyOptions{}, low);
  std::printf("%s\n", h.reason.c_str());
  ASSERT_TRUE(h.ran) << h.reason;
  EXPECT_EQ(h.ladder_order, 1);
  EXPECT_EQ(h.chosen_order, 3);
  EXPECT_NE(h.reason.find("standard errors"), std::string::npos);
}

TEST(HeldOutOrder, ARecordTooShortToHalveIsNotCheckedAndSaysSo) {
  Eigen::MatrixXd u, y;
  simulate(6000, 0.05, u, y);
  IdentifyOptions given;
  given.plant_order = 3;
  const IdentifyResult r = identify_open_loop({{u, y}}, kTs, given);
  const Eigen::MatrixXd us = u.topRows(200), ys = y.topRows(200);
  const IdentifyChoices::HeldOutOrder h = identify_detail::check_order_held_out({{us, ys}}, kTs, IdentifyOptions{}, r);
  EXPECT_FALSE(h.ran);
  EXPECT_EQ(h.chosen_order, 3);
  EXPECT_NE(h.reason.find("does not split"), std::string::npos) << h.reason;
}

}  // namespace order_held_out_test
}  // namespace lpvid
