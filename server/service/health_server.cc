#include "server/service/health_server.h"

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

#include "absl/strings/str_cat.h"

namespace totalgrad::service {
namespace {

constexpr size_t kMaxRequestHead = 4096;
constexpr auto kConnectionBudget = std::chrono::seconds(2);

using Clock = std::chrono::steady_clock;

// Milliseconds left until `deadline` (0 if past).
int RemainingMs(Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
  return left.count() > 0 ? static_cast<int>(left.count()) : 0;
}

// Waits until `fd` is ready for `events`, the deadline passes (false) or the
// wake pipe is readable (false).
bool WaitReady(int fd, short events, int wake, Clock::time_point deadline) {
  while (true) {
    const int timeout = RemainingMs(deadline);
    if (timeout == 0) return false;
    pollfd fds[2] = {{fd, events, 0}, {wake, POLLIN, 0}};
    const int n = ::poll(fds, 2, timeout);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    if (fds[1].revents != 0) return false;
    return fds[0].revents != 0;
  }
}

std::string Response(int code, const char* reason, const std::string& body) {
  return absl::StrCat("HTTP/1.1 ", code, " ", reason,
                      "\r\nContent-Type: text/plain; charset=utf-8\r\nContent-Length: ",
                      body.size(), "\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
                      body);
}

}  // namespace

absl::StatusOr<std::unique_ptr<HealthServer>> HealthServer::Start(
    const std::string& listen, std::function<absl::Status()> check) {
  const size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon + 1 == listen.size()) {
    return absl::InvalidArgumentError(
        absl::StrCat("--health-listen: expected HOST:PORT, got '", listen, "'"));
  }
  std::string host = listen.substr(0, colon);
  const std::string port = listen.substr(colon + 1);
  if (port.find_first_not_of("0123456789") != std::string::npos || port.size() > 5) {
    return absl::InvalidArgumentError(
        absl::StrCat("--health-listen: bad port in '", listen, "'"));
  }
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const int rc = ::getaddrinfo(host.empty() ? nullptr : host.c_str(), port.c_str(), &hints, &found);
  if (rc != 0 || found == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat("--health-listen: cannot resolve '", listen,
                                                   "': ", ::gai_strerror(rc)));
  }
  std::unique_ptr<HealthServer> server(new HealthServer());
  server->check_ = std::move(check);
  std::string error = "no address";
  for (addrinfo* a = found; a != nullptr; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK,
                            a->ai_protocol);
    if (fd < 0) {
      error = std::strerror(errno);
      continue;
    }
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
    if (::bind(fd, a->ai_addr, a->ai_addrlen) == 0 && ::listen(fd, 16) == 0) {
      server->listen_fd_ = fd;
      break;
    }
    error = std::strerror(errno);
    ::close(fd);
  }
  ::freeaddrinfo(found);
  if (server->listen_fd_ < 0) {
    return absl::UnavailableError(
        absl::StrCat("--health-listen: cannot listen on ", listen, ": ", error));
  }
  sockaddr_storage bound{};
  socklen_t length = sizeof(bound);
  if (::getsockname(server->listen_fd_, reinterpret_cast<sockaddr*>(&bound), &length) == 0) {
    if (bound.ss_family == AF_INET) {
      server->port_ = ntohs(reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
    } else if (bound.ss_family == AF_INET6) {
      server->port_ = ntohs(reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port);
    }
  }
  int wake[2];
  if (::pipe2(wake, O_CLOEXEC | O_NONBLOCK) != 0) {
    return absl::InternalError(absl::StrCat("health server: pipe: ", std::strerror(errno)));
  }
  server->wake_read_ = wake[0];
  server->wake_write_ = wake[1];
  server->thread_ = std::thread([raw = server.get()] { raw->Loop(); });
  return server;
}

void HealthServer::Loop() {
  while (true) {
    pollfd fds[2] = {{listen_fd_, POLLIN, 0}, {wake_read_, POLLIN, 0}};
    const int n = ::poll(fds, 2, -1);
    if (n < 0) {
      if (errno == EINTR) continue;
      return;
    }
    if (fds[1].revents != 0) return;
    if (fds[0].revents == 0) continue;
    const int client = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (client < 0) continue;  // EAGAIN, ECONNABORTED, EMFILE...: try again on the next poll
    Serve(client);
    ::close(client);
  }
}

void HealthServer::Serve(int client) {
  const Clock::time_point deadline = Clock::now() + kConnectionBudget;
  std::string head;
  bool complete = false;
  while (head.size() < kMaxRequestHead) {
    char buffer[1024];
    const ssize_t got = ::recv(client, buffer, sizeof(buffer), 0);
    if (got > 0) {
      head.append(buffer, static_cast<size_t>(got));
      if (head.find("\r\n\r\n") != std::string::npos || head.find("\n\n") != std::string::npos) {
        complete = true;
        break;
      }
      continue;
    }
    if (got == 0) break;  // the client closed before finishing
    if (errno == EINTR) continue;
    if (errno != EAGAIN && errno != EWOULDBLOCK) return;
    if (!WaitReady(client, POLLIN, wake_read_, deadline)) return;
  }

  std::string response;
  if (!complete) {
    if (head.size() < kMaxRequestHead) return;  // closed early: nobody to answer
    response = Response(400, "Bad Request", "request too large\n");
  } else {
    const std::string line = head.substr(0, head.find_first_of("\r\n"));
    const size_t first = line.find(' ');
    const size_t second = first == std::string::npos ? first : line.find(' ', first + 1);
    if (second == std::string::npos || line.compare(second + 1, 5, "HTTP/") != 0) {
      response = Response(400, "Bad Request", "bad request\n");
    } else {
      const std::string method = line.substr(0, first);
      std::string target = line.substr(first + 1, second - first - 1);
      target = target.substr(0, target.find('?'));
      if (method == "GET" && target == "/healthz") {
        absl::Status status = check_();
        response = status.ok() ? Response(200, "OK", "ok\n")
                               : Response(503, "Service Unavailable",
                                          absl::StrCat(status.message(), "\n"));
      } else {
        response = Response(404, "Not Found", "not found\n");
      }
    }
  }
  size_t sent = 0;
  while (sent < response.size()) {
    const ssize_t n =
        ::send(client, response.data() + sent, response.size() - sent, MSG_NOSIGNAL);
    if (n > 0) {
      sent += static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK) &&
        WaitReady(client, POLLOUT, wake_read_, deadline)) {
      continue;
    }
    return;
  }
  ::shutdown(client, SHUT_WR);
  // Read what the client still sends (bounded) until it closes, so closing a
  // socket with unread input does not reset the connection before the client
  // has read the answer.
  size_t drained = 0;
  while (drained < 64 * 1024) {
    char buffer[1024];
    const ssize_t got = ::recv(client, buffer, sizeof(buffer), 0);
    if (got > 0) {
      drained += static_cast<size_t>(got);
    } else if (got < 0 && errno == EINTR) {
      continue;
    } else if (got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK) &&
               WaitReady(client, POLLIN, wake_read_, deadline)) {
      continue;
    } else {
      return;
    }
  }
}

void HealthServer::Stop() {
  if (thread_.joinable()) {
    const char byte = 1;
    (void)!::write(wake_write_, &byte, 1);
    thread_.join();
  }
  for (int* fd : {&listen_fd_, &wake_read_, &wake_write_}) {
    if (*fd >= 0) ::close(*fd);
    *fd = -1;
  }
}

HealthServer::~HealthServer() { Stop(); }

}  // namespace totalgrad::service
