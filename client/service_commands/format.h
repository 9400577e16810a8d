// Output of listings in the three formats every listing supports
// (-f table|json|csv): an aligned text table, a JSON array of objects, or
// RFC 4180 CSV with a header row.
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_FORMAT_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_FORMAT_H_

#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

#include "core/common/record.h"
#include "io/record_format.h"
#include "results/stats.h"

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

// Records with a field table (jobs, sweeps: server/storage/service_records.h)
// in -f json (an array of the records' objects, keys in table order) or -f csv
// (the table's CSV columns), in io/record_format.h's one format: every field,
// named as on every other path. -f table is a view each command chooses
// (Listing), so it is not written here; `format` must be kJson or kCsv.
template <typename R>
void PrintRecords(const record::FieldTable<R>& table, const std::vector<R>& records,
                  Format format, std::ostream& out) {
  if (format == Format::kCsv) {
    out << io::CsvLine(io::RecordCsvColumns(table)) << "\n";
    for (const R& r : records) out << io::CsvLine(io::RecordCsvCells(table, r)) << "\n";
    return;
  }
  nlohmann::ordered_json array = nlohmann::ordered_json::array();
  for (const R& r : records) array.push_back(io::RecordToJson(table, r));
  out << array.dump(2) << "\n";
}

// PrintRecords for records that arrive page by page: the same text, written
// as they come (Add), completed by Finish.
template <typename R>
class RecordPrinter {
 public:
  RecordPrinter(const record::FieldTable<R>& table, Format format, std::ostream& out)
      : table_(table), format_(format), out_(out) {}
  void Add(const R& r) {
    if (format_ == Format::kCsv) {
      if (count_++ == 0) out_ << io::CsvLine(io::RecordCsvColumns(table_)) << "\n";
      out_ << io::CsvLine(io::RecordCsvCells(table_, r)) << "\n";
      return;
    }
    // An element of PrintRecords' array.dump(2): its own dump(2), indented
    // (a JSON text has line breaks only between its tokens).
    out_ << (count_++ == 0 ? "[\n  " : ",\n  ");
    for (const char c : io::RecordToJson(table_, r).dump(2)) {
      out_ << c;
      if (c == '\n') out_ << "  ";
    }
  }
  void Finish() {
    if (format_ == Format::kCsv) {
      if (count_ == 0) out_ << io::CsvLine(io::RecordCsvColumns(table_)) << "\n";
      return;
    }
    out_ << (count_ == 0 ? "[]\n" : "\n]\n");
  }

 private:
  const record::FieldTable<R>& table_;
  Format format_;
  std::ostream& out_;
  int64_t count_ = 0;
};

// A CSV field, quoted when it holds a comma, quote or line break.
std::string CsvField(const std::string& text);
// A number for display: shortest round-trip text; "nan" for NaN.
std::string FormatNumber(double value);
// Fixed decimals (for tables).
std::string FormatFixed(double value, int decimals);
// An estimate with its interval for tables, fixed decimals:
// "0.90 [0.60, 0.98]"; "-" when the estimate is NaN (nothing to estimate from).
std::string FormatInterval(double estimate, double low, double high, int decimals);
// A rate with its Wilson interval, two decimals: FormatInterval of its three values.
std::string FormatRate(const results::WilsonRate& rate);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_FORMAT_H_
