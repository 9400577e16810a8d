#include "server/service/http_guard.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>

namespace totalgrad::service {
namespace {

using Clock = std::chrono::steady_clock;

void AddressOf(int fd, bool peer, std::string& ip, int& port) {
  sockaddr_storage address{};
  socklen_t length = sizeof(address);
  const int got = peer ? ::getpeername(fd, reinterpret_cast<sockaddr*>(&address), &length)
                       : ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
  ip.clear();
  port = 0;
  if (got != 0) return;
  char host[NI_MAXHOST];
  char service[NI_MAXSERV];
  if (::getnameinfo(reinterpret_cast<sockaddr*>(&address), length, host, sizeof(host), service,
                    sizeof(service), NI_NUMERICHOST | NI_NUMERICSERV) == 0) {
    ip = host;
    port = std::atoi(service);
  }
}

// Waits until `fd` is ready for `events` (or hung up or failed: the next
// call on it says which) or `deadline` passes (false).
bool WaitReady(int fd, short events, Clock::time_point deadline) {
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    if (left.count() <= 0) return false;
    pollfd entry{fd, events, 0};
    const int ready = ::poll(&entry, 1, static_cast<int>(left.count()));
    if (ready > 0) return (entry.revents & (events | POLLHUP | POLLERR)) != 0;
    if (ready == 0) return false;
    if (errno != EINTR) return false;
  }
}

// A non-blocking socket (plain, or TLS when `ssl` is set) whose reads all end
// at one deadline, the request's, and whose writes each have a timeout.
class DeadlineStream : public httplib::Stream {
 public:
  DeadlineStream(int fd, SSL* ssl, Clock::time_point read_deadline,
                 std::chrono::milliseconds write_timeout)
      : fd_(fd), ssl_(ssl), read_deadline_(read_deadline), write_timeout_(write_timeout) {}

  bool is_readable() const override {
    if (ssl_ != nullptr && SSL_pending(ssl_) > 0) return true;
    return WaitReady(fd_, POLLIN, read_deadline_);
  }
  bool is_writable() const override {
    return WaitReady(fd_, POLLOUT, Clock::now() + write_timeout_);
  }
  ssize_t read(char* ptr, size_t size) override {
    for (;;) {
      const ssize_t got = ssl_ != nullptr ? ReadTls(ptr, size) : ::recv(fd_, ptr, size, 0);
      if (got >= 0) return got;
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) return -1;
      if (!WaitReady(fd_, want_write_ ? POLLOUT : POLLIN, read_deadline_)) return -1;
    }
  }
  ssize_t write(const char* ptr, size_t size) override {
    const Clock::time_point deadline = Clock::now() + write_timeout_;
    for (;;) {
      const ssize_t sent = ssl_ != nullptr ? WriteTls(ptr, size)
                                           : ::send(fd_, ptr, size, MSG_NOSIGNAL);
      if (sent >= 0) return sent;
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) return -1;
      if (!WaitReady(fd_, want_read_ ? POLLIN : POLLOUT, deadline)) return -1;
    }
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    AddressOf(fd_, /*peer=*/true, ip, port);
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    AddressOf(fd_, /*peer=*/false, ip, port);
  }
  socket_t socket() const override { return fd_; }

 private:
  // -1 with errno EAGAIN (and want_read_ or want_write_ saying for what)
  // when the call must wait; -1 with EIO on an error; 0 at the end.
  ssize_t ReadTls(char* ptr, size_t size) {
    const int got = SSL_read(ssl_, ptr, static_cast<int>(std::min<size_t>(size, 1 << 20)));
    return got > 0 ? got : TlsFailure(got);
  }
  ssize_t WriteTls(const char* ptr, size_t size) {
    const int sent = SSL_write(ssl_, ptr, static_cast<int>(std::min<size_t>(size, 1 << 20)));
    return sent > 0 ? sent : TlsFailure(sent);
  }
  ssize_t TlsFailure(int result) {
    const int error = SSL_get_error(ssl_, result);
    want_read_ = error == SSL_ERROR_WANT_READ;
    want_write_ = error == SSL_ERROR_WANT_WRITE;
    if (error == SSL_ERROR_ZERO_RETURN) return 0;
    if (!want_read_ && !want_write_) ERR_clear_error();
    errno = want_read_ || want_write_ ? EAGAIN : EIO;  // EIO: the callers give up
    return -1;
  }

  const int fd_;
  SSL* const ssl_;
  const Clock::time_point read_deadline_;
  const std::chrono::milliseconds write_timeout_;
  bool want_read_ = false;
  bool want_write_ = false;
};

