#include "io/text_file.h"

#include <fstream>

#include "absl/strings/str_cat.h"

namespace totalgrad::io {

absl::Status WriteTextFile(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  if (!out) return absl::UnavailableError(absl::StrCat("cannot write '", path, "'"));
  out << text;
  if (!out) return absl::UnavailableError(absl::StrCat("error writing '", path, "'"));
  return absl::OkStatus();
}

}  // namespace totalgrad::io
