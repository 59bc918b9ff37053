// The era route's warning rule on the plant unloop returns, closed again with the
// controller (identify_detail::reclosed_loop_misses_far_more): more than twice the ERA
// closed loop's miss AND more than one point of fit.  The cases are the rule's own
// arithmetic, written out: the levitated platform's (issue 24: −0.0 % against 99.5 %), a
// pair of loops both within a point of the logs (99.97 against 99.99 %: 3x "as much",
// which the rule before this commit called a miss), and the boundaries of both parts.
#include <gtest/gtest.h>

#include "idlib/identify/identify_detail.h"

namespace lpvid {
namespace reclosed_loop_test {

using identify_detail::reclosed_loop_misses_far_more;

TEST(ReclosedLoop, AMissIsTwiceTheEraLoopsAndMoreThanAPointOfFit) {
  EXPECT_TRUE(reclosed_loop_misses_far_more(99.5, -0.0));   // the levitated platform's unloop
  EXPECT_TRUE(reclosed_loop_misses_far_more(90.0, 75.0));   // 25 points against 10: 2.5x, 15 points
  EXPECT_FALSE(reclosed_loop_misses_far_more(99.99, 99.97));  // 3x, but 0.02 points: both simulate the logs
  EXPECT_FALSE(reclosed_loop_misses_far_more(99.9, 99.0));    // 10x, 0.9 points
  EXPECT_TRUE(reclosed_loop_misses_far_more(99.9, 98.8));     // 12x, 1.1 points
  EXPECT_FALSE(reclosed_loop_misses_far_more(80.0, 61.0));    // 39 against 20: 1.95x
  EXPECT_TRUE(reclosed_loop_misses_far_more(100.0, 98.5));    // a perfect ERA loop, 1.5 points off
  EXPECT_FALSE(reclosed_loop_misses_far_more(95.0, 96.0));    // the plant's loop is the better
}

}  // namespace reclosed_loop_test
}  // namespace lpvid
