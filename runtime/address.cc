#include "runtime/address.h"

namespace totalgrad {

std::string HostOf(const std::string& address) {
  std::string rest = address;
  for (const char* scheme : {"dns:///", "ipv4:", "ipv6:"}) {
    const std::string prefix(scheme);
    if (rest.compare(0, prefix.size(), prefix) == 0) rest = rest.substr(prefix.size());
  }
  if (!rest.empty() && rest[0] == '[') {
    const size_t close = rest.find(']');
    return close == std::string::npos ? rest : rest.substr(1, close - 1);
  }
  const size_t colon = rest.rfind(':');
  return colon == std::string::npos ? rest : rest.substr(0, colon);
}

bool IsLoopbackAddress(const std::string& address) {
  const std::string host = HostOf(address);
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

}  // namespace totalgrad