// The TLS handshake, by `deadline`. Returns null if it did not complete.
SSL* AcceptTls(int fd, SSL_CTX* context, Clock::time_point deadline) {
  SSL* ssl = SSL_new(context);
  if (ssl == nullptr) return nullptr;
  SSL_set_fd(ssl, fd);
  for (;;) {
    const int result = SSL_accept(ssl);
    if (result == 1) return ssl;
    const int error = SSL_get_error(ssl, result);
    const bool wait = error == SSL_ERROR_WANT_READ || error == SSL_ERROR_WANT_WRITE;
    if (!wait || !WaitReady(fd, error == SSL_ERROR_WANT_READ ? POLLIN : POLLOUT, deadline)) {
      ERR_clear_error();
      SSL_free(ssl);
      return nullptr;
    }
  }
}

}  // namespace

void ConnectionRegistry::Admit(int fd, const std::string& address) {
  absl::MutexLock lock(&mutex_);
  if (per_address_[address] >= limits_.max_connections_per_address) {
    EvictOldestLocked(address);
  }
  if (static_cast<int>(connections_.size()) >= limits_.max_connections) EvictOldestLocked("");
  connections_[fd] = Connection{address, next_admission_++, /*waiting=*/true};
  ++per_address_[address];
}

void ConnectionRegistry::MarkAnswering(int fd) {
  absl::MutexLock lock(&mutex_);
  auto found = connections_.find(fd);
  if (found != connections_.end()) found->second.waiting = false;
}

void ConnectionRegistry::Remove(int fd) {
  absl::MutexLock lock(&mutex_);
  auto found = connections_.find(fd);
  if (found == connections_.end()) return;
  auto count = per_address_.find(found->second.address);
  if (count != per_address_.end() && --count->second <= 0) per_address_.erase(count);
  connections_.erase(found);
}

bool ConnectionRegistry::EvictOldestWaiting() {
  absl::MutexLock lock(&mutex_);
  return EvictOldestLocked("");
}

void ConnectionRegistry::EvictAllWaiting() {
  absl::MutexLock lock(&mutex_);
  while (EvictOldestLocked("")) {
  }
}

bool ConnectionRegistry::EvictOldestLocked(const std::string& address) {
  auto oldest = connections_.end();
  for (auto it = connections_.begin(); it != connections_.end(); ++it) {
    if (!it->second.waiting || (!address.empty() && it->second.address != address)) continue;
    if (oldest == connections_.end() || it->second.admitted < oldest->second.admitted) oldest = it;
  }
  if (oldest == connections_.end()) return false;
  // Its thread sees the end of the stream at once and closes the fd; until
  // then the entry stays (no longer waiting), so the fd is not reused here.
  ::shutdown(oldest->first, SHUT_RDWR);
  oldest->second.waiting = false;
  evicted_.fetch_add(1);
  return true;
}

void ConnectionTaskQueue::enqueue(std::function<void()> fn) {
  // Every thread is serving or about to serve a connection: make room by
  // closing the connection that has waited longest for its request.
  if (in_flight_.fetch_add(1) >= limits_.max_connections) registry_->EvictOldestWaiting();
  pool_.enqueue([this, fn = std::move(fn)] {
    fn();
    in_flight_.fetch_sub(1);
  });
}

void ConnectionTaskQueue::shutdown() {
  registry_->EvictAllWaiting();
  pool_.shutdown();
}

bool ServeGuardedConnection(int fd, const HttpLimits& limits, ConnectionRegistry* registry,
                            void* ssl_context,
                            const std::function<bool(httplib::Stream&, bool& closed,
                                                     const std::function<void(httplib::Request&)>&)>&
                                process_request) {
  const Clock::time_point deadline = Clock::now() + limits.request_deadline;
  std::string address;
  int port = 0;
  AddressOf(fd, /*peer=*/true, address, port);
  registry->Admit(fd, address);
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL, 0) | O_NONBLOCK);
  bool answered = false;
  SSL* ssl = nullptr;
  if (ssl_context != nullptr) ssl = AcceptTls(fd, static_cast<SSL_CTX*>(ssl_context), deadline);
  if (ssl_context == nullptr || ssl != nullptr) {
    DeadlineStream stream(fd, ssl, deadline, limits.write_timeout);
    bool closed = false;
    answered = process_request(stream, closed,
                               [registry, fd](httplib::Request&) { registry->MarkAnswering(fd); });
  }
  if (ssl != nullptr) {
    SSL_shutdown(ssl);
    SSL_free(ssl);
  }
  registry->Remove(fd);
  ::shutdown(fd, SHUT_RDWR);
  ::close(fd);
  return answered;
}

}  // namespace totalgrad::service
