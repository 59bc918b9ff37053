#include "formats/io/model_json.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace model_json_test {

using test::input_error;

class ModelJson : public test::TempDirTest {};

constexpr unsigned kSeed = 7;  // named seed for the random models

StateSpace random_model(Index n, Index m, Index p, double ts) {
  std::mt19937_64 rng(kSeed);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto fill = [&](Index r, Index c) {
    Eigen::MatrixXd x(r, c);
    for (Index i = 0; i < r; ++i)
      for (Index j = 0; j < c; ++j) x(i, j) = normal(rng) / 3.0;  // thirds: no short decimal form
    return x;
  };
  StateSpace model;
  model.A = fill(n, n);
  model.B = fill(n, m);
  model.C = fill(p, n);
  model.D = fill(p, m);
  model.sample_period_s = ts;
  return model;
}

void expect_identical(const StateSpace& a, const StateSpace& b) {
  EXPECT_EQ(a.A.rows(), b.A.rows());
  EXPECT_EQ(a.B.rows(), b.B.rows());
  EXPECT_EQ(a.B.cols(), b.B.cols());
  EXPECT_EQ(a.C.rows(), b.C.rows());
  EXPECT_EQ(a.C.cols(), b.C.cols());
  EXPECT_EQ(a.D.rows(), b.D.rows());
  EXPECT_EQ(a.D.cols(), b.D.cols());
  EXPECT_TRUE(a.A == b.A && a.B == b.B && a.C == b.C && a.D == b.D);
  EXPECT_EQ(a.sample_period_s, b.sample_period_s);
  EXPECT_EQ(a.input_names, b.input_names);
  EXPECT_EQ(a.output_names, b.output_names);
}

TEST_F(ModelJson, WriteThenRead_DiscreteWithNamesAndExtra_IsIdentical) {
  StateSpace model = random_model(4, 3, 2, 1e-3 / 3);
  model.input_names = {"v1", "v2", "v3"};
  model.output_names = {"q1", "q2"};
  const std::string p = path("m.json");
  write_state_space(p, model, {{"provenance", {{"command", "lpvid realize"}, {"seed", 3}}}});
  expect_identical(read_state_space(p), model);
  const nlohmann::json file = nlohmann::json::parse(read(p));
  EXPECT_EQ(file["provenance"]["command"], "lpvid realize");
  EXPECT_EQ(entries(), std::vector<std::string>{"m.json"});
}

TEST_F(ModelJson, WriteThenRead_ContinuousWithoutNames_IsIdentical) {
  const StateSpace model = random_model(3, 1, 1, 0.0);
  const std::string p = path("c.json");
  write_state_space(p, model);
  expect_identical(read_state_space(p), model);
}

TEST_F(ModelJson, StaticGain_OrderZero_RoundTripsWithItsShapes) {
  StateSpace model;
  model.A.resize(0, 0);
  model.B.resize(0, 2);
  model.C.resize(3, 0);
  model.D = Eigen::MatrixXd::Constant(3, 2, 0.5);
  model.input_names = {"v1", "v2"};
  model.output_names = {"q1", "q2", "q3"};
  const std::string text = state_space_to_json(model);
  EXPECT_NE(text.find("\"B\": []"), std::string::npos);
  EXPECT_NE(text.find("\"C\": [\n    [],\n    [],\n    []\n  ]"), std::string::npos);
  const std::string p = write("g.json", text);
  const StateSpace back = read_state_space(p);
  EXPECT_EQ(back.order(), 0);
  expect_identical(back, model);
}

TEST_F(ModelJson, Text_IsPrettyWithOneRowPerLine) {
  StateSpace model;
  model.A = Eigen::MatrixXd::Identity(2, 2) * 0.5;
  model.B = Eigen::MatrixXd::Ones(2, 1);
  model.C = Eigen::MatrixXd::Zero(1, 2);
  model.D = Eigen::MatrixXd::Zero(1, 1);
  model.sample_period_s = 0.001;
  model.input_names = {"v1"};
  model.output_names = {"q1"};
  EXPECT_EQ(state_space_to_json(model, {{"note", "x"}}),
            "{\n"
            "  \"type\": \"state_space\",\n"
            "  \"ts\": 0.001,\n"
            "  \"inputs\": [\"v1\"],\n"
            "  \"outputs\": [\"q1\"],\n"
            "  \"A\": [\n    [0.5, 0.0],\n    [0.0, 0.5]\n  ],\n"
            "  \"B\": [\n    [1.0],\n    [1.0]\n  ],\n"
            "  \"C\": [\n    [0.0, 0.0]\n  ],\n"
            "  \"D\": [\n    [0.0]\n  ],\n"
            "  \"note\": \"x\"\n"
            "}\n");
}

const char* const kGood =
    "{\n"
    "  \"type\": \"state_space\",\n"
    "  \"ts\": 0,\n"
    "  \"A\": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],\n"
    "  \"B\": [[1], [0], [0]],\n"
    "  \"C\": [[1, 0, 0]],\n"
    "  \"D\": [[0]]\n"
    "}\n";

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST_F(ModelJson, GoodFile_Reads) {
  const StateSpace model = read_state_space(write("ctl.json", kGood));
  EXPECT_EQ(model.order(), 3);
  EXPECT_EQ(model.num_inputs(), 1);
  EXPECT_EQ(model.num_outputs(), 1);
  EXPECT_FALSE(model.is_discrete());
}

