#include "ffloc/io/json_fields.h"

#include <gtest/gtest.h>

#include <fstream>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/scene_test_util.h"

namespace ffloc {
namespace {

using testing::expectInputError;

// nlohmann keeps the last of two equal keys: {"steps": 10, "steps": 20} trained 20 steps, and a
// manifest camera's second "fx" replaced the first, without a word.
TEST(ParseJson, RefusesAKeyGivenTwiceNamingItsPath) {
  expectInputError([] { parseJson(R"({"steps": 10, "steps": 20})", "cfg.json"); },
                   {"cfg.json: field 'steps': duplicated key"});
  expectInputError([] { parseJson(R"({"cameras": {"0": {"fx": 5, "fy": 5, "fx": 6}}})", "m.json"); },
                   {"m.json: field 'cameras.0.fx': duplicated key"});
  expectInputError(
      [] { parseJson(R"({"frames": [{"camera": "a"}, 3, [1, {"x": 1}], {"image": "b", "camera": "a", "camera": "b"}]})", "m.json"); },
      {"m.json: field 'frames[3].camera': duplicated key"});
  expectInputError([] { parseJson(R"([[], [{"a": 1}, {"b": {"c": 1, "c": 1}}]])", "list.json"); },
                   {"list.json: field '[1][1].b.c': duplicated key"});
}

TEST(ParseJson, EqualKeysInDifferentObjectsAreFine) {
  const nlohmann::json parsed =
      parseJson(R"({"a": {"x": 1, "y": [{"x": 2}, {"x": 3}]}, "x": {"a": {"x": 4}}, "y": [[{"x": 5}]]})", "ok.json");
  EXPECT_EQ(parsed["a"]["y"][1]["x"], 3);
  EXPECT_EQ(parsed["x"]["a"]["x"], 4);
  EXPECT_EQ(parsed["y"][0][0]["x"], 5);
  EXPECT_EQ(parseJson("7", "scalar.json"), 7);
}

TEST(ParseJson, FilesAreNamedInEveryError) {
  const auto dir = testing::makeTempDir("ffloc-json-fields");
  std::ofstream(dir / "dup.json") << "{\"steps\": 10,\n \"steps\": 20}\n";
  expectInputError([&] { parseJsonFile(dir / "dup.json"); }, {(dir / "dup.json").string() + ": field 'steps': duplicated key"});
  std::ofstream(dir / "nan.json") << "{\"fx\": NaN}";
  expectInputError([&] { parseJsonFile(dir / "nan.json"); },
                   {(dir / "nan.json").string() + ": invalid JSON", "NaN and Infinity are not JSON"});
  // Without nlohmann's tag ("[json.exception.parse_error.101] ").
  std::ofstream(dir / "cut.json") << "{\"steps\": 1";
  try {
    parseJsonFile(dir / "cut.json");
    FAIL() << "a truncated file parsed";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind((dir / "cut.json").string() + ": invalid JSON: parse error at line 1", 0), 0u)
        << e.what();
  }
}

}  // namespace
}  // namespace ffloc
