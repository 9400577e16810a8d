// Bearer-token authorisation of every call.
//
// Two roles: a worker token may call only WorkerService, a user token only
// ControlService. A call without "authorization: Bearer <token>" or with an
// unknown token gets UNAUTHENTICATED; a known token of the other role gets
// PERMISSION_DENIED. Tokens are compared in constant time and never logged.
//
// With no tokens configured (only allowed with --insecure on loopback) every
// call is allowed.
//
// Threading: immutable after construction; Check is safe from any thread.
#ifndef TOTALGRAD_SERVER_SERVICE_AUTH_H_
#define TOTALGRAD_SERVER_SERVICE_AUTH_H_

#include <grpcpp/server_context.h>

#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace totalgrad::service {

enum class Role { kWorker, kUser };

class TokenAuthenticator {
 public:
  // Empty tokens mean "no tokens" (both must then be empty). InvalidArgument
  // if only one is set, either is shorter than 16 characters, or they are equal.
  static absl::StatusOr<TokenAuthenticator> Create(std::string worker_token,
                                                   std::string user_token);
  bool enabled() const { return !worker_token_.empty(); }

  // OK, Unauthenticated or PermissionDenied as described above.
  absl::Status Check(const grpc::ServerContext& context, Role role) const;
  // The same check of an authorization value ("Bearer <token>") that came
  // by another way than gRPC metadata (the dashboard's HTTP requests);
  // nullptr means the request carried none.
  absl::Status CheckBearer(const std::string* authorization, Role role) const;

 private:
  TokenAuthenticator(std::string worker_token, std::string user_token)
      : worker_token_(std::move(worker_token)), user_token_(std::move(user_token)) {}
  std::string worker_token_;
  std::string user_token_;
};

// Tokens are read from files with totalgrad::ReadTokenFile (runtime/token_file.h).

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_AUTH_H_
