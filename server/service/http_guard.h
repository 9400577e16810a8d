// The connection policy of the coordinator's HTTP port, on top of Debian 12's
// cpp-httplib 0.11.4, so that slow or idle clients cannot starve /healthz.
//
// What the library offers and what it lacks: it serves connections on a
// TaskQueue (a fixed ThreadPool by default) and bounds each read by a
// timeout, but a client that sends a header line every second holds a thread
// for as long as it likes, and connections beyond the pool's threads wait in
// an unbounded queue. This layer adds, without touching the library's parsing
// or routing (httplib::Server::process_request does both):
//
//  * a deadline for the whole request (request line, headers and body) from
//    the moment the connection is served: a dribbling client is cut when it
//    passes, whatever the pace of its bytes;
//  * a bound on connections in total and per client address that never
//    refuses a new connection: when a bound is reached, the oldest
//    connection still waiting for its request (of that address, or of any)
//    is closed instead. A probe sends its request at once and is answered in
//    milliseconds, so it gets through even from the address of the slow
//    clients (a kubelet and a scanner may share a node's address).
//
// Threading: ConnectionRegistry is thread-safe; GuardedServer is used as an
// httplib::Server (its listener thread and TaskQueue threads call it).
#ifndef TOTALGRAD_SERVER_SERVICE_HTTP_GUARD_H_
#define TOTALGRAD_SERVER_SERVICE_HTTP_GUARD_H_

#include <httplib.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"
#include "server/service/health_server.h"  // HttpLimits

namespace totalgrad::service {

// The connections being served: which are still waiting for their request
// (and may be closed to make room) and which are being answered.
class ConnectionRegistry {
 public:
  explicit ConnectionRegistry(const HttpLimits& limits) : limits_(limits) {}

  // Records `fd` from `address` as waiting for its request. If the address
  // (or the whole port) is at its bound, first closes the oldest waiting
  // connection of the address (or of any) with shutdown(2), which wakes its
  // thread; the fd itself is closed by that thread.
  void Admit(int fd, const std::string& address);
  // The request has arrived: `fd` is no longer a candidate for closing.
  void MarkAnswering(int fd);
  // Forgets `fd`; call before closing it (so that it is never shut down
  // after the number was reused).
  void Remove(int fd);
  // Closes the oldest waiting connection, if any (a thread is needed for a
  // new connection). Returns whether one was closed.
  bool EvictOldestWaiting();
  // Closes every connection still waiting for its request.
  void EvictAllWaiting();
  int64_t evicted() const { return evicted_.load(); }

 private:
  struct Connection {
    std::string address;
    uint64_t admitted = 0;  // order of admission
    bool waiting = true;
  };
  // Among the waiting connections (of `address` if not empty), shuts the
  // oldest down. Returns whether one was.
  bool EvictOldestLocked(const std::string& address) ABSL_EXCLUSIVE_LOCKS_REQUIRED(mutex_);

  const HttpLimits limits_;
  absl::Mutex mutex_;
  std::map<int, Connection> connections_ ABSL_GUARDED_BY(mutex_);
  std::map<std::string, int> per_address_ ABSL_GUARDED_BY(mutex_);
  uint64_t next_admission_ ABSL_GUARDED_BY(mutex_) = 0;
  std::atomic<int64_t> evicted_{0};
};

// The TaskQueue of a guarded port: limits.max_connections threads; when a
// new connection arrives and every thread is taken or spoken for, the oldest
// connection still waiting for its request is closed so that the new one is
// served at once.
class ConnectionTaskQueue : public httplib::TaskQueue {
 public:
  ConnectionTaskQueue(const HttpLimits& limits, ConnectionRegistry* registry)
      : limits_(limits), registry_(registry), pool_(static_cast<size_t>(limits.max_connections)) {}
  void enqueue(std::function<void()> fn) override;
  // Closes the connections still waiting for a request (a stop need not
  // wait for their deadlines), then joins the threads.
  void shutdown() override;

 private:
  const HttpLimits limits_;
  ConnectionRegistry* registry_;
  std::atomic<int> in_flight_{0};
  httplib::ThreadPool pool_;
};

// Serves one accepted connection: one request under `limits`, answered by
// `server.process_request` (the library's parsing and routing), then closed.
// `ssl_context` null: plain HTTP; else the TLS handshake comes first, under
// the same deadline. Returns whether a request was answered.
bool ServeGuardedConnection(int fd, const HttpLimits& limits, ConnectionRegistry* registry,
                            void* ssl_context,
                            const std::function<bool(httplib::Stream&, bool& closed,
                                                     const std::function<void(httplib::Request&)>&)>&
                                process_request);

// httplib::Server or httplib::SSLServer (Base) whose connections are served
// by ServeGuardedConnection and a ConnectionTaskQueue.
template <class Base>
class GuardedServer : public Base {
 public:
  template <class... Args>
  explicit GuardedServer(const HttpLimits& limits, Args&&... args)
      : Base(std::forward<Args>(args)...), limits_(limits), registry_(limits) {
    this->new_task_queue = [this] { return new ConnectionTaskQueue(limits_, &registry_); };
  }
  const ConnectionRegistry& registry() const { return registry_; }

 private:
  bool process_and_close_socket(socket_t sock) override {
    void* ssl_context = nullptr;
    if constexpr (std::is_base_of_v<httplib::SSLServer, Base>) ssl_context = this->ssl_context();
    return ServeGuardedConnection(
        sock, limits_, &registry_, ssl_context,
        [this](httplib::Stream& stream, bool& closed,
               const std::function<void(httplib::Request&)>& setup) {
          return this->process_request(stream, /*close_connection=*/true, closed, setup);
        });
  }

  const HttpLimits limits_;
  ConnectionRegistry registry_;
};

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_HTTP_GUARD_H_
