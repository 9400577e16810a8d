#include "runtime/token_file.h"

#include <sys/stat.h>

#include <fstream>
#include <sstream>

#include "absl/strings/ascii.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace totalgrad {

absl::StatusOr<TokenFile> ReadTokenFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot read token file ", path));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  TokenFile file;
  file.token = std::string(absl::StripAsciiWhitespace(buffer.str()));
  if (file.token.empty()) {
    return absl::InvalidArgumentError(absl::StrCat("token file ", path, " is empty"));
  }
  struct stat st;
  if (::stat(path.c_str(), &st) == 0 && (st.st_mode & (S_IRWXG | S_IRWXO)) != 0) {
    file.warning = absl::StrFormat(
        "token file %s has group or other permission bits (mode %04o): anyone who can read it "
        "can use the token; chmod 600 %s",
        path, st.st_mode & 07777, path);
  }
  return file;
}

}  // namespace totalgrad
