// Telling "the coordinator answered with an error" from "no answer came".
//
// A status the coordinator's handlers return carries binary error details:
// a google.rpc.Status with the same code and message (the wire format gRPC
// defines for grpc-status-details-bin). A status the gRPC library makes on
// the client (no connection, the deadline passed before an answer, a
// message over the limit) carries none. So UNAVAILABLE from a full disk or a
// deleted database (the coordinator refused; a worker retries it, a user
// must act on the coordinator's side) is told apart from UNAVAILABLE of an
// unreachable address. Header only: both sides of the wire use it.
#ifndef TOTALGRAD_RUNTIME_STATUS_ORIGIN_H_
#define TOTALGRAD_RUNTIME_STATUS_ORIGIN_H_

#include <grpcpp/support/status.h>

#include <cstdint>
#include <string>

namespace totalgrad::rpc {

namespace internal {
inline void AppendVarint(uint64_t value, std::string* out) {
  while (value >= 0x80) {
    out->push_back(static_cast<char>((value & 0x7f) | 0x80));
    value >>= 7;
  }
  out->push_back(static_cast<char>(value));
}
}  // namespace internal

// The status a coordinator handler returns: `code` and `message` with the
// details that mark it as the coordinator's answer. OK stays plain OK.
inline grpc::Status CoordinatorStatus(grpc::StatusCode code, const std::string& message) {
  if (code == grpc::StatusCode::OK) return grpc::Status::OK;
  std::string details;  // google.rpc.Status{code = 1, message = 2}
  details.push_back(0x08);
  internal::AppendVarint(static_cast<uint64_t>(code), &details);
  details.push_back(0x12);
  internal::AppendVarint(message.size(), &details);
  details += message;
  return grpc::Status(code, message, details);
}

// Whether `status` is an error the coordinator itself answered with.
inline bool AnsweredByCoordinator(const grpc::Status& status) {
  return !status.ok() && !status.error_details().empty();
}

}  // namespace totalgrad::rpc

#endif  // TOTALGRAD_RUNTIME_STATUS_ORIGIN_H_
