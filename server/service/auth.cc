#include "server/service/auth.h"

#include <openssl/crypto.h>

#include <fstream>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "absl/strings/strip.h"
#include "absl/strings/ascii.h"

namespace totalgrad::service {
namespace {

bool SameToken(const std::string& given, const std::string& expected) {
  // Length is not secret (tokens have a fixed format); contents are compared
  // in constant time.
  return given.size() == expected.size() &&
         CRYPTO_memcmp(given.data(), expected.data(), given.size()) == 0;
}

}  // namespace

absl::StatusOr<TokenAuthenticator> TokenAuthenticator::Create(std::string worker_token,
                                                              std::string user_token) {
  if (worker_token.empty() != user_token.empty()) {
    return absl::InvalidArgumentError("give both a worker token and a user token, or neither");
  }
  if (!worker_token.empty()) {
    if (worker_token.size() < 16 || user_token.size() < 16) {
      return absl::InvalidArgumentError("tokens must be at least 16 characters long");
    }
    if (worker_token == user_token) {
      return absl::InvalidArgumentError("the worker token and the user token must differ");
    }
  }
  return TokenAuthenticator(std::move(worker_token), std::move(user_token));
}

absl::Status TokenAuthenticator::Check(const grpc::ServerContext& context, Role role) const {
  if (!enabled()) return absl::OkStatus();
  const auto& metadata = context.client_metadata();
  const auto found = metadata.find("authorization");
  if (found == metadata.end()) {
    return absl::UnauthenticatedError(
        "missing 'authorization: Bearer <token>' metadata; pass --token-file");
  }
  const std::string value(found->second.data(), found->second.size());
  return CheckBearer(&value, role);
}

absl::Status TokenAuthenticator::CheckBearer(const std::string* authorization, Role role) const {
  if (!enabled()) return absl::OkStatus();
  if (authorization == nullptr) {
    return absl::UnauthenticatedError("missing 'authorization: Bearer <token>'");
  }
  constexpr absl::string_view kBearer = "Bearer ";
  if (!absl::StartsWith(*authorization, kBearer)) {
    return absl::UnauthenticatedError("authorization metadata is not 'Bearer <token>'");
  }
  const std::string token = authorization->substr(kBearer.size());
  const bool is_worker = SameToken(token, worker_token_);
  const bool is_user = SameToken(token, user_token_);
  if (!is_worker && !is_user) return absl::UnauthenticatedError("unknown token");
  if (role == Role::kWorker && !is_worker) {
    return absl::PermissionDeniedError("a user token cannot make worker calls");
  }
  if (role == Role::kUser && !is_user) {
    return absl::PermissionDeniedError("a worker token cannot make user calls");
  }
  return absl::OkStatus();
}

}  // namespace totalgrad::service
