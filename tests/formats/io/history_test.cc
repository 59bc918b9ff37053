#include "formats/io/history.h"

#include <gtest/gtest.h>

#include <cmath>

#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace history_test {

using test::input_error;

class History : public test::TempDirTest {};

HistoryRecord record(const std::string& note, double error) {
  HistoryRecord r;
  r.timestamp = "2026-11-23T12:00:00Z";
  r.model = "plant.json";
  r.effects = {"rigid body", "suspension"};
  r.free_parameters = 9;
  r.cost = 1.25e-3;
  r.error_mean = error;
  r.error_max = 4 * error;
  r.channels = {{"psi", "T_psi", error / 2, error}, {"z", "F_z", error, 3 * error}};
  r.aic = -812.5;
  r.note = note;
  return r;
}

TEST_F(History, AppendThenReadGivesTheRecordsBackInOrder) {
  const std::string p = history_path_for(path("plant.json"));
  EXPECT_EQ(p, path("plant.json") + ".history.jsonl");
  append_history(p, record("first fit", 0.1));
  HistoryRecord second = record("with delay", 0.01);
  second.effects.push_back("delay");
  second.free_parameters = 10;
  second.bic = 12.0;
  append_history(p, second);
  const auto back = read_history(p);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].note, "first fit");
  EXPECT_EQ(back[1].effects, (std::vector<std::string>{"rigid body", "suspension", "delay"}));
  EXPECT_EQ(back[1].free_parameters, 10);
  // JSON numbers are written in the shortest form that reads back exactly.
  EXPECT_EQ(back[1].error_mean, 0.01);
  EXPECT_EQ(back[1].error_max, 0.04);
  EXPECT_EQ(back[0].cost, 1.25e-3);
  EXPECT_EQ(back[0].aic, -812.5);
  EXPECT_TRUE(std::isnan(back[0].bic));  // null = not computed
  EXPECT_EQ(back[1].bic, 12.0);
  ASSERT_EQ(back[1].channels.size(), 2u);
  EXPECT_EQ(back[1].channels[1].output, "z");
  EXPECT_EQ(back[1].channels[1].error_max, 0.03);
  // One line per record, and the file holds nothing else.
  const std::string text = read(p);
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 2);
  EXPECT_EQ(entries(), (std::vector<std::string>{"plant.json.history.jsonl"}));
}

TEST_F(History, BadLinesNameFileLineAndColumn) {
  const std::string good = history_line(record("ok", 0.1));
  const std::string p = write("h.jsonl", good + "\n" + good.substr(0, 20) + "\n");
  EXPECT_EQ(input_error([&] { read_history(p); }).rfind(p + ":2:", 0), 0u) << input_error([&] { read_history(p); });
  std::string bad = good;
  bad.replace(bad.find("\"free_parameters\":9"), 19, "\"free_parameters\":-1");
  write("h2.jsonl", good + "\n" + good + "\n" + bad + "\n");
  EXPECT_EQ(input_error([&] { read_history(path("h2.jsonl")); }),
            path("h2.jsonl") + ":3:1: free_parameters is -1; write the number of free parameters (>= 0)");
  write("h3.jsonl", good + "\n\n");
  EXPECT_EQ(input_error([&] { read_history(path("h3.jsonl")); }),
            path("h3.jsonl") +
                ":2:1: empty line; a history file has one JSON record per line and no blank lines");
  std::string typo = good;
  typo.replace(typo.find("\"note\""), 6, "\"note2\"");
  write("h4.jsonl", typo + "\n");
  EXPECT_NE(input_error([&] { read_history(path("h4.jsonl")); }).find(":1:1: unknown key 'note2'"), std::string::npos);
  std::string missing = good;
  missing.replace(missing.find("\"cost\""), 6, "\"note\"");  // duplicate key, cost gone
  write("h5.jsonl", missing + "\n");
  EXPECT_NE(input_error([&] { read_history(path("h5.jsonl")); }).find("no key 'cost'"), std::string::npos);
}

TEST_F(History, AppendToABrokenHistoryChangesNothing) {
  const std::string p = write("h.jsonl", "{not json\n");
  EXPECT_NE(input_error([&] { append_history(p, record("x", 0.1)); }).find(p + ":1:"), std::string::npos);
  EXPECT_EQ(read(p), "{not json\n");
  EXPECT_EQ(entries(), (std::vector<std::string>{"h.jsonl"}));  // no temporary left
}

TEST_F(History, InvalidRecordIsRejectedBeforeWriting) {
  HistoryRecord r = record("x", 0.1);
  r.timestamp = "yesterday";
  EXPECT_EQ(input_error([&] { append_history(path("h.jsonl"), r); }),
            "timestamp 'yesterday' is not ISO 8601 UTC; write it as YYYY-MM-DDThh:mm:ssZ");
  r = record("x", 0.1);
  r.error_max = r.error_mean / 2;
  EXPECT_NE(input_error([&] { append_history(path("h.jsonl"), r); }).find("max >= mean"), std::string::npos);
  EXPECT_TRUE(entries().empty());
}

TEST_F(History, MissingFileSaysToFitFirst) {
  EXPECT_NE(input_error([&] { read_history(path("none.jsonl")); }).find("fit a model first"), std::string::npos);
}

TEST(HistoryTimestamp, NowIsIsoUtc) {
  HistoryRecord r = record("x", 0.1);
  r.timestamp = utc_timestamp_now();
  EXPECT_NO_THROW(r.validate()) << r.timestamp;
}

}  // namespace history_test
}  // namespace lpvid
