// Plain text files for the CLI's outputs (tables, plot data and scripts).
#ifndef TOTALGRAD_IO_TEXT_FILE_H_
#define TOTALGRAD_IO_TEXT_FILE_H_

#include <string>

#include "absl/status/status.h"

namespace totalgrad::io {

// Writes `text` to `path` (created or truncated). Unavailable naming the path
// when it cannot be opened or written.
absl::Status WriteTextFile(const std::string& path, const std::string& text);

}  // namespace totalgrad::io

#endif  // TOTALGRAD_IO_TEXT_FILE_H_
