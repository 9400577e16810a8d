// The output formats of every listing (client/service_commands/format.h):
// CSV quoting, typed JSON in column order, aligned text tables.
#include "client/service_commands/format.h"

#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

namespace totalgrad::cli {
namespace {

TEST(FormatTest, CsvQuotesOnlyWhenNeeded) {
  EXPECT_EQ(CsvField("plain"), "plain");
  EXPECT_EQ(CsvField("a,b"), "\"a,b\"");
  EXPECT_EQ(CsvField("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(CsvField("two\nlines"), "\"two\nlines\"");
}

TEST(FormatTest, JsonKeepsColumnOrderAndTypesNumbers) {
  Listing listing;
  listing.columns = {"name", "count", "cost"};
  listing.numeric_columns = {"count", "cost"};
  listing.rows = {{"x", "3", "1.5"}, {"y", "", "nan"}};
  std::ostringstream out;
  Print(listing, Format::kJson, out);
  EXPECT_EQ(out.str(),
            "[\n  {\n    \"name\": \"x\",\n    \"count\": 3,\n    \"cost\": 1.5\n  },\n  {\n"
            "    \"name\": \"y\",\n    \"count\": null,\n    \"cost\": null\n  }\n]\n");
}

TEST(FormatTest, TableAlignsColumns) {
  Listing listing;
  listing.columns = {"a", "bbb"};
  listing.rows = {{"long value", "1"}};
  std::ostringstream out;
  Print(listing, Format::kTable, out);
  EXPECT_EQ(out.str(), "a           bbb\nlong value  1\n");
}

TEST(FormatTest, IntervalsRoundToFixedDecimalsAndShowNothingForNaN) {
  EXPECT_EQ(FormatInterval(-0.5, -0.7249, -0.1351, 2), "-0.50 [-0.72, -0.14]");
  EXPECT_EQ(FormatInterval(std::nan(""), 0, 1, 2), "-");
  results::WilsonRate rate;  // 9 of 10: Wilson's 95% interval is [0.596, 0.982]
  for (int i = 0; i < 10; ++i) rate.Add(i != 3);
  EXPECT_EQ(FormatRate(rate), "0.90 [0.60, 0.98]");
  EXPECT_EQ(FormatRate(results::WilsonRate{}), "-");
}

}  // namespace
}  // namespace totalgrad::cli
