// cli/common.h's name lists: a numbered range "a1..a28" stands for its names (the DaISy
// subframe's 28 accelerometers need not be typed one by one); anything else is a name.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cli/common.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace common_names_test {

using cli::split_names;
using Names = std::vector<std::string>;

TEST(SplitNames, ANumberedRangeStandsForItsNames) {
  EXPECT_EQ(split_names("f1,f2,a1..a4", "--output"), (Names{"f1", "f2", "a1", "a2", "a3", "a4"}));
  EXPECT_EQ(split_names("acc08..acc11", "--output"), (Names{"acc08", "acc09", "acc10", "acc11"}));  // width kept
  EXPECT_EQ(split_names("q2..q2", "--output"), (Names{"q2"}));
  EXPECT_EQ(split_names("a1..a28", "--output").size(), 28u);
}

TEST(SplitNames, WhatIsNotARangeIsANameAsItStands) {
  // Other prefixes, a descending range, no number, a bare number: names as written.
  EXPECT_EQ(split_names("a1..b3", "--output"), (Names{"a1..b3"}));
  EXPECT_EQ(split_names("a3..a1", "--output"), (Names{"a3..a1"}));
  EXPECT_EQ(split_names("x..y", "--output"), (Names{"x..y"}));
  EXPECT_EQ(split_names("1..3", "--output"), (Names{"1..3"}));
  EXPECT_EQ(split_names("v1, q1", "--output"), (Names{"v1", "q1"}));
  EXPECT_THROW(split_names("v1,,q1", "--output"), InputError);
}

}  // namespace common_names_test
}  // namespace lpvid
