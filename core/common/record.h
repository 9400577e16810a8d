// One description per record (issue 13): a result record's fields written
// once, as a table of (name, type, where the value lives, whether it is a
// CSV column), beside the struct that holds them. Every path that copies
// the record reads the table instead of naming the fields again:
//   io/record_format.h          CSV header and rows, JSON objects (write, read)
//   runtime/record_proto.h  the proto message, by reflection on names
//   server/storage/sqlite_records.h  SQL column lists, binds and reads
// so a field added to the struct and its table line reaches every writer,
// and a path that drops one is a test failure (tests/service/records_test.cc),
// not a silent copy that drifted.
//
// Contract of a table:
//   * a value lives in a member of the record or of a record it holds by
//     value (Nested: a small record such as a rate with its interval,
//     shared by several records), and is written flat under its own name;
//   * names are unique and are, verbatim, the CSV column, the JSON key, the
//     proto field's name and (lists with the suffix "_json") the SQL column;
//   * the order is the CSV's column order and the JSON's key order;
//   * a derived field is computed from the others (a getter, no storage in
//     the struct): every writer writes it, every reader ignores it, so a
//     stored copy can never disagree with the record it was computed from.
// The formats themselves (one per record on every path: shortest round-trip
// numbers, NaN as an empty CSV field, null in JSON and NULL in SQL) are
// io/record_format.h's and docs/core.md "Records".
//
// Header only; core/ still writes no files: this file knows no format.
#ifndef TOTALGRAD_CORE_COMMON_RECORD_H_
#define TOTALGRAD_CORE_COMMON_RECORD_H_

#include <cstdint>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "core/common/types.h"

namespace totalgrad::record {

// The value types a record field may have. kVector is an Eigen vector
// (core's gradients); on the wire and in files it is a list of doubles like
// kDoubles. kInt64 is a 64-bit integer (ids, Unix milliseconds). kEnum is an
// enumerator member written everywhere as its text (EnumText: "queued",
// "lease_lost"), so the files and the database hold a name a reader can
// check, never a number that means something else after a reordering.
// kDerivedText and kDerivedBool are derived fields (getters). kTextPairs is
// an ordered list of (key, text) pairs (a job's options); in JSON, SQL and
// protos it keeps its order and any repeated key: a JSON array of
// [key, text] arrays, a proto's repeated message with string fields `key`
// and `value`, and in CSV "key=text" entries joined with ';'.
enum class FieldType {
  kInt, kDouble, kBool, kText, kDoubles, kInts, kTexts, kVector, kDerivedText,
  kInt64, kEnum, kDerivedBool, kTextPairs
};

using TextPairs = std::vector<std::pair<std::string, std::string>>;

// How an enumerator member of R is read and written as text: to_text gives
// the member's name ("running"); parse sets the member from a name and
// returns false (leaving *r as it was) for a text that names no enumerator.
// Written once per enum as a pair of plain functions (captureless lambdas),
// e.g. around storage::ToString(JobState) and storage::ParseJobState.
template <typename R>
struct EnumText {
  std::string (*to_text)(const R&);
  bool (*parse)(const std::string& text, R* r);
};

// Where a field's value of type T lives in a record R: a data member of R
// (a table line writes `&R::name`, converted implicitly), or a member of a
// record that R holds by value (Nested<&R::outer, &Inner::name>()), so that
// records can share a small record (a rate with its interval) and still be
// written flat, one column per value.
template <typename R, typename T>
class Slot {
 public:
  Slot(T R::*member) : member_(member) {}  // NOLINT(runtime/explicit): see above
  Slot(T& (*mutable_at)(R&), const T& (*at)(const R&)) : mutable_at_(mutable_at), at_(at) {}

  const T& Of(const R& r) const { return member_ != nullptr ? r.*member_ : at_(r); }
  T& Of(R& r) const { return member_ != nullptr ? r.*member_ : mutable_at_(r); }

