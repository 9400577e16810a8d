// Network address helpers shared by the coordinator, worker and CLI.
#ifndef TOTALGRAD_RUNTIME_ADDRESS_H_
#define TOTALGRAD_RUNTIME_ADDRESS_H_

#include <string>

namespace totalgrad {

// The host part of "host:port", "[v6]:port" or "dns:///host:port".
std::string HostOf(const std::string& address);
// True for localhost, 127.0.0.0/8 and ::1 (plaintext is allowed only there).
bool IsLoopbackAddress(const std::string& address);

}  // namespace totalgrad

#endif  // TOTALGRAD_RUNTIME_ADDRESS_H_
