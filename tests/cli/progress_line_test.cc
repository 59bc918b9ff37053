// The progress line's drawing (cli/progress_line.h) with a fake clock, stream and
// terminal width: the first report drawn at once, at most one draw per
// kMinIntervalS after it, the newest state drawn by the ticker, the line cut to the
// width, erased at the end and nothing drawn after.
#include "cli/progress_line.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace lpvid::cli {
namespace progress_line_test {

using ::testing::HasSubstr;

// Code points of UTF-8 text, counted here without the renderer's helper.
std::size_t columns_of(const std::string& s) {
  std::size_t n = 0;
  for (unsigned char c : s) n += (c & 0xC0) != 0x80;
  return n;
}

struct Fake {
  double now = 100.0;  // any origin: the elapsed time is measured from construction
  int columns = 120;
  std::vector<std::string> writes;
  ProgressLine::Io io() {
    return {[this](std::string_view b) { writes.emplace_back(b); }, [this] { return now; }, [this] { return columns; }};
  }
};

ProgressStep start_of(Index i, Index n) { return {"fit round 1", "global start", i, n, "", -1.0}; }

TEST(ProgressLine, FirstReportIsDrawnAtOnceAsOneLineRewrittenInPlace) {
  Fake f;
  ProgressLine line(f.io());
  line.report(start_of(1, 8));
  ASSERT_EQ(f.writes.size(), 1u);
  EXPECT_EQ(f.writes[0], "\rfit round 1: global start 1 of 8 [--------------------] 0 s\x1b[K");
}

TEST(ProgressLine, AtMostOneDrawPerIntervalWhateverTheReportRate) {
  Fake f;
  ProgressLine line(f.io());
  // 1000 reports over one second, one per millisecond, each a different line.
  for (int k = 0; k < 1000; ++k) {
    f.now = 100.0 + 1e-3 * k;
    const std::string detail = "iteration " + std::to_string(k);
    line.report({"fit", "Levenberg-Marquardt", 0, 0, detail, -1.0});
  }
  // The first at once, then one per 0.1 s: 10 in [0, 1) s; 11 allows the clock's rounding.
  EXPECT_GE(f.writes.size(), 9u);
  EXPECT_LE(f.writes.size(), 11u);
}

TEST(ProgressLine, TickDrawsTheNewestReportHeldBackByTheInterval) {
  Fake f;
  ProgressLine line(f.io());
  line.report(start_of(1, 8));
  f.now += 0.05;
  line.report(start_of(2, 8));  // within the interval: held back
  ASSERT_EQ(f.writes.size(), 1u);
  f.now += 0.06;
  line.tick();
  ASSERT_EQ(f.writes.size(), 2u);
  EXPECT_THAT(f.writes[1], HasSubstr("global start 2 of 8"));
}

TEST(ProgressLine, TickRedrawsOnlyWhenTheLineChangesAndTheSecondsAdvanceDuringALongStep) {
  Fake f;
  ProgressLine line(f.io());
  line.tick();  // nothing reported yet: nothing to draw
  EXPECT_TRUE(f.writes.empty());
  line.report(start_of(3, 8));
  f.now += 0.5;
  line.tick();  // still "0 s": the same line
  EXPECT_EQ(f.writes.size(), 1u);
  f.now += 0.6;
  line.tick();
  ASSERT_EQ(f.writes.size(), 2u);
  EXPECT_THAT(f.writes[1], HasSubstr("] 1 s\x1b[K"));
  f.now += 60.0;
  line.tick();
  EXPECT_THAT(f.writes.back(), HasSubstr("] 1 min 01 s\x1b[K"));
}

TEST(ProgressLine, ClearErasesTheLineOnceAndCloseIgnoresLaterReports) {
  Fake f;
  ProgressLine line(f.io());
  line.clear();  // nothing shown: nothing to erase
  EXPECT_TRUE(f.writes.empty());
  line.report(start_of(1, 2));
  line.clear();
  ASSERT_EQ(f.writes.size(), 2u);
  EXPECT_EQ(f.writes[1], "\r\x1b[K");
  line.report(start_of(2, 2));  // after clear a report draws again, at once
  ASSERT_EQ(f.writes.size(), 3u);
  line.close();
  ASSERT_EQ(f.writes.size(), 4u);
  EXPECT_EQ(f.writes[3], "\r\x1b[K");
  f.now += 10.0;
  line.report(start_of(2, 2));
  line.tick();
  line.close();
  EXPECT_EQ(f.writes.size(), 4u);
}

TEST(ProgressLine, LineIsCutToTheWidthMinusOneKeepingTheBarAndTime) {
  const ProgressStep s{"diagnose", "candidate", 3, 8, "actuator_lag, coil_lag, sensor_resonance, input_delay", -1.0};
  const std::string whole = ProgressLine::compose(s, 41.0, 200);
  EXPECT_EQ(whole,
            "diagnose: candidate 3 of 8: actuator_lag, coil_lag, sensor_resonance, input_delay [#####---------------] "
            "41 s");
  for (int width : {80, 60, 45, 40}) {
    const std::string cut = ProgressLine::compose(s, 41.0, width);
    EXPECT_EQ(columns_of(cut), static_cast<std::size_t>(width - 1)) << width;
    EXPECT_THAT(cut, HasSubstr("...")) << width;
    EXPECT_THAT(cut, ::testing::EndsWith(" [#####---------------] 41 s")) << width;
  }
  // Too narrow for the bar: the whole line is cut.
  const std::string narrow = ProgressLine::compose(s, 41.0, 20);
  EXPECT_EQ(narrow, "diagnose: candidate");
  // Unknown width: 80 columns.
  EXPECT_EQ(columns_of(ProgressLine::compose(s, 41.0, 0)), 79u);
}

TEST(ProgressLine, CutsUtf8TextOnCodePointsAndShowsControlCharactersAsQuestionMarks) {
  // "–" is three bytes, one column.
  const ProgressStep s{"fit", "Levenberg–Marquardt", 0, 0, "a\nb\x1b[2Jc", -1.0};
  EXPECT_EQ(ProgressLine::compose(s, 2.0, 200), "fit: Levenberg–Marquardt: a?b?[2Jc (2 s)");
  const std::string cut = ProgressLine::compose(s, 2.0, 20);
  EXPECT_EQ(columns_of(cut), 19u);
  EXPECT_EQ(cut, "fit: Leven... (2 s)");
  const ProgressStep dash{"fit", "––––––––––––––––––––––––––––––––", 0, 0, "", -1.0};
  const std::string d = ProgressLine::compose(dash, 0.0, 20);
  EXPECT_EQ(columns_of(d), 19u);
  EXPECT_EQ(d.substr(5, 3), "–");  // whole code points only
}

TEST(ProgressLine, BarShowsTheGivenFractionOrTheStepsBeforeTheRunningOne) {
  EXPECT_THAT(ProgressLine::compose({"t", "s", 3, 8, "", -1.0}, 0, 200), HasSubstr("[#####---------------]"));
  EXPECT_THAT(ProgressLine::compose({"t", "s", 3, 8, "", 0.5}, 0, 200), HasSubstr("[##########----------]"));
  EXPECT_EQ(ProgressLine::compose({"t", "s", 3, 0, "x", -1.0}, 0, 200), "t: s 3: x (0 s)");  // no count: no bar
  EXPECT_EQ(ProgressLine::compose({"t", "", 0, 0, "", -1.0}, 0, 200), "t (0 s)");
}

TEST(ProgressLine, ElapsedTimeInSecondsMinutesAndHours) {
  EXPECT_EQ(ProgressLine::elapsed_text(0.4), "0 s");
  EXPECT_EQ(ProgressLine::elapsed_text(41.9), "41 s");
  EXPECT_EQ(ProgressLine::elapsed_text(125), "2 min 05 s");
  EXPECT_EQ(ProgressLine::elapsed_text(3725), "1 h 02 min");
}

}  // namespace progress_line_test
}  // namespace lpvid::cli
