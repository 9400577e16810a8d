// The text formats of a record (core/common/record.h): one CSV layout and
// one JSON layout per record, written and read through the record's field
// table by every path (`totalgrad study`'s files, `totalgrad results study`,
// the worker and coordinator have no format of their own).
//
// Numbers (docs/core.md, "Records"):
//   CSV   the shortest text that reads back as the same double (std::to_chars;
//         "0.1", "1e-05", "inf"); NaN is the empty field; integers in
//         decimal; bools 1 / 0; enumerators as their names ("running");
//         lists joined with ';' (pairs as key=text); a field holding a
//         comma, quote or line break is quoted as RFC 4180 says.
//   JSON  numbers as numbers (the same shortest round trip), NaN and +-inf as
//         null; bools true / false; enumerators as their names; lists as
//         arrays; (key, text) pairs as an array of [key, text] arrays.
// So a CSV or JSON value read back is the value written, bit for bit
// (non-finite values aside in JSON, where they read back as NaN).
//
// Thread safety: plain functions of their arguments.
#ifndef TOTALGRAD_IO_RECORD_FORMAT_H_
#define TOTALGRAD_IO_RECORD_FORMAT_H_

#include <charconv>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/common/record.h"

namespace totalgrad::io {

// A double as CSV text: shortest round trip, "" for NaN.
inline std::string RecordNumberText(double value) {
  if (std::isnan(value)) return "";
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

// A CSV field, quoted (quotes doubled) when it holds a comma, quote or line
// break (RFC 4180).
inline std::string CsvQuote(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) {
    if (c == '"') quoted += '"';
    quoted += c;
  }
  return quoted + "\"";
}

// One field's value as CSV text (unquoted).
template <typename R>
std::string RecordFieldText(const record::Field<R>& field, const R& r) {
  using record::FieldType;
  switch (field.type()) {
    case FieldType::kInt: return std::to_string(field.template Get<int>(r));
    case FieldType::kInt64: return std::to_string(field.template Get<int64_t>(r));
    case FieldType::kDouble: return RecordNumberText(field.template Get<double>(r));
    case FieldType::kBool: return field.template Get<bool>(r) ? "1" : "0";
    case FieldType::kDerivedBool: return field.DeriveBool(r) ? "1" : "0";
    case FieldType::kText: return field.template Get<std::string>(r);
    case FieldType::kEnum: return field.EnumToText(r);
    case FieldType::kDerivedText: return field.Derive(r);
    case FieldType::kInts: return absl::StrJoin(field.template Get<std::vector<int>>(r), ";");
    case FieldType::kTexts:
      return absl::StrJoin(field.template Get<std::vector<std::string>>(r), ";");
    case FieldType::kDoubles:
    case FieldType::kVector: {
      std::vector<std::string> parts;
      for (double v : record::DoublesOf(field, r)) parts.push_back(RecordNumberText(v));
      return absl::StrJoin(parts, ";");
    }
    case FieldType::kTextPairs: {
      std::vector<std::string> parts;
      for (const auto& [key, text] : field.template Get<record::TextPairs>(r)) {
        parts.push_back(absl::StrCat(key, "=", text));
      }
      return absl::StrJoin(parts, ";");
    }
  }
  return "";
}

// The CSV columns of a record (its csv fields, in table order).
template <typename R>
std::vector<std::string> RecordCsvColumns(const record::FieldTable<R>& table) {
  std::vector<std::string> columns;
  for (const auto& field : table) {
    if (field.csv) columns.push_back(field.name);
  }
  return columns;
}

// The record's CSV cells, unquoted, in RecordCsvColumns' order.
template <typename R>
std::vector<std::string> RecordCsvCells(const record::FieldTable<R>& table, const R& r) {
  std::vector<std::string> cells;
  for (const auto& field : table) {
    if (field.csv) cells.push_back(RecordFieldText(field, r));
  }
  return cells;
}

// A line of CSV (quoted cells, no line break).
inline std::string CsvLine(const std::vector<std::string>& cells) {
  std::vector<std::string> quoted;
  quoted.reserve(cells.size());
  for (const std::string& cell : cells) quoted.push_back(CsvQuote(cell));
  return absl::StrJoin(quoted, ",");
}

// Appends every field (derived ones included) to `out`, a JSON object
// (nlohmann::ordered_json: in table order), after what it holds.
template <typename R, typename Json>
void AppendRecordJson(const record::FieldTable<R>& table, const R& r, Json* out) {
  using record::FieldType;
  for (const auto& field : table) {
    Json& v = (*out)[field.name];
    switch (field.type()) {
      case FieldType::kInt: v = field.template Get<int>(r); break;
      case FieldType::kInt64: v = field.template Get<int64_t>(r); break;
      case FieldType::kEnum: v = field.EnumToText(r); break;
      case FieldType::kDerivedBool: v = field.DeriveBool(r); break;
      case FieldType::kDouble: {
        const double x = field.template Get<double>(r);
        v = std::isfinite(x) ? Json(x) : Json(nullptr);
        break;
      }
      case FieldType::kBool: v = field.template Get<bool>(r); break;
      case FieldType::kText: v = field.template Get<std::string>(r); break;
      case FieldType::kDerivedText: v = field.Derive(r); break;
      case FieldType::kInts: v = field.template Get<std::vector<int>>(r); break;
      case FieldType::kTexts: v = field.template Get<std::vector<std::string>>(r); break;
      case FieldType::kDoubles:
      case FieldType::kVector: {
        v = Json::array();
        for (double x : record::DoublesOf(field, r)) {
          v.push_back(std::isfinite(x) ? Json(x) : Json(nullptr));
        }
        break;
      }
      case FieldType::kTextPairs: {
        v = Json::array();
        for (const auto& [key, text] : field.template Get<record::TextPairs>(r)) {
          v.push_back(Json::array({key, text}));
        }
        break;
      }
    }
  }
}

template <typename R>
nlohmann::ordered_json RecordToJson(const record::FieldTable<R>& table, const R& r) {
  nlohmann::ordered_json out = nlohmann::ordered_json::object();
  AppendRecordJson(table, r, &out);
  return out;
}

// Reads the table's fields from a JSON object into *r. A missing key keeps
// *r's value (files written before the field existed); derived fields and
// unknown keys are ignored. InvalidArgument "<where><key>: <why>" for a
// mistyped value (a number for text, a fraction for an integer, ...); *r is
// then partly filled.
template <typename R, typename Json>
absl::Status RecordFromJson(const record::FieldTable<R>& table, const Json& object,
                            const std::string& where, R* r) {
  using record::FieldType;
  if (!object.is_object()) return absl::InvalidArgumentError(absl::StrCat(where, "not an object"));
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  auto fail = [&](const char* key, const char* why) {
    return absl::InvalidArgumentError(absl::StrCat(where, key, ": ", why));
  };
  for (const auto& field : table) {
    if (field.derived()) continue;
    const auto it = object.find(field.name);
    if (it == object.end()) continue;
    const Json& v = *it;
    switch (field.type()) {
      case FieldType::kInt:
        if (!v.is_number_integer()) return fail(field.name, "not an integer");
        field.template Get<int>(*r) = v.template get<int>();
        break;
      case FieldType::kInt64:
        if (!v.is_number_integer()) return fail(field.name, "not an integer");
        field.template Get<int64_t>(*r) = v.template get<int64_t>();
        break;
      case FieldType::kEnum:
        if (!v.is_string()) return fail(field.name, "not a string");
        if (!field.ParseEnum(v.template get<std::string>(), r)) {
          return absl::InvalidArgumentError(absl::StrCat(where, field.name, ": '",
                                                         v.template get<std::string>(),
                                                         "' is not one of its names"));
        }
        break;
      case FieldType::kDouble:
        if (v.is_null()) field.template Get<double>(*r) = kNaN;
        else if (v.is_number()) field.template Get<double>(*r) = v.template get<double>();
        else return fail(field.name, "not a number or null");
        break;
      case FieldType::kBool:
        if (!v.is_boolean()) return fail(field.name, "not true or false");
        field.template Get<bool>(*r) = v.template get<bool>();
        break;
      case FieldType::kText:
        if (!v.is_string()) return fail(field.name, "not a string");
        field.template Get<std::string>(*r) = v.template get<std::string>();
        break;
      case FieldType::kInts: {
        if (!v.is_array()) return fail(field.name, "not an array");
        std::vector<int> values;
        for (const Json& x : v) {
          if (!x.is_number_integer()) return fail(field.name, "holds an entry that is not an integer");
          values.push_back(x.template get<int>());
        }
        field.template Get<std::vector<int>>(*r) = std::move(values);
        break;
      }
      case FieldType::kTexts: {
        if (!v.is_array()) return fail(field.name, "not an array");
        std::vector<std::string> values;
        for (const Json& x : v) {
          if (!x.is_string()) return fail(field.name, "holds an entry that is not a string");
          values.push_back(x.template get<std::string>());
        }
        field.template Get<std::vector<std::string>>(*r) = std::move(values);
        break;
      }
      case FieldType::kDoubles:
      case FieldType::kVector: {
        if (!v.is_array()) return fail(field.name, "not an array");
        std::vector<double> values;
        for (const Json& x : v) {
          if (x.is_null()) values.push_back(kNaN);
          else if (x.is_number()) values.push_back(x.template get<double>());
          else return fail(field.name, "holds an entry that is not a number or null");
        }
        record::SetDoubles(field, std::move(values), r);
        break;
      }
      case FieldType::kTextPairs: {
        if (!v.is_array()) return fail(field.name, "not an array");
        record::TextPairs values;
        for (const Json& x : v) {
          if (!x.is_array() || x.size() != 2 || !x[0].is_string() || !x[1].is_string()) {
            return fail(field.name, "holds an entry that is not a [key, text] pair of strings");
          }
          values.emplace_back(x[0].template get<std::string>(), x[1].template get<std::string>());
        }
        field.template Get<record::TextPairs>(*r) = std::move(values);
        break;
      }
      case FieldType::kDerivedText:
      case FieldType::kDerivedBool: break;
    }
  }
  return absl::OkStatus();
}

}  // namespace totalgrad::io

#endif  // TOTALGRAD_IO_RECORD_FORMAT_H_
