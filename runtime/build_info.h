// What build produced a binary: project version, git commit (with "-dirty"
// when the tree had local changes at configure time), compiler and flags.
// Stored with every sweep (coordinator) and every attempt (worker), so each
// number in the database can be traced to the code that produced it.
#ifndef TOTALGRAD_RUNTIME_BUILD_INFO_H_
#define TOTALGRAD_RUNTIME_BUILD_INFO_H_

#include <string>

namespace totalgrad {

// e.g. "totalgrad 0.1.0 git 5b4d8dc-dirty gcc 12.2.0 Release -O3 -march=x86-64-v2".
std::string BuildId();
// e.g. "0.1.0".
std::string ProjectVersion();

}  // namespace totalgrad

#endif  // TOTALGRAD_RUNTIME_BUILD_INFO_H_
