#include "core/common/option_table.h"

#include <cmath>
#include <cstdio>
#include <limits>

#include "absl/strings/numbers.h"

namespace totalgrad {

absl::Status ParseOptionDouble(absl::string_view key, absl::string_view text, double* out) {
  double v;
  if (!absl::SimpleAtod(text, &v) || !std::isfinite(v))
    return absl::InvalidArgumentError(absl::StrCat("option '", key, "': '", text, "' is not a finite number"));
  *out = v;
  return absl::OkStatus();
}

absl::Status CheckOptionRange(absl::string_view key, double value, const OptionRange& range) {
  if (value >= range.min && value <= range.max) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat("option '", key, "': ", value,
                                                 " is out of range: allowed ", range.min, " to ",
                                                 range.max, " (", range.meaning, ")"));
}

absl::Status ParseOptionInt(absl::string_view key, absl::string_view text, int* out) {
  int v;
  if (!absl::SimpleAtoi(text, &v)) {
    // A whole number too large for an int ("1e12", "3000000000") is out of
    // range, not "not an integer".
    double d;
    if (absl::SimpleAtod(text, &d) && std::isfinite(d) && d == std::floor(d) &&
        std::fabs(d) > std::numeric_limits<int>::max())
      return absl::InvalidArgumentError(absl::StrCat("option '", key, "': ", text,
                                                     " is out of range; counts are at most ",
                                                     std::numeric_limits<int>::max()));
    return absl::InvalidArgumentError(absl::StrCat("option '", key, "': '", text, "' is not an integer"));
  }
  *out = v;
  return absl::OkStatus();
}

absl::Status ParseOptionUint64(absl::string_view key, absl::string_view text, uint64_t* out) {
  uint64_t v;
  if (!absl::SimpleAtoi(text, &v))
    return absl::InvalidArgumentError(
        absl::StrCat("option '", key, "': '", text, "' is not a non-negative integer"));
  *out = v;
  return absl::OkStatus();
}

const char* OptionTypeName(OptionType type) {
  switch (type) {
    case OptionType::kNumber: return "number";
    case OptionType::kInteger: return "integer";
    case OptionType::kBool: return "bool";
    case OptionType::kChoice: return "choice";
    case OptionType::kText: return "text";
  }
  return "text";
}

absl::Status ParseOptionBool(absl::string_view key, absl::string_view text, bool* out) {
  if (text == "true" || text == "1") {
    *out = true;
    return absl::OkStatus();
  }
  if (text == "false" || text == "0") {
    *out = false;
    return absl::OkStatus();
  }
  return absl::InvalidArgumentError(absl::StrCat("option '", key, "': '", text, "' is not true/false"));
}

std::string FormatOptionDouble(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof(buffer), "%.17g", value);
  return buffer;
}

absl::Status InvalidOption(absl::string_view key, absl::string_view why) {
  return absl::InvalidArgumentError(absl::StrCat("option '", key, "' ", why));
}

}  // namespace totalgrad
