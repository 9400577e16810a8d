#include "runtime/rpc_client.h"

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>

#include <chrono>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include "absl/strings/str_cat.h"
#include "runtime/address.h"
#include "runtime/status_origin.h"

namespace totalgrad::rpc {
namespace {

absl::StatusOr<std::string> ReadPem(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot read ", what, " ", path));
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

}  // namespace

absl::StatusOr<std::shared_ptr<grpc::Channel>> MakeChannel(const ConnectionOptions& options) {
  if (options.target.empty()) {
    return absl::InvalidArgumentError("no coordinator address (--coordinator HOST:PORT)");
  }
  std::shared_ptr<grpc::ChannelCredentials> credentials;
  grpc::ChannelArguments arguments;
  arguments.SetMaxReceiveMessageSize(options.max_message_bytes);
  arguments.SetMaxSendMessageSize(options.max_message_bytes);
  // Reconnect quickly after a coordinator restart (the default backoff can
  // grow to two minutes).
  arguments.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, 2000);
  arguments.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 200);
  arguments.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 200);
  if (options.insecure) {
    if (!IsLoopbackAddress(options.target)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "--insecure is only allowed for a loopback coordinator address; '", options.target,
          "' is not one. Use --ca-cert (TLS) instead"));
    }
    credentials = grpc::InsecureChannelCredentials();
  } else {
    grpc::SslCredentialsOptions ssl;
    if (!options.ca_cert_file.empty()) {
      absl::StatusOr<std::string> ca = ReadPem(options.ca_cert_file, "CA certificate");
      if (!ca.ok()) return ca.status();
      ssl.pem_root_certs = *ca;
    }
    if (!options.client_cert_file.empty()) {
      absl::StatusOr<std::string> cert = ReadPem(options.client_cert_file, "client certificate");
      if (!cert.ok()) return cert.status();
      absl::StatusOr<std::string> key = ReadPem(options.client_key_file, "client key");
      if (!key.ok()) return key.status();
      ssl.pem_cert_chain = *cert;
      ssl.pem_private_key = *key;
    }
    credentials = grpc::SslCredentials(ssl);
    if (!options.tls_server_name.empty()) {
      arguments.SetSslTargetNameOverride(options.tls_server_name);
    }
  }
  return grpc::CreateCustomChannel(options.target, credentials, arguments);
}

bool IsRetryable(grpc::StatusCode code) {
  return code == grpc::StatusCode::UNAVAILABLE || code == grpc::StatusCode::DEADLINE_EXCEEDED;
}

void PrepareContext(grpc::ClientContext* context, const std::string& token,
                    absl::Duration timeout, bool wait_for_ready) {
  context->set_deadline(std::chrono::system_clock::now() +
                        std::chrono::milliseconds(absl::ToInt64Milliseconds(timeout)));
  context->set_wait_for_ready(wait_for_ready);
  if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
}

void CallRegistry::Add(grpc::ClientContext* context) {
  absl::MutexLock lock(&mutex_);
  contexts_.insert(context);
  if (cancelled_) context->TryCancel();
}

void CallRegistry::Remove(grpc::ClientContext* context) {
  absl::MutexLock lock(&mutex_);
  contexts_.erase(context);
}

void CallRegistry::CancelAll() {
  absl::MutexLock lock(&mutex_);
  cancelled_ = true;
  for (grpc::ClientContext* context : contexts_) context->TryCancel();
}

bool CallRegistry::cancelled() const {
  absl::MutexLock lock(&mutex_);
  return cancelled_;
}

grpc::Status CallWithRetry(const RetryPolicy& policy, const std::string& token,
                           const std::function<grpc::Status(grpc::ClientContext*)>& call,
                           const std::atomic<bool>* stop, CallRegistry* registry) {
  thread_local std::mt19937_64 random(std::random_device{}());
  const auto give_up = std::chrono::steady_clock::now() +
                       std::chrono::milliseconds(absl::ToInt64Milliseconds(policy.give_up_after));
  absl::Duration backoff = policy.initial_backoff;
  grpc::Status status(grpc::StatusCode::CANCELLED, "stopped before the call was made");
  while (true) {
    if ((stop != nullptr && stop->load()) || (registry != nullptr && registry->cancelled())) {
      return status;
    }
    grpc::ClientContext context;
    PrepareContext(&context, token, policy.call_timeout, policy.wait_for_ready);
    if (registry != nullptr) registry->Add(&context);
    status = call(&context);
    if (registry != nullptr) registry->Remove(&context);
    if (status.ok() || !IsRetryable(status.error_code())) return status;
    if (!policy.retry_coordinator_answers && AnsweredByCoordinator(status)) return status;
    std::uniform_real_distribution<double> jitter(1 - policy.jitter, 1 + policy.jitter);
    const auto sleep = std::chrono::milliseconds(
        static_cast<int64_t>(absl::ToDoubleMilliseconds(backoff) * jitter(random)));
    if (std::chrono::steady_clock::now() + sleep > give_up) return status;
    // Sleep in short steps so a stop request is honoured promptly.
    const auto until = std::chrono::steady_clock::now() + sleep;
    while (std::chrono::steady_clock::now() < until) {
      if (stop != nullptr && stop->load()) return status;
      if (registry != nullptr && registry->cancelled()) return status;
      std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(
          std::chrono::milliseconds(50), until - std::chrono::steady_clock::now()));
    }
    backoff = std::min(backoff * 2, policy.max_backoff);
  }
}

}  // namespace totalgrad::rpc
