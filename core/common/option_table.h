// Named options of a plain options struct: each field has one key, a parser
// from text and a canonical text, declared once in a table that the struct
// owns (e.g. tasks::SceneOptions::Table()). A struct that holds other
// options structs composes their tables (Nest), so a key is written in
// exactly one place and the composed table (learner::TrialOptions::Table())
// is what the CLI flags, sweep files, the service and trial snapshots use.
//
// Contract of every table: for any options value o,
//   Set(k, v) for each (k, v) in Pairs(o), applied to a default value,
//   gives back o (tests/core/learner/trial_options_test.cc checks it for the
//   trial's whole table with every field set to a non-default value).
// Canonical texts: doubles "%.17g" (round trip), integers in decimal, bools
// "true"/"false", enums their name in the field's EnumNames.
//
// Errors of Set: InvalidArgument naming the key and the text ("option
// 'particles': 'many' is not an integer"), or an unknown key with the list of
// known ones. A key added twice to one table is a programmer error
// (TG_CHECK).
//
// Thread safety: a table is immutable once built; the static tables are
// built on first use (thread-safe function-local statics).
#ifndef TOTALGRAD_CORE_COMMON_OPTION_TABLE_H_
#define TOTALGRAD_CORE_COMMON_OPTION_TABLE_H_

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/common/check.h"
#include "core/common/closest_word.h"
#include "core/common/option_pairs.h"

namespace totalgrad {

// The canonical names of an enum's values, each value once.
template <typename E>
using EnumNames = std::vector<std::pair<E, std::string>>;

// Parsers with the messages every table uses: "option 'KEY': 'TEXT' is not
// a finite number", "... is not an integer", "... is out of range; counts
// are at most 2147483647", "... is not a non-negative integer", "... is not
// true/false".
absl::Status ParseOptionDouble(absl::string_view key, absl::string_view text, double* out);
absl::Status ParseOptionInt(absl::string_view key, absl::string_view text, int* out);
absl::Status ParseOptionUint64(absl::string_view key, absl::string_view text, uint64_t* out);
absl::Status ParseOptionBool(absl::string_view key, absl::string_view text, bool* out);
// "%.17g": parses back to the same double.
std::string FormatOptionDouble(double value);

// The values of a numeric option that mean something physically (or
// numerically), with what the option is, for the message. Values outside are
// refused when the option is set, i.e. at submission, not at run time.
struct OptionRange {
  double min;
  double max;
  const char* meaning;  // e.g. "observation noise variance multiplier"
};
// InvalidArgument "option 'noise_k': 1e+308 is out of range: allowed 0 to
// 10000 (observation noise variance multiplier)" unless min <= value <= max.
absl::Status CheckOptionRange(absl::string_view key, double value, const OptionRange& range);
// InvalidArgument "option 'KEY' WHY", the form of every Validate() message.
absl::Status InvalidOption(absl::string_view key, absl::string_view why);

// The name of `value` in `names` ("" if it is not listed: an enum value set
// by a cast, which Validate() functions refuse).
template <typename E>
std::string EnumName(const EnumNames<E>& names, E value) {
  for (const auto& [v, name] : names)
    if (v == value) return name;
  return "";
}

template <typename E>
bool IsNamedEnum(const EnumNames<E>& names, E value) {
  for (const auto& entry : names)
    if (entry.first == value) return true;
  return false;
}

// "option 'KEY': 'TEXT' is not one of a, b, c" for an unknown name.
template <typename E>
absl::Status ParseEnum(absl::string_view key, absl::string_view text, const EnumNames<E>& names,
                       E* out) {
  std::vector<std::string> known;
  for (const auto& [v, name] : names) {
    if (name == text) {
      *out = v;
      return absl::OkStatus();
    }
    known.push_back(name);
  }
  return absl::InvalidArgumentError(absl::StrCat("option '", key, "': '", text,
                                                 "' is not one of ", absl::StrJoin(known, ", ")));
}

// What kind of value an option holds, for readers that type its canonical
// text (CLI help, typed export columns, the Python module): a number (a
// double, "1" included), an integer, true/false, one of `choices`, or text.
enum class OptionType { kNumber, kInteger, kBool, kChoice, kText };
// "number", "integer", "bool", "choice", "text".
const char* OptionTypeName(OptionType type);

template <typename T>
class OptionTable {
 public:
  struct Field {
    std::string key;
    std::function<absl::Status(absl::string_view text, T* options)> set;
    std::function<std::string(const T& options)> get;
    OptionType type = OptionType::kText;
    std::vector<std::string> choices;  // kChoice: the accepted names
  };

