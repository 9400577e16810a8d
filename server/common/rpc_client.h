// Client side of the service, shared by the worker and the CLI: channel
// credentials (TLS or loopback plaintext), bearer tokens, deadlines, and
// retries with exponential backoff and jitter.
//
// Every call made through CallWithRetry has a deadline. Retried codes are
// UNAVAILABLE and DEADLINE_EXCEEDED, which is safe because every write of the
// service is idempotent (a timed-out call may have been committed).
//
// Threading: free functions; a Channel may be shared by many threads.
#ifndef TOTALGRAD_SERVER_COMMON_RPC_CLIENT_H_
#define TOTALGRAD_SERVER_COMMON_RPC_CLIENT_H_

#include <grpcpp/channel.h>
#include <grpcpp/client_context.h>

#include <atomic>
#include <functional>
#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "absl/time/time.h"

namespace totalgrad::rpc {

struct ConnectionOptions {
  // host:port of the coordinator.
  std::string target;
  // Bearer token (contents); empty sends none.
  std::string token;
  // Plaintext; refused unless `target` is a loopback address.
  bool insecure = false;
  // PEM root certificate(s) to trust; empty: the system roots.
  std::string ca_cert_file;
  // Optional client certificate for coordinators that require one.
  std::string client_cert_file;
  std::string client_key_file;
  // Name to check the server certificate against instead of the target host.
  std::string tls_server_name;
  int max_message_bytes = 4 << 20;
};

// InvalidArgument for plaintext to a non-loopback target; NotFound for an
// unreadable certificate file.
absl::StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(const ConnectionOptions& options);

struct RetryPolicy {
  // Deadline of each try.
  absl::Duration call_timeout = absl::Seconds(30);
  absl::Duration initial_backoff = absl::Milliseconds(200);
  absl::Duration max_backoff = absl::Seconds(10);
  // Each sleep is scaled by a uniform factor in [1 - jitter, 1 + jitter].
  double jitter = 0.2;
  // Total time after which the last error is returned.
  absl::Duration give_up_after = absl::Minutes(2);
  // Wait for the channel to (re)connect within the deadline instead of
  // failing at once (a restarting coordinator).
  bool wait_for_ready = true;
};

bool IsRetryable(grpc::StatusCode code);

// Calls `call` with a fresh context (deadline, token, wait-for-ready) until it
// returns OK or a non-retryable status, the policy gives up, or *stop becomes
// true (then the last status, or CANCELLED). The context is registered in
// *current (if given) while the call runs, so another thread may TryCancel it.
grpc::Status CallWithRetry(const RetryPolicy& policy, const std::string& token,
                           const std::function<grpc::Status(grpc::ClientContext*)>& call,
                           const std::atomic<bool>* stop = nullptr);

// Prepares one context: deadline now + timeout, bearer token, wait-for-ready.
void PrepareContext(grpc::ClientContext* context, const std::string& token,
                    absl::Duration timeout, bool wait_for_ready);

}  // namespace totalgrad::rpc

#endif  // TOTALGRAD_SERVER_COMMON_RPC_CLIENT_H_
