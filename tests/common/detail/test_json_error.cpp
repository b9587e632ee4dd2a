// The shared JSON error messages: positions of syntax errors, of overflowing numbers and of a value
// at a path, counted by hand on small documents.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "common/detail/json_error.hpp"

namespace {

using sinew::common::detail::json_syntax_error;
using sinew::common::detail::json_value_error;
using sinew::common::detail::JsonLocator;
using sinew::common::detail::JsonPathStep;
using sinew::common::detail::line_column;

std::string at(const std::string& text, const std::vector<JsonPathStep>& path) {
  return line_column(text, JsonLocator(text).find(path));
}

TEST(JsonError, LineColumnCountsFromOne) {
  EXPECT_EQ(line_column("ab\ncd", 0), "1:1");
  EXPECT_EQ(line_column("ab\ncd", 4), "2:2");
  EXPECT_EQ(line_column("ab", 99), "1:3");  // past the end: the end
}

TEST(JsonError, SyntaxErrorKeepsTheParsersReasonAndItsPosition) {
  const std::string what =
      "[json.exception.parse_error.101] parse error at line 2, column 1: syntax error while "
      "parsing value - unexpected end of input";
  EXPECT_EQ(json_syntax_error("a.json", "{\"a\": [\n", what, 9),
            "a.json:2:1: invalid JSON: syntax error while parsing value - unexpected end of input");
}

TEST(JsonError, AnOverflowingNumberIsFoundAsAWholeToken) {
  // "11e999" contains "1e999" but is not it: the whole token on line 2 is.
  const std::string text = "{\"a\": 11e999,\n \"b\": 1e999}";
  EXPECT_EQ(json_value_error("b.json", text,
                             "[json.exception.out_of_range.406] number overflow parsing '1e999'"),
            "b.json:2:7: invalid JSON: number overflow parsing '1e999' (not a finite double)");
  EXPECT_EQ(json_value_error("c.json", "{}", "[json.exception.other.1] something"),
            "c.json: invalid JSON: something");
}

TEST(JsonError, LocatorFindsValuesByKeyAndIndexPastNestedValues) {
  const std::string text =
      "{\"skip\": {\"x\": [1, {\"y\": \"}]\"}]},\n"
      " \"nodes\": [[0, 0], [1, 2],\n"
      "   [3, 4]],\n"
      " \"m\": {\"E\": true}}";
  EXPECT_EQ(at(text, {}), "1:1");
  EXPECT_EQ(at(text, {{true, "nodes", 0}}), "2:11");
  EXPECT_EQ(at(text, {{true, "nodes", 0}, {false, "", 2}}), "3:4");
  EXPECT_EQ(at(text, {{true, "nodes", 0}, {false, "", 2}, {false, "", 1}}), "3:8");
  EXPECT_EQ(at(text, {{true, "m", 0}, {true, "E", 0}}), "4:13");
}

TEST(JsonError, LocatorDecodesEscapedKeys) {
  const std::string text = "{\"a\\\"b\": 1, \"c\\\\d\": 2, \"tab\\tkey\": 3}";
  EXPECT_EQ(at(text, {{true, "a\"b", 0}}), "1:10");
  EXPECT_EQ(at(text, {{true, "c\\d", 0}}), "1:21");
  EXPECT_EQ(at(text, {{true, "tab\tkey", 0}}), "1:36");
}

}  // namespace