 private:
  T R::*member_ = nullptr;
  T& (*mutable_at_)(R&) = nullptr;
  const T& (*at_)(const R&) = nullptr;
};

template <typename M>
struct MemberOf;
template <typename C, typename V>
struct MemberOf<V C::*> {
  using Class = C;
  using Value = V;
};

// The member at the end of a path of members: At<&A::b, &B::c>(a) is a.b.c.
template <auto kFirst, auto... kRest, typename Object>
decltype(auto) At(Object& object) {
  if constexpr (sizeof...(kRest) == 0) {
    return (object.*kFirst);
  } else {
    return At<kRest...>(object.*kFirst);
  }
}

template <auto kFirst, auto... kRest>
struct PathOf {
  using Record = typename MemberOf<decltype(kFirst)>::Class;
  using Value = typename PathOf<kRest...>::Value;
};
template <auto kLast>
struct PathOf<kLast> {
  using Record = typename MemberOf<decltype(kLast)>::Class;
  using Value = typename MemberOf<decltype(kLast)>::Value;
};

// The slot of the member at the end of a path that starts in the record:
// Nested<&TableCell::success, &WilsonRate::rate>() is cell.success.rate.
template <auto... kPath>
Slot<typename PathOf<kPath...>::Record, typename PathOf<kPath...>::Value> Nested() {
  using R = typename PathOf<kPath...>::Record;
  using T = typename PathOf<kPath...>::Value;
  return Slot<R, T>(+[](R& r) -> T& { return At<kPath...>(r); },
                    +[](const R& r) -> const T& { return At<kPath...>(r); });
}

template <typename R>
struct Field {
  // The alternatives are in FieldType's order (type() is the index).
  using Member = std::variant<Slot<R, int>, Slot<R, double>, Slot<R, bool>, Slot<R, std::string>,
                              Slot<R, std::vector<double>>, Slot<R, std::vector<int>>,
                              Slot<R, std::vector<std::string>>, Slot<R, Vector>,
                              std::string (*)(const R&), Slot<R, int64_t>, EnumText<R>,
                              bool (*)(const R&), Slot<R, TextPairs>>;
  const char* name;
  Member member;
  // A column of the record's CSV (long lists and free-text details that a
  // spreadsheet cannot use are JSON-only).
  bool csv = true;

  FieldType type() const { return static_cast<FieldType>(member.index()); }
  bool derived() const {
    return type() == FieldType::kDerivedText || type() == FieldType::kDerivedBool;
  }
  // The value of a field of type T (the caller switched on type()).
  template <typename T>
  const T& Get(const R& r) const { return std::get<Slot<R, T>>(member).Of(r); }
  template <typename T>
  T& Get(R& r) const { return std::get<Slot<R, T>>(member).Of(r); }
  // A derived field's value (kDerivedText, kDerivedBool).
  std::string Derive(const R& r) const { return std::get<std::string (*)(const R&)>(member)(r); }
  bool DeriveBool(const R& r) const { return std::get<bool (*)(const R&)>(member)(r); }
  // A kEnum field's value as text, and the field set from a text (false, *r
  // unchanged, for a text that names no enumerator).
  std::string EnumToText(const R& r) const { return std::get<EnumText<R>>(member).to_text(r); }
  bool ParseEnum(const std::string& text, R* r) const {
    return std::get<EnumText<R>>(member).parse(text, r);
  }
  // True for the list types (stored as one JSON text, "<name>_json").
  bool is_list() const {
    const FieldType t = type();
    return t == FieldType::kDoubles || t == FieldType::kInts || t == FieldType::kTexts ||
           t == FieldType::kVector || t == FieldType::kTextPairs;
  }
};

template <typename R>
using FieldTable = std::vector<Field<R>>;

// The value of a list field of doubles (kDoubles or kVector) as a std::vector.
template <typename R>
std::vector<double> DoublesOf(const Field<R>& field, const R& r) {
  if (field.type() == FieldType::kVector) {
    const Vector& v = field.template Get<Vector>(r);
    return std::vector<double>(v.data(), v.data() + v.size());
  }
  return field.template Get<std::vector<double>>(r);
}
template <typename R>
void SetDoubles(const Field<R>& field, std::vector<double> values, R* r) {
  if (field.type() == FieldType::kVector) {
    field.template Get<Vector>(*r) =
        Eigen::Map<const Vector>(values.data(), static_cast<Eigen::Index>(values.size()));
  } else {
    field.template Get<std::vector<double>>(*r) = std::move(values);
  }
}

}  // namespace totalgrad::record

#endif  // TOTALGRAD_CORE_COMMON_RECORD_H_
