// Output of listings in the three formats every listing supports
// (-f table|json|csv): an aligned text table, a JSON array of objects, or
// RFC 4180 CSV with a header row.
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_FORMAT_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_FORMAT_H_

#include <ostream>
#include <string>
#include <vector>

namespace totalgrad::cli {

enum class Format { kTable, kJson, kCsv };

// "table", "json" or "csv"; false otherwise.
bool ParseFormat(const std::string& text, Format* format);

// A listing: column names and rows of cells. A cell is text; for JSON, a
// column listed in `numeric_columns` is written as a number when the cell
// parses as one (empty/"nan" become null).
struct Listing {
  std::vector<std::string> columns;
  std::vector<std::vector<std::string>> rows;
  std::vector<std::string> numeric_columns;
};

void Print(const Listing& listing, Format format, std::ostream& out);

// A CSV field, quoted when it holds a comma, quote or line break.
std::string CsvField(const std::string& text);
// A number for display: shortest round-trip text; "nan" for NaN.
std::string FormatNumber(double value);
// Fixed decimals (for tables).
std::string FormatFixed(double value, int decimals);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_FORMAT_H_
