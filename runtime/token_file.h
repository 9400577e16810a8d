// Bearer tokens kept in files (coordinator, worker and CLI read them the same
// way).
//
// Threading: free functions, no shared state.
#ifndef TOTALGRAD_RUNTIME_TOKEN_FILE_H_
#define TOTALGRAD_RUNTIME_TOKEN_FILE_H_

#include <string>

#include "absl/status/statusor.h"

namespace totalgrad {

struct TokenFile {
  std::string token;  // the file's content without surrounding whitespace
  // Non-empty if the file may be read by others than its owner (group or
  // other permission bits): a sentence naming the file, its mode and the fix.
  // The token is still used; whoever can read the file can act with it.
  std::string warning;
};

// NotFound if the file cannot be read, InvalidArgument if it holds only
// whitespace.
absl::StatusOr<TokenFile> ReadTokenFile(const std::string& path);

}  // namespace totalgrad

#endif  // TOTALGRAD_RUNTIME_TOKEN_FILE_H_
