// JSON reading limits shared by every JSON reader (issue 12, classes 4 and 5):
// depth, number range and size give one positioned line, never a crash.
#include "formats/io/json_detail.h"

#include <gtest/gtest.h>

#include "formats/io/model_json.h"
#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace json_detail_test {

using test::input_error;

class JsonLimitsTest : public test::TempDirTest {};

TEST_F(JsonLimitsTest, NumberBeyondADouble_IsAPositionedInputError) {
  const std::string text = "{\n  \"ts\": 1e400\n}";
  EXPECT_EQ(input_error([&] { detail::parse_json("m.json", text); }),
            "m.json:2:9: number '1e400' is out of range (a double holds up to about 1.8e308); write a finite number");
  EXPECT_EQ(input_error([&] { detail::parse_json("h.jsonl", "{\"cost\": -1e999}", {}, 7); }),
            "h.jsonl:7:10: number '-1e999' is out of range (a double holds up to about 1.8e308); write a finite number");
}

TEST_F(JsonLimitsTest, DeepNesting_StopsAtTheLimitWithAShortMessage) {
  // 200,000 levels crashed the program (stack overflow while building the message).
  const std::string deep = std::string(200000, '[') + std::string(200000, ']');
  const std::string message = input_error([&] { detail::parse_json("deep.json", deep); });
  EXPECT_EQ(message, "deep.json:1:65: arrays and objects nested deeper than 64 levels; lpvid's files nest a few "
                     "levels: check that this is the right file");
  // Brackets inside strings do not count.
  EXPECT_NO_THROW(detail::parse_json("s.json", "{\"a\": \"" + std::string(1000, '[') + "\"}"));
}

TEST_F(JsonLimitsTest, SyntaxError_PointsAtTheByte) {
  EXPECT_EQ(input_error([&] { detail::parse_json("b.json", "{\n  \"a\": ,\n}"); }),
            "b.json:2:8: invalid JSON: syntax error while parsing value - unexpected ','; expected '[', '{', or a "
            "literal; fix the JSON syntax");
}

TEST_F(JsonLimitsTest, FileLargerThanTheLimit_IsRefusedWhileReading) {
  detail::JsonLimits limits;
  limits.max_bytes = 1 << 20;
  EXPECT_EQ(input_error([&] { detail::read_json_text("/dev/zero", "a model file", limits); }),
            "/dev/zero: larger than 1 MiB; a model file is far smaller: check that this is the right file");
  EXPECT_EQ(input_error([&] { detail::read_json_text(dir_.string(), "a model file"); }),
            "cannot read '" + dir_.string() + "': it is a directory; give a model file");
}

TEST_F(JsonLimitsTest, Excerpt_IsCutTo40Bytes) {
  const nlohmann::json big = std::vector<int>(1000, 7);
  EXPECT_EQ(detail::json_excerpt(big), "[7,7,7,7,7,7,7,7,7,7,7,7,7,7,7,7,7,7,7,7...");
  EXPECT_EQ(detail::json_excerpt(nlohmann::json(nullptr)), "null");
}

TEST_F(JsonLimitsTest, ModelFile_ValueNestedDeepInAMatrix_GivesAShortLine) {
  // 10,000 levels gave a 20 KB message echoing the value.
  const std::string p = write("d.json", "{\"type\": \"state_space\", \"ts\": 0, \"A\": [[" + std::string(50, '[') +
                                            std::string(50, ']') + "]], \"B\": [], \"C\": [], \"D\": []}");
  const std::string message = input_error([&] { read_state_space(p); });
  EXPECT_LT(message.size(), 400u) << message;
  EXPECT_NE(message.find("entry (1, 1) is [[[[[["), std::string::npos) << message;
}

TEST_F(JsonLimitsTest, ModelFile_MoreStatesThanTheLimit_IsRefusedBeforeAllocating) {
  std::string rows = "[";
  for (int i = 0; i <= kMaxModelStates; ++i) rows += std::string(i ? "," : "") + "[]";
  rows += "]";
  const std::string p = write("big.json", "{\"type\": \"state_space\", \"ts\": 0,\n\"A\": " + rows +
                                              ", \"B\": [], \"C\": [], \"D\": []}");
  EXPECT_EQ(input_error([&] { read_state_space(p); }),
            p + ":2:1: key 'A' has 401 rows: lpvid reads models of at most 400 states and 256 inputs and outputs; "
                "reduce the model first (e.g. realize --order)");
}

}  // namespace json_detail_test
}  // namespace lpvid
