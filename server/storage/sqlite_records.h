// SQL column lists, binds and reads of a record (core/common/record.h)
// generated from its field table, so a stored record's INSERT and SELECT
// name every field exactly once, in the table's order. Internal to
// server/storage.
//
// Columns: a scalar field is the column of its name (REAL, NULL for NaN;
// INTEGER; INTEGER 0/1 for a bool; TEXT); a list field is "<name>_json", a
// JSON array (doubles at round-trip precision, non-finite as null; (key,
// text) pairs as [[key, text], ...], OptionsToJson's layout). A
// derived field is written (so a reader of the file sees it) and never read
// back: the record recomputes it. The table's own columns are created by the
// schema's migrations (sqlite_schema.cc); tests/service/records_test.cc
// checks that every field has its column.
//
// Threading: as internal::Statement.
#ifndef TOTALGRAD_SERVER_STORAGE_SQLITE_RECORDS_H_
#define TOTALGRAD_SERVER_STORAGE_SQLITE_RECORDS_H_

#include <cstdio>
#include <cstdlib>
#include <initializer_list>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/common/record.h"
#include "server/storage/sqlite_db.h"
#include "server/storage/sqlite_internal.h"

namespace totalgrad::storage::internal {

template <typename R>
std::string RecordColumn(const record::Field<R>& field) {
  return field.is_list() ? absl::StrCat(field.name, "_json") : std::string(field.name);
}

// The columns of the record, "prefix" before each ("c." for a joined
// query); with_derived false leaves the derived fields out (for reads).
template <typename R>
std::vector<std::string> RecordColumns(const record::FieldTable<R>& table, bool with_derived,
                                       const std::string& prefix = "") {
  std::vector<std::string> columns;
  for (const auto& field : table) {
    if (with_derived || !field.derived()) columns.push_back(prefix + RecordColumn(field));
  }
  return columns;
}

// "a, b, c" of RecordColumns.
template <typename R>
std::string RecordColumnList(const record::FieldTable<R>& table, bool with_derived,
                             const std::string& prefix = "") {
  return absl::StrJoin(RecordColumns(table, with_derived, prefix), ", ");
}

// Binds every field (derived ones included) to parameters first, first + 1,
// ... in table order; returns the next free parameter index.
template <typename R>
int BindRecord(Statement& statement, int first, const record::FieldTable<R>& table, const R& r) {
  using record::FieldType;
  int index = first;
  for (const auto& field : table) {
    switch (field.type()) {
      case FieldType::kInt: statement.Bind(index, field.template Get<int>(r)); break;
      case FieldType::kInt64: statement.Bind(index, field.template Get<int64_t>(r)); break;
      case FieldType::kEnum: statement.Bind(index, field.EnumToText(r)); break;
      case FieldType::kDerivedBool: statement.Bind(index, field.DeriveBool(r) ? 1 : 0); break;
      case FieldType::kDouble: statement.Bind(index, field.template Get<double>(r)); break;
      case FieldType::kBool: statement.Bind(index, field.template Get<bool>(r) ? 1 : 0); break;
      case FieldType::kText: statement.Bind(index, field.template Get<std::string>(r)); break;
      case FieldType::kDerivedText: statement.Bind(index, field.Derive(r)); break;
      case FieldType::kInts:
        statement.Bind(index, nlohmann::json(field.template Get<std::vector<int>>(r)).dump());
        break;
      case FieldType::kTexts:
        statement.Bind(index,
                       nlohmann::json(field.template Get<std::vector<std::string>>(r)).dump());
        break;
      case FieldType::kDoubles:
      case FieldType::kVector: statement.Bind(index, DoublesToJson(record::DoublesOf(field, r))); break;
      case FieldType::kTextPairs:
        statement.Bind(index, OptionsToJson(field.template Get<record::TextPairs>(r)));
        break;
    }
    ++index;
  }
  return index;
}

// Reads the non-derived fields from result columns first, first + 1, ...
// (a SELECT of RecordColumnList(table, false)); returns the next column.
// A list column that is not a JSON array reads as an empty list.
template <typename R>
int ReadRecord(const Statement& query, int first, const record::FieldTable<R>& table, R* r) {
  using record::FieldType;
  int column = first;
  for (const auto& field : table) {
    if (field.derived()) continue;
    switch (field.type()) {
      case FieldType::kInt:
        field.template Get<int>(*r) = static_cast<int>(query.ColumnInt(column));
        break;
      case FieldType::kInt64: field.template Get<int64_t>(*r) = query.ColumnInt(column); break;
      case FieldType::kEnum:
        // A name this build does not know leaves the field's value (as a
        // proto read does); the store's own enums are CHECK-constrained.
        field.ParseEnum(query.ColumnText(column), r);
        break;
      case FieldType::kDouble: field.template Get<double>(*r) = query.ColumnDouble(column); break;
      case FieldType::kBool: field.template Get<bool>(*r) = query.ColumnInt(column) != 0; break;
      case FieldType::kText: field.template Get<std::string>(*r) = query.ColumnText(column); break;
      case FieldType::kInts: {
        std::vector<int>& values = field.template Get<std::vector<int>>(*r);
        values.clear();
        const nlohmann::json array = nlohmann::json::parse(query.ColumnText(column), nullptr, false);
        if (array.is_array()) {
          for (const auto& n : array) values.push_back(n.is_number_integer() ? n.get<int>() : 0);
        }
        break;
      }
      case FieldType::kTexts: {
        std::vector<std::string>& values = field.template Get<std::vector<std::string>>(*r);
        values.clear();
        const nlohmann::json array = nlohmann::json::parse(query.ColumnText(column), nullptr, false);
        if (array.is_array()) {
          for (const auto& u : array) values.push_back(u.is_string() ? u.get<std::string>() : "");
        }
        break;
      }
      case FieldType::kDoubles:
      case FieldType::kVector:
        record::SetDoubles(field, DoublesFromJson(query.ColumnText(column)), r);
        break;
      case FieldType::kTextPairs:
        field.template Get<record::TextPairs>(*r) = OptionsFromJson(query.ColumnText(column));
        break;
      case FieldType::kDerivedText:
      case FieldType::kDerivedBool: break;
    }
    ++column;
  }
  return column;
}

// A record read by a query whose values are not all plain columns (joins,
// counts, COALESCEs): its fields in read order, and the SELECT list that
// yields them in that order. ReadRecord(query, 0, view.fields, &r) reads a
// row of "SELECT " + view.select_list + " FROM ...".
// A record table and its SQL disagree: a programmer error (check.h's rule),
// reported with the field's name before aborting.
[[noreturn]] inline void RecordSqlMismatch(const std::string& what) {
  std::fprintf(stderr, "record/SQL mismatch: %s\n", what.c_str());
  std::abort();
}

template <typename R>
struct SqlView {
  record::FieldTable<R> fields;
  std::string select_list;
};

// The view of the non-derived fields of `tables`, in their order, each read
// from its expression in `sql` (field name -> SQL expression); the fields
// named in `computed` are left out (the reader fills them after the row:
// counts over other rows, rules of the job's kind). A field with neither, or
// an expression naming no field, is a programmer error (TG_CHECK; every
// store test reads records, so it cannot go unnoticed). So adding a field
// to a record's table without saying where the store reads it from fails
// the first test that lists the record, instead of a column silently
// missing or read from the wrong position.
template <typename R>
SqlView<R> MakeSqlView(std::initializer_list<const record::FieldTable<R>*> tables,
                       const std::map<std::string, std::string>& sql,
                       const std::set<std::string>& computed) {
  SqlView<R> view;
  std::vector<std::string> expressions;
  std::set<std::string> used;
  for (const record::FieldTable<R>* table : tables) {
    for (const auto& field : *table) {
      if (field.derived() || computed.count(field.name) > 0) continue;
      const auto it = sql.find(field.name);
      if (it == sql.end()) {
        RecordSqlMismatch(absl::StrCat("record field '", field.name,
                                       "' has no SQL expression to read it from"));
      }
      view.fields.push_back(field);
      expressions.push_back(it->second);
      used.insert(field.name);
    }
  }
  for (const auto& [name, expression] : sql) {
    if (used.count(name) == 0) {
      RecordSqlMismatch(absl::StrCat("SQL expression '", expression, "' names no field ('",
                                     name, "') of its record"));
    }
  }
  view.select_list = absl::StrJoin(expressions, ", ");
  return view;
}

}  // namespace totalgrad::storage::internal

#endif  // TOTALGRAD_SERVER_STORAGE_SQLITE_RECORDS_H_
