#include "server/service/health_server.h"

#include <httplib.h>

#include "absl/strings/str_cat.h"
#include "server/service/http_guard.h"

namespace totalgrad::service {

absl::StatusOr<std::unique_ptr<HealthServer>> HealthServer::Start(
    const std::string& listen, std::function<absl::Status()> check, HttpPortOptions options) {
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon + 1 == listen.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("--health-listen: expected HOST:PORT, got '", listen, "'"));
  }
  std::string host = listen.substr(0, colon);
  const std::string port_text = listen.substr(colon + 1);
  if (port_text.find_first_not_of("0123456789") != std::string::npos || port_text.size() > 5 ||
      std::stoi(port_text) > 65535) {
    return absl::InvalidArgumentError(
        absl::StrCat("--health-listen: bad port in '", listen, "'"));
  }
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  if (host.empty()) host = "0.0.0.0";
  std::unique_ptr<HealthServer> health(new HealthServer());
  if (options.tls_cert_file.empty() != options.tls_key_file.empty()) {
    return absl::InvalidArgumentError("HTTPS needs both a certificate and a key file");
  }
  if (!options.tls_cert_file.empty()) {
    auto tls_server = std::make_unique<GuardedServer<httplib::SSLServer>>(
        options.limits, options.tls_cert_file.c_str(), options.tls_key_file.c_str());
    if (!tls_server->is_valid()) {
      return absl::FailedPreconditionError(
          absl::StrCat("HTTP port: cannot load the TLS certificate ", options.tls_cert_file,
                       " or key ", options.tls_key_file));
    }
    health->server_ = std::move(tls_server);
    health->tls_ = true;
  } else {
    health->server_ = std::make_unique<GuardedServer<httplib::Server>>(options.limits);
  }
  httplib::Server& server = *health->server_;
  server.set_payload_max_length(4096);
  server.Get("/healthz", [check = std::move(check)](const httplib::Request&,
                                                    httplib::Response& response) {
    const absl::Status status = check();
    response.set_header("Cache-Control", "no-store");
    if (status.ok()) {
      response.set_content("ok\n", "text/plain; charset=utf-8");
    } else {
      response.status = 503;
      response.set_content(absl::StrCat(status.message(), "\n"), "text/plain; charset=utf-8");
    }
  });
  if (options.add_routes) options.add_routes(&server);
  const int port = std::stoi(port_text);
  if (port == 0) {
    health->port_ = server.bind_to_any_port(host.c_str());
  } else if (server.bind_to_port(host.c_str(), port)) {
    health->port_ = port;
  }
  if (health->port_ <= 0) {
    return absl::UnavailableError(absl::StrCat("--health-listen: cannot listen on ", listen));
  }
  health->thread_ = std::thread([raw = health->server_.get()] { raw->listen_after_bind(); });
  return health;
}

void HealthServer::Stop() {
  if (!thread_.joinable()) return;
  server_->stop();
  thread_.join();
}

HealthServer::~HealthServer() { Stop(); }

}  // namespace totalgrad::service
