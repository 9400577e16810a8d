// (key, canonical text) pairs: how options travel between the option table
// (core/common/option_table.h), sweeps, the store and the worker. One type for
// all of them; the texts are each option's canonical form, in a table's order.
#ifndef TOTALGRAD_CORE_COMMON_OPTION_PAIRS_H_
#define TOTALGRAD_CORE_COMMON_OPTION_PAIRS_H_

#include <string>
#include <utility>
#include <vector>

namespace totalgrad {

using OptionPairs = std::vector<std::pair<std::string, std::string>>;

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_OPTION_PAIRS_H_
