// Client side of the service, shared by the worker and the CLI: channel
// credentials (TLS or loopback plaintext), bearer tokens, deadlines, and
// retries with exponential backoff and jitter.
//
// Every call made through CallWithRetry has a deadline. Retried codes are
// UNAVAILABLE and DEADLINE_EXCEEDED, which is safe because every write of the
// service is idempotent (a timed-out call may have been committed).
//
// Threading: free functions; a Channel may be shared by many threads.
#ifndef TOTALGRAD_RUNTIME_RPC_CLIENT_H_
#define TOTALGRAD_RUNTIME_RPC_CLIENT_H_

#include <grpcpp/channel.h>
#include <grpcpp/client_context.h>

#include <atomic>
#include <functional>
#include <memory>
#include <set>
#include <string>

#include "absl/base/thread_annotations.h"
#include "absl/status/statusor.h"
#include "absl/synchronization/mutex.h"
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
  // Also retry the retryable codes when the coordinator itself answered
  // with them (status_origin.h: its store is busy, full or gone). A worker
  // does (it keeps its results until they are stored); the CLI does not: the
  // user learns at once that the coordinator refused, and why.
  bool retry_coordinator_answers = true;
};

bool IsRetryable(grpc::StatusCode code);

// The calls in flight of one owner (e.g. a worker), so that another thread
// can cut them short: CancelAll() cancels every registered call at once and
// makes every later Add() cancel its call immediately (a shutdown that must
// not wait for a call deadline).
//
// Threading: all methods may be called from any thread.
class CallRegistry {
 public:
  CallRegistry() = default;
  CallRegistry(const CallRegistry&) = delete;
  CallRegistry& operator=(const CallRegistry&) = delete;

  // Registers a context for the duration of its call.
  void Add(grpc::ClientContext* context);
  void Remove(grpc::ClientContext* context);
  void CancelAll();
  bool cancelled() const;

 private:
  mutable absl::Mutex mutex_;
  std::set<grpc::ClientContext*> contexts_ ABSL_GUARDED_BY(mutex_);
  bool cancelled_ ABSL_GUARDED_BY(mutex_) = false;
};

// Calls `call` with a fresh context (deadline, token, wait-for-ready) until it
// returns OK or a non-retryable status, the policy gives up, *stop becomes
// true, or `registry` is cancelled (then the last status, or CANCELLED if no
// call was made). While a call runs its context is registered in `registry`
// (if given), so CancelAll() ends it at once.
grpc::Status CallWithRetry(const RetryPolicy& policy, const std::string& token,
                           const std::function<grpc::Status(grpc::ClientContext*)>& call,
                           const std::atomic<bool>* stop = nullptr,
                           CallRegistry* registry = nullptr);

// Prepares one context: deadline now + timeout, bearer token, wait-for-ready.
void PrepareContext(grpc::ClientContext* context, const std::string& token,
                    absl::Duration timeout, bool wait_for_ready);

}  // namespace totalgrad::rpc

#endif  // TOTALGRAD_RUNTIME_RPC_CLIENT_H_
