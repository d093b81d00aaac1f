#include "common/config/json_reader.h"

#include <gtest/gtest.h>

namespace mirrorscan {
namespace {

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(JsonReaderTest, ReadsValuesAndDefaults) {
  const auto json =
      JsonReader::ParseText(R"({"a": 1.5, "n": 3, "s": "x", "o": {"b": true}})", "f.json");
  JsonReader r(json, "f.json");
  EXPECT_EQ(r.Number("a"), 1.5);
  EXPECT_EQ(r.Number("missing", 2.0), 2.0);
  EXPECT_EQ(r.Integer("n"), 3);
  EXPECT_EQ(r.String("s"), "x");
  EXPECT_TRUE(r.Object("o").Bool("b"));
}

TEST(JsonReaderTest, ErrorsNameFileAndKeyPath) {
  const auto json = JsonReader::ParseText(
      R"({"cameras": [{"fx": 1000}, {"fx": -3}], "mode": "z", "v": [1, "a"]})", "scene.json");
  JsonReader r(json, "scene.json");
  EXPECT_EQ(ErrorOf([&] { r.Objects("cameras")[1].Number("fx", std::nullopt, 1.0); }),
            "scene.json: cameras[1].fx: must be in [1, inf], got -3");
  EXPECT_EQ(ErrorOf([&] { r.Objects("cameras")[0].Number("fy"); }),
            "scene.json: cameras[0].fy: missing (expected a number)");
  EXPECT_EQ(ErrorOf([&] {
              r.Choice("mode", {"a", "b"});
            }),
            "scene.json: mode: \"z\" is not one of: a, b");
  EXPECT_EQ(ErrorOf([&] { r.Numbers("v", 2); }),
            "scene.json: v: expected an array of 2 finite numbers");
  EXPECT_EQ(ErrorOf([&] { r.Integer("mode"); }), "scene.json: mode: expected an integer");
  EXPECT_EQ(ErrorOf([&] {
              r.AllowOnly({"cameras", "mode"});
            }),
            "scene.json: v: unknown key (expected one of: cameras, mode)");
}

TEST(JsonReaderTest, SyntaxErrorAndMissingFileNameTheFile) {
  EXPECT_EQ(ErrorOf([] {
              JsonReader::ParseText("{\"a\": ", "bad.json");
            }).rfind("bad.json: not valid JSON", 0),
            0u);
  EXPECT_EQ(ErrorOf([] { JsonReader::ParseFile("/nonexistent/x.json"); }),
            "/nonexistent/x.json: cannot open file");
  const auto array = JsonReader::ParseText("[1]", "arr.json");
  EXPECT_EQ(ErrorOf([&] { JsonReader r(array, "arr.json"); }),
            "arr.json: top level: expected an object");
}

}  // namespace
}  // namespace mirrorscan
