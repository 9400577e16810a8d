#include "client/service_commands/format.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"

namespace totalgrad::cli {

bool ParseFormat(const std::string& text, Format* format) {
  if (text == "table") *format = Format::kTable;
  else if (text == "json") *format = Format::kJson;
  else if (text == "csv") *format = Format::kCsv;
  else return false;
  return true;
}

std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) {
    if (c == '"') quoted += "\"\"";
    else quoted += c;
  }
  return quoted + "\"";
}

std::string FormatNumber(double value) {
  if (std::isnan(value)) return "nan";
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

std::string FormatFixed(double value, int decimals) {
  if (std::isnan(value)) return "-";
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

std::string FormatInterval(double estimate, double low, double high, int decimals) {
  if (std::isnan(estimate)) return "-";
  return absl::StrCat(FormatFixed(estimate, decimals), " [", FormatFixed(low, decimals), ", ",
                      FormatFixed(high, decimals), "]");
}

std::string FormatRate(const results::WilsonRate& rate) {
  return FormatInterval(rate.rate, rate.low, rate.high, 2);
}

void Print(const Listing& listing, Format format, std::ostream& out) {
  switch (format) {
    case Format::kTable: {
      std::vector<size_t> width(listing.columns.size());
      for (size_t c = 0; c < listing.columns.size(); ++c) width[c] = listing.columns[c].size();
      for (const auto& row : listing.rows) {
        for (size_t c = 0; c < row.size() && c < width.size(); ++c) {
          width[c] = std::max(width[c], row[c].size());
        }
      }
      auto line = [&](const std::vector<std::string>& cells) {
        std::string text;
        for (size_t c = 0; c < width.size(); ++c) {
          const std::string cell = c < cells.size() ? cells[c] : "";
          text += cell;
          if (c + 1 < width.size()) text += std::string(width[c] - cell.size() + 2, ' ');
        }
        while (!text.empty() && text.back() == ' ') text.pop_back();
        out << text << "\n";
      };
      line(listing.columns);
      for (const auto& row : listing.rows) line(row);
      break;
    }
    case Format::kCsv: {
      for (size_t c = 0; c < listing.columns.size(); ++c) {
        out << (c ? "," : "") << CsvField(listing.columns[c]);
      }
      out << "\n";
      for (const auto& row : listing.rows) {
        for (size_t c = 0; c < row.size(); ++c) out << (c ? "," : "") << CsvField(row[c]);
        out << "\n";
      }
      break;
    }
    case Format::kJson: {
      nlohmann::ordered_json array = nlohmann::ordered_json::array();
      for (const auto& row : listing.rows) {
        nlohmann::ordered_json object = nlohmann::ordered_json::object();  // column order
        for (size_t c = 0; c < listing.columns.size() && c < row.size(); ++c) {
          const std::string& name = listing.columns[c];
          const bool numeric = std::find(listing.numeric_columns.begin(),
                                         listing.numeric_columns.end(),
                                         name) != listing.numeric_columns.end();
          if (numeric) {
            double value = 0;
            int64_t integer = 0;
            const char* end = row[c].data() + row[c].size();
            const auto as_integer = std::from_chars(row[c].data(), end, integer);
            const auto parsed = std::from_chars(row[c].data(), end, value);
            if (row[c].empty() || row[c] == "nan" || row[c] == "-") {
              object[name] = nullptr;
            } else if (as_integer.ec == std::errc() && as_integer.ptr == end) {
              object[name] = integer;
            } else if (parsed.ec == std::errc() && parsed.ptr == row[c].data() + row[c].size()) {
              object[name] = value;
            } else {
              object[name] = row[c];
            }
          } else {
            object[name] = row[c];
          }
        }
        array.push_back(object);
      }
      out << array.dump(2) << "\n";
      break;
    }
  }
}

}  // namespace totalgrad::cli