TEST_F(ModelJson, WrongShapeOfB_NamesKeyShapeAndPosition) {
  const std::string p = write("ctl.json", replace(kGood, "\"B\": [[1], [0], [0]]", "\"B\": [[1, 2], [0, 0], [0, 0]]"));
  // m comes from D (1 column), so B must be 3×1.
  EXPECT_EQ(input_error([&] { read_state_space(p); }),
            p + ":5:3: key 'B' must be a 3×1 matrix (states × inputs), got 3×2; check the dimensions of A, B, C, D "
                "and the inputs/outputs names");
}

TEST_F(ModelJson, InvalidJson_ReportsLineAndColumn) {
  const std::string p = write("bad.json", "{\n  \"type\": \"state_space\",\n  \"ts\": ,\n}\n");
  EXPECT_EQ(input_error([&] { read_state_space(p); }),
            p + ":3:9: invalid JSON: syntax error while parsing value - unexpected ','; expected '[', '{', or a "
                "literal; fix the JSON syntax");
}

TEST_F(ModelJson, MissingMatrix_IsNamed) {
  const std::string p = write("m.json", replace(kGood, ",\n  \"D\": [[0]]", ""));
  EXPECT_EQ(input_error([&] { read_state_space(p); }),
            p + ":1:1: missing key 'D'; a model needs the matrices A, B, C and D");
}

TEST_F(ModelJson, NullEntry_SaysJsonHasNoNaN) {
  const std::string p = write("n.json", replace(kGood, "[[1, 0, 0]]", "[[1, null, 0]]"));
  EXPECT_EQ(input_error([&] { read_state_space(p); }),
            p + ":6:3: key 'C' must be a matrix (outputs × states) written as an array of rows, but entry (1, 2) is "
                "null; every entry must be a finite number (JSON has no NaN or Inf)");
}

TEST_F(ModelJson, RaggedRows_AreRejected) {
  const std::string p = write("r.json", replace(kGood, "[0, 1, 0]", "[0, 1]"));
  EXPECT_EQ(input_error([&] { read_state_space(p); }),
            p + ":4:3: key 'A' must be a matrix (states × states) written as an array of rows, but row 2 has 2 entries "
                "and row 1 has 3; give every row the same length");
}

TEST_F(ModelJson, NegativeTsAndWrongType_AreRejected) {
  const std::string p = write("t.json", replace(kGood, "\"ts\": 0", "\"ts\": -0.001"));
  EXPECT_EQ(input_error([&] { read_state_space(p); }),
            p + ":3:3: key 'ts' is -0.001; write 0 (continuous time) or the positive sample period in seconds");
  const std::string q = write("y.json", replace(kGood, "\"state_space\"", "\"zpk\""));
  EXPECT_EQ(input_error([&] { read_state_space(q); }),
            q + ":2:3: key 'type' is \"zpk\"; write \"type\": \"state_space\" or \"transfer_function\" (the types lpvid "
                "reads)");
}

TEST_F(ModelJson, NameCountDisagreeingWithMatrices_IsAShapeError) {
  const std::string p =
      write("i.json", replace(kGood, "\"ts\": 0,", "\"ts\": 0,\n  \"inputs\": [\"v1\", \"v2\"],"));
  EXPECT_EQ(input_error([&] { read_state_space(p); }),
            p + ":6:3: key 'B' must be a 3×2 matrix (states × inputs), got 3×1; check the dimensions of A, B, C, D "
                "and the inputs/outputs names");
}

TEST_F(ModelJson, DuplicateNames_AreRejected) {
  const std::string p = write("d.json", replace(kGood, "\"ts\": 0,", "\"ts\": 0, \"outputs\": [\"q\", \"q\"],"));
  EXPECT_EQ(input_error([&] { read_state_space(p); }),
            p + ":3:12: key 'outputs' must be an array of unique, non-empty names, 'q' appears twice; give every "
                "signal its own name");
}

TEST_F(ModelJson, NotAnObject_IsRejected) {
  const std::string p = write("a.json", "[1, 2]");
  EXPECT_EQ(input_error([&] { read_state_space(p); }),
            p + ":1:1: the file holds array where a JSON object is expected; a model file is an object {\"type\": "
                "\"state_space\", \"ts\": ..., \"A\": ..., \"B\": ..., \"C\": ..., \"D\": ...}: check that this is a model file");
}

TEST_F(ModelJson, WritingNaNOrCollidingExtra_FailsAndLeavesNoFile) {
  StateSpace model = random_model(2, 1, 1, 0.01);
  model.A(0, 1) = std::nan("");
  const std::string p = path("x.json");
  EXPECT_EQ(input_error([&] { write_state_space(p, model); }),
            "state-space model: a matrix holds NaN or Inf; every entry must be finite");
  model.A(0, 1) = 0;
  EXPECT_EQ(input_error([&] { write_state_space(p, model, {{"A", 1}}); }),
            "extra model-file key 'A' collides with the model schema; rename it");
  EXPECT_TRUE(entries().empty());
}

TEST_F(ModelJson, MissingFile_SaysCannotOpen) {
  EXPECT_EQ(input_error([&] { read_state_space(path("no.json")); }),
            "cannot open '" + path("no.json") + "': No such file or directory; check the path");
}

}  // namespace model_json_test
}  // namespace lpvid