  // Builders, in the order the fields are listed by Pairs() and Keys().
  OptionTable& Custom(std::string key, std::function<absl::Status(absl::string_view, T*)> set,
                      std::function<std::string(const T&)> get,
                      OptionType type = OptionType::kText, std::vector<std::string> choices = {}) {
    for (const Field& f : fields_) TG_CHECK(f.key != key);
    fields_.push_back({std::move(key), std::move(set), std::move(get), type, std::move(choices)});
    return *this;
  }
  OptionTable& Double(const std::string& key, double T::*member) {
    return Custom(
        key, [key, member](absl::string_view text, T* o) { return ParseOptionDouble(key, text, &(o->*member)); },
        [member](const T& o) { return FormatOptionDouble(o.*member); }, OptionType::kNumber);
  }
  // A double that must lie in `range` (CheckOptionRange).
  OptionTable& Double(const std::string& key, double T::*member, OptionRange range) {
    return Custom(
        key,
        [key, member, range](absl::string_view text, T* o) {
          double value = 0;
          if (absl::Status st = ParseOptionDouble(key, text, &value); !st.ok()) return st;
          if (absl::Status st = CheckOptionRange(key, value, range); !st.ok()) return st;
          o->*member = value;
          return absl::OkStatus();
        },
        [member](const T& o) { return FormatOptionDouble(o.*member); }, OptionType::kNumber);
  }
  // An int that must lie in `range` (CheckOptionRange).
  OptionTable& Int(const std::string& key, int T::*member, OptionRange range) {
    return Custom(
        key,
        [key, member, range](absl::string_view text, T* o) {
          int value = 0;
          if (absl::Status st = ParseOptionInt(key, text, &value); !st.ok()) return st;
          if (absl::Status st = CheckOptionRange(key, value, range); !st.ok()) return st;
          o->*member = value;
          return absl::OkStatus();
        },
        [member](const T& o) { return std::to_string(o.*member); }, OptionType::kInteger);
  }
  OptionTable& Int(const std::string& key, int T::*member) {
    return Custom(
        key, [key, member](absl::string_view text, T* o) { return ParseOptionInt(key, text, &(o->*member)); },
        [member](const T& o) { return std::to_string(o.*member); }, OptionType::kInteger);
  }
  OptionTable& Uint64(const std::string& key, uint64_t T::*member) {
    return Custom(
        key, [key, member](absl::string_view text, T* o) { return ParseOptionUint64(key, text, &(o->*member)); },
        [member](const T& o) { return std::to_string(o.*member); }, OptionType::kInteger);
  }
  OptionTable& Bool(const std::string& key, bool T::*member) {
    return Custom(
        key, [key, member](absl::string_view text, T* o) { return ParseOptionBool(key, text, &(o->*member)); },
        [member](const T& o) { return std::string(o.*member ? "true" : "false"); },
        OptionType::kBool);
  }
  OptionTable& String(const std::string& key, std::string T::*member) {
    return Custom(
        key,
        [member](absl::string_view text, T* o) {
          o->*member = std::string(text);
          return absl::OkStatus();
        },
        [member](const T& o) { return o.*member; });
  }
  // `names` is copied into the field.
  template <typename E>
  OptionTable& Enum(const std::string& key, E T::*member, const EnumNames<E>& names) {
    std::vector<std::string> choices;
    for (const auto& entry : names) choices.push_back(entry.second);
    return Custom(
        key, [key, member, names](absl::string_view text, T* o) { return ParseEnum(key, text, names, &(o->*member)); },
        [member, names](const T& o) { return EnumName(names, o.*member); }, OptionType::kChoice,
        std::move(choices));
  }
  // Every field of `inner` (keys unchanged), reading and writing o.*member.
  template <typename S>
  OptionTable& Nest(S T::*member, const OptionTable<S>& inner) {
    for (const typename OptionTable<S>::Field& f : inner.fields()) {
      auto set = f.set;
      auto get = f.get;
      Custom(
          f.key, [set, member](absl::string_view text, T* o) { return set(text, &(o->*member)); },
          [get, member](const T& o) { return get(o.*member); }, f.type, f.choices);
    }
    return *this;
  }

  // Sets the field named `key` from `text`; *options is unchanged on error.
  absl::Status Set(absl::string_view key, absl::string_view text, T* options) const {
    for (const Field& f : fields_) {
      if (f.key != key) continue;
      T scratch = *options;
      if (absl::Status st = f.set(text, &scratch); !st.ok()) return st;
      *options = std::move(scratch);
      return absl::OkStatus();
    }
    const std::vector<std::string> keys = Keys();
    if (const std::string close = ClosestCandidate(std::string(key), keys); !close.empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat("unknown option '", key, "'; did you mean '", close, "'?"));
    }
    return absl::InvalidArgumentError(
        absl::StrCat("unknown option '", key, "'; known: ", absl::StrJoin(keys, ", ")));
  }
  OptionPairs Pairs(const T& options) const {
    OptionPairs pairs;
    pairs.reserve(fields_.size());
    for (const Field& f : fields_) pairs.emplace_back(f.key, f.get(options));
    return pairs;
  }
  std::vector<std::string> Keys() const {
    std::vector<std::string> keys;
    keys.reserve(fields_.size());
    for (const Field& f : fields_) keys.push_back(f.key);
    return keys;
  }
  // The field named `key`, or null.
  const Field* Find(absl::string_view key) const {
    for (const Field& f : fields_)
      if (f.key == key) return &f;
    return nullptr;
  }
  bool Has(absl::string_view key) const {
    for (const Field& f : fields_)
      if (f.key == key) return true;
    return false;
  }
  const std::vector<Field>& fields() const { return fields_; }

 private:
  std::vector<Field> fields_;
};

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_OPTION_TABLE_H_
