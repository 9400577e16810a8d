// The coordinator's HTTP port under slow and idle clients (issue 28.4):
// HealthServer on loopback with its real connection policy
// (server/service/http_guard.h), probed with raw sockets.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "server/service/health_server.h"

namespace totalgrad::service {
namespace {

using std::chrono::milliseconds;
using std::chrono::steady_clock;

int Connect(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = htons(static_cast<uint16_t>(port));
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// Sends `request` on a new connection and reads the answer until the server
// closes it or `limit` passes.
std::string Exchange(int port, const std::string& request, milliseconds limit) {
  const int fd = Connect(port);
  if (fd < 0) return "";
  (void)::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  std::string answer;
  const auto deadline = steady_clock::now() + limit;
  char buffer[4096];
  for (;;) {
    const auto left = std::chrono::duration_cast<milliseconds>(deadline - steady_clock::now());
    pollfd entry{fd, POLLIN, 0};
    if (left.count() <= 0 || ::poll(&entry, 1, static_cast<int>(left.count())) <= 0) break;
    const ssize_t got = ::recv(fd, buffer, sizeof(buffer), 0);
    if (got <= 0) break;
    answer.append(buffer, static_cast<size_t>(got));
  }
  ::close(fd);
  return answer;
}

// Whether the server closed `fd` (end of stream or reset) within `limit`.
// Whether the server closed (or reset) the connection within `limit`. An
// answer it sends before closing (an error status for the cut request) is
// read and skipped: only the end of the connection counts.
bool ClosedWithin(int fd, milliseconds limit) {
  const auto end = steady_clock::now() + limit;
  char buffer[512];
  while (true) {
    const auto left = std::chrono::duration_cast<milliseconds>(end - steady_clock::now());
    if (left.count() <= 0) return false;
    pollfd entry{fd, POLLIN, 0};
    if (::poll(&entry, 1, static_cast<int>(left.count())) <= 0) return false;
    if (::recv(fd, buffer, sizeof buffer, MSG_DONTWAIT) <= 0) return true;
  }
}

// A client that sends a request line, then a header line every `pace`, never
// finishing its head, until stopped or the server closes the connection.
class Dribbler {
 public:
  Dribbler(int port, milliseconds pace) : fd_(Connect(port)) {
    thread_ = std::thread([this, pace] {
      const std::string start = "GET /healthz HTTP/1.1\r\n";
      if (::send(fd_, start.data(), start.size(), MSG_NOSIGNAL) < 0) return;
      while (!stop_.load()) {
        std::this_thread::sleep_for(pace);
        const std::string line = "X-Slow: 1\r\n";
        if (::send(fd_, line.data(), line.size(), MSG_NOSIGNAL) < 0) return;  // cut
      }
    });
  }
  ~Dribbler() {
    stop_.store(true);
    thread_.join();
    ::close(fd_);
  }
  int fd() const { return fd_; }

 private:
  const int fd_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

std::unique_ptr<HealthServer> StartServer(HttpLimits limits = {}) {
  HttpPortOptions options;
  options.limits = limits;
  auto server = HealthServer::Start("127.0.0.1:0", [] { return absl::OkStatus(); }, options);
  EXPECT_TRUE(server.ok()) << server.status();
  return server.ok() ? *std::move(server) : nullptr;
}

// 40 idle and 10 dribbling connections (a header line every 200 ms, more
// than the old pool's 8 threads could serve: each held one until its 2 s
// read timeout, or for ever while dribbling): a probe is answered within 1 s,
// five times in a row.
TEST(HttpPortTest, HealthAnswersWithinASecondBesideIdleAndDribblingConnections) {
  std::unique_ptr<HealthServer> server = StartServer();
  ASSERT_NE(server, nullptr);
  std::vector<int> idle;
  for (int i = 0; i < 40; ++i) {
    const int fd = Connect(server->port());
    ASSERT_GE(fd, 0);
    idle.push_back(fd);
  }
  std::vector<std::unique_ptr<Dribbler>> dribblers;
  for (int i = 0; i < 10; ++i) {
    dribblers.push_back(std::make_unique<Dribbler>(server->port(), milliseconds(200)));
  }
  std::this_thread::sleep_for(milliseconds(300));  // all accepted and being read
  for (int probe = 0; probe < 5; ++probe) {
    const auto start = steady_clock::now();
    const std::string answer = Exchange(server->port(), "GET /healthz HTTP/1.1\r\n\r\n",
                                        milliseconds(3000));
    const auto took = steady_clock::now() - start;
    EXPECT_EQ(answer.rfind("HTTP/1.1 200 OK", 0), 0u) << "probe " << probe << ": " << answer;
    EXPECT_LT(took, milliseconds(1000)) << "probe " << probe;
    std::this_thread::sleep_for(milliseconds(200));
  }
  dribblers.clear();
  for (int fd : idle) ::close(fd);
}

// The deadline covers the whole request head, not each read: a client that
// keeps sending header lines every 100 ms is cut once the deadline passes.
TEST(HttpPortTest, DribblingClientIsCutAtTheRequestDeadline) {
  HttpLimits limits;
  limits.request_deadline = milliseconds(800);
  std::unique_ptr<HealthServer> server = StartServer(limits);
  ASSERT_NE(server, nullptr);
  const auto start = steady_clock::now();
  Dribbler dribbler(server->port(), milliseconds(100));
  EXPECT_TRUE(ClosedWithin(dribbler.fd(), milliseconds(2500)));
  EXPECT_LT(steady_clock::now() - start, milliseconds(2000));
  EXPECT_GE(steady_clock::now() - start, milliseconds(700));
}

// One address holds at most max_connections_per_address connections that
// wait for their request: more close the oldest, and a new request from the
// same address is still answered.
TEST(HttpPortTest, ConnectionsPerAddressAreBoundedWithoutRefusingANewOne) {
  HttpLimits limits;
  limits.max_connections_per_address = 4;
  std::unique_ptr<HealthServer> server = StartServer(limits);
  ASSERT_NE(server, nullptr);
  std::vector<int> idle;
  for (int i = 0; i < 6; ++i) {
    idle.push_back(Connect(server->port()));
    std::this_thread::sleep_for(milliseconds(50));  // served in this order
  }
  EXPECT_TRUE(ClosedWithin(idle[0], milliseconds(500)));
  EXPECT_TRUE(ClosedWithin(idle[1], milliseconds(500)));
  EXPECT_FALSE(ClosedWithin(idle[5], milliseconds(100)));
  const std::string answer =
      Exchange(server->port(), "GET /healthz HTTP/1.1\r\n\r\n", milliseconds(1000));
  EXPECT_EQ(answer.rfind("HTTP/1.1 200 OK", 0), 0u) << answer;
  for (int fd : idle) ::close(fd);
}

// An unknown path is still the library's 404, a malformed request its 400.
TEST(HttpPortTest, LibraryAnswersAreKept) {
  std::unique_ptr<HealthServer> server = StartServer();
  ASSERT_NE(server, nullptr);
  EXPECT_EQ(Exchange(server->port(), "GET /nothing HTTP/1.1\r\n\r\n", milliseconds(1000))
                .rfind("HTTP/1.1 404", 0),
            0u);
  EXPECT_EQ(Exchange(server->port(), "NONSENSE\r\n\r\n", milliseconds(1000)).rfind("HTTP/1.1 400", 0),
            0u);
}

}  // namespace
}  // namespace totalgrad::service
