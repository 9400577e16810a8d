// "Did you mean ...?": the closest of a set of known words to a mistyped one.
// Used for command-line flags (client/core_commands/cli_suggest.h) and for
// option keys (core/common/option_table.h: sweep files, --set, trial flags).
#ifndef TOTALGRAD_CORE_COMMON_CLOSEST_WORD_H_
#define TOTALGRAD_CORE_COMMON_CLOSEST_WORD_H_

#include <string>
#include <vector>

namespace totalgrad {

// Levenshtein distance (insert, delete, substitute: 1 each).
int EditDistance(const std::string& a, const std::string& b);

// The candidate closest to `word` if it is close enough to be a typo (edit
// distance <= max(1, |word| / 3), or `word` is a prefix of exactly one
// candidate), else "".
std::string ClosestCandidate(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_CLOSEST_WORD_H_
