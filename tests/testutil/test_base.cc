#include "tests/testutil/test_base.h"

#include <stdlib.h>

#include <filesystem>

namespace totalgrad::testing {

std::string MakeTempDir() {
  const char* base = std::getenv("TEST_TMPDIR");
  std::string pattern =
      (std::filesystem::path(base ? base : std::filesystem::temp_directory_path().string()) /
       "totalgrad_test_XXXXXX")
          .string();
  char* made = mkdtemp(pattern.data());
  if (made == nullptr) {
    ADD_FAILURE() << "mkdtemp failed for " << pattern;
    return "/tmp";
  }
  return made;
}

}  // namespace totalgrad::testing
