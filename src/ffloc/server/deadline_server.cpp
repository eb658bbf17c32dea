#include "ffloc/server/deadline_server.h"

#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <string>

namespace ffloc {

namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

// Waits until `socket` is ready for `events` or `wait` passes. Interrupted waits resume with
// what is left.
int pollFor(int socket, short events, Clock::duration wait) {
  const Clock::time_point until = Clock::now() + wait;
  for (;;) {
    const auto left = std::chrono::ceil<milliseconds>(until - Clock::now()).count();
    pollfd entry = {socket, events, 0};
    const int ready = poll(&entry, 1, static_cast<int>(std::max<int64_t>(left, 0)));
    if (ready < 0 && errno == EINTR) continue;
    return ready > 0 ? entry.revents : ready;
  }
}

// How often a wait on a client looks whether the server has stopped.
constexpr milliseconds kStopCheckInterval{100};

// Waits as pollFor does while the server listens; once it has stopped (its listening socket
// closed), only what the client has already sent, or the room already free for an answer,
// counts: a stopping server waits for no client. A slow client held a stop until its request's
// deadline (a body sent a byte a second: 58.6 s).
int pollUnlessStopped(int socket, short events, Clock::duration wait, const std::atomic<socket_t>& server_socket) {
  const Clock::time_point until = Clock::now() + wait;
  for (;;) {
    const bool stopped = server_socket == INVALID_SOCKET;
    const Clock::duration left =
        stopped ? Clock::duration::zero() : std::min<Clock::duration>(until - Clock::now(), kStopCheckInterval);
    const int ready = pollFor(socket, events, std::max(left, Clock::duration::zero()));
    if (ready != 0 || stopped || Clock::now() >= until) return ready;
  }
}

void numericAddress(const sockaddr_storage& address, socklen_t length, std::string& ip, int& port) {
  char host[NI_MAXHOST];
  char service[NI_MAXSERV];
  if (getnameinfo(reinterpret_cast<const sockaddr*>(&address), length, host, sizeof(host), service, sizeof(service),
                  NI_NUMERICHOST | NI_NUMERICSERV) == 0) {
    ip = host;
    port = std::atoi(service);
  }
}

// One connection's socket, read through a buffer (the library reads headers a byte at a time)
// and held to the deadline of the request part being read, not to the library's per-read timeout
// (5 s): a client pausing 6 s inside a 60 s body deadline was answered 400 "malformed", and
// headers stalled half-way got that 400, not the 408 of their deadline. Once the server stops, no read or write waits for the client
// (pollUnlessStopped), and a request that has not all arrived is cut.
class DeadlineStream : public httplib::Stream {
 public:
  DeadlineStream(socket_t socket, Clock::duration write_timeout, const std::atomic<socket_t>& server_socket)
      : socket_(socket), write_timeout_(write_timeout), server_socket_(server_socket) {}

  // The part of the request read from now on, and how long it may take.
  void startPart(const char* part, milliseconds limit) {
    part_ = part;
    limit_ = limit;
    deadline_ = Clock::now() + limit;
  }
  void startRequest(milliseconds header_limit) {
    startPart("headers", header_limit);
    cut_ = Cut::kNone;
    written_ = 0;
  }
  bool cut() const { return cut_ != Cut::kNone; }
  // 408 past the deadline, 503 when the server stopped first (the client may retry elsewhere).
  DeadlineServer::RequestCut cutAnswer() const {
    char text[160];
    if (cut_ == Cut::kStopping) {
      std::snprintf(text, sizeof(text),
                    "server stopping: the request's %s had not all arrived when the server began to stop; retry later",
                    part_);
      return {503, text};
    }
    std::snprintf(text, sizeof(text), "request timeout: the request's %s did not arrive within %g s", part_,
                  std::chrono::duration<double>(limit_).count());
    return {408, text};
  }
  bool answered() const { return written_ > 0; }
  void closeAfterAnswer() { close_after_answer_ = true; }
  bool closingAfterAnswer() const { return close_after_answer_; }

  // Waits for the next request of a kept-alive connection: true when bytes (or the end of the
  // stream, which the library then reads as such) arrive within `idle`, false when they have not
  // by then or by the server's stop.
  bool awaitRequest(Clock::duration idle) {
    return begin_ < end_ || pollUnlessStopped(socket_, POLLIN, idle, server_socket_) > 0;
  }

  // The client closed its side (or reset the connection): nothing it sent is still to be read,
  // and the end of the stream, or an error, is.
  bool peerClosed() const {
    if (begin_ < end_) return false;
    const int ready = pollFor(socket_, POLLIN | POLLRDHUP, Clock::duration::zero());
    if (ready <= 0) return ready < 0;
    if (ready & (POLLHUP | POLLERR | POLLRDHUP)) return true;
    char byte;
    return recv(socket_, &byte, 1, MSG_PEEK | MSG_DONTWAIT) == 0;
  }

  bool is_readable() const override {
    if (begin_ < end_) return true;
    const Clock::duration left = deadline_ - Clock::now();
    if (left > Clock::duration::zero() &&
        pollUnlessStopped(socket_, POLLIN, left, server_socket_) > 0)
      return true;
    if (server_socket_ == INVALID_SOCKET) {
      cut_ = Cut::kStopping;
    } else if (Clock::now() >= deadline_) {
      cut_ = Cut::kDeadline;
    }
    return false;
  }

  bool is_writable() const override { return pollUnlessStopped(socket_, POLLOUT, write_timeout_, server_socket_) > 0; }

  ssize_t read(char* ptr, size_t size) override {
    if (begin_ == end_) {
      if (!is_readable()) return -1;
      ssize_t got;
      do {
        got = recv(socket_, buffer_, sizeof(buffer_), 0);
      } while (got < 0 && errno == EINTR);
      if (got <= 0) return got;
      begin_ = 0;
      end_ = static_cast<size_t>(got);
    }
    const size_t taken = std::min(size, end_ - begin_);
    std::memcpy(ptr, buffer_ + begin_, taken);
    begin_ += taken;
    return static_cast<ssize_t>(taken);
  }

  ssize_t write(const char* ptr, size_t size) override {
    if (!is_writable()) return -1;
    ssize_t sent;
    do {
      sent = send(socket_, ptr, size, MSG_NOSIGNAL);
    } while (sent < 0 && errno == EINTR);
    if (sent > 0) written_ += static_cast<size_t>(sent);
    return sent;
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage address = {};
    socklen_t length = sizeof(address);
    if (getpeername(socket_, reinterpret_cast<sockaddr*>(&address), &length) == 0)
      numericAddress(address, length, ip, port);
  }

  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage address = {};
    socklen_t length = sizeof(address);
    if (getsockname(socket_, reinterpret_cast<sockaddr*>(&address), &length) == 0)
      numericAddress(address, length, ip, port);
  }

  socket_t socket() const override { return socket_; }

 private:
  socket_t socket_;
  Clock::duration write_timeout_;
  const std::atomic<socket_t>& server_socket_;
  const char* part_ = "headers";
  milliseconds limit_{0};
  Clock::time_point deadline_ = Clock::time_point::max();
  enum class Cut { kNone, kDeadline, kStopping };
  mutable Cut cut_ = Cut::kNone;
  size_t written_ = 0;
  bool close_after_answer_ = false;
  char buffer_[16384];
  size_t begin_ = 0;
  size_t end_ = 0;
};

// The connection the calling thread serves: the library runs each connection, its parsing and
// its handlers on one thread of its pool, and gives handlers no way to reach the socket.
thread_local DeadlineStream* current_connection = nullptr;

void writeCutAnswer(DeadlineStream& stream) {
  const DeadlineServer::RequestCut cut = stream.cutAnswer();
  const std::string body = "{\"error\":\"" + cut.message + "\"}";
  const std::string answer = "HTTP/1.1 " + std::to_string(cut.status) +
                             (cut.status == 503 ? " Service Unavailable" : " Request Timeout") +
                             "\r\nContent-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) +
                             "\r\nConnection: close\r\n\r\n" + body;
  stream.write(answer.data(), answer.size());
}

// Set on the accepting thread while it refuses a connection beyond the pending limit.
thread_local bool refusing_connection = false;

// The library's thread pool, with a bound on the connections waiting for a thread. A connection
// waits only when every thread is busy: one counted from its accepting to a thread's taking it up
// made a limit of 0 refuse every connection of an idle server (an outside probe).
class BoundedConnectionPool : public httplib::TaskQueue {
 public:
  BoundedConnectionPool(size_t threads, size_t max_pending)
      : pool_(threads), capacity_(threads + max_pending) {}

  void enqueue(std::function<void()> connection) override {
    if (open_.load() >= capacity_) {
      // `connection` ends in process_and_close_socket, which answers and closes at once.
      refusing_connection = true;
      connection();
      refusing_connection = false;
      return;
    }
    ++open_;
    pool_.enqueue([this, connection = std::move(connection)] {
      connection();
      --open_;
    });
  }
  void shutdown() override { pool_.shutdown(); }

 private:
  httplib::ThreadPool pool_;
  size_t capacity_;  // connections served or waiting
  std::atomic<size_t> open_{0};
};

// Without blocking the accepting thread: a fresh socket's send buffer takes the few bytes.
void writeTooManyConnectionsAnswer(socket_t socket) {
  const std::string body = "{\"error\":\"busy: too many connections are waiting for the server; retry later\"}";
  const std::string answer = "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\nContent-Length: " +
                             std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" + body;
  [[maybe_unused]] const ssize_t sent = send(socket, answer.data(), answer.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
}

// Closing a socket that holds unread bytes resets the connection, and the reset can destroy
// an answer the client has not read yet. So the client is first told the answer is complete
// (our FIN), and what it still sends is read and dropped, for at most a second; a stopping
// server drops only what has arrived.
void closeLeavingUnreadBody(socket_t socket, const std::atomic<socket_t>& server_socket) {
  shutdown(socket, SHUT_WR);
  const Clock::time_point until = Clock::now() + std::chrono::seconds(1);
  char dropped[16384];
  while (Clock::now() < until && pollUnlessStopped(socket, POLLIN, until - Clock::now(), server_socket) > 0 &&
         recv(socket, dropped, sizeof(dropped), 0) > 0) {
  }
  close(socket);
}

}  // namespace

DeadlineServer::DeadlineServer(std::chrono::milliseconds headers, std::chrono::milliseconds body)
    : header_deadline_(headers), body_deadline_(body) {
  // Runs after the library has added its own connection headers, which contradicted ours: an
  // answer that closes the connection also said `Keep-Alive: timeout=5, max=5` (and
  // `Connection: close` twice when the client asked for it too), and HEAD answers said
  // `Accept-Ranges: bytes` of a server that ignores Range.
  set_post_routing_handler([](const httplib::Request&, httplib::Response& response) {
    if (response.get_header_value("Connection") == "close") {
      response.headers.erase("Connection");
      response.headers.erase("Keep-Alive");
      response.set_header("Connection", "close");
    }
    response.headers.erase("Accept-Ranges");
    response.set_header("Accept-Ranges", "none");
  });
}

void DeadlineServer::setConnectionLimits(size_t threads, size_t max_pending) {
  new_task_queue = [threads, max_pending] { return new BoundedConnectionPool(threads, max_pending); };
}

DeadlineServer::RequestCut DeadlineServer::requestCut() {
  return current_connection && current_connection->cut() ? current_connection->cutAnswer() : RequestCut{};
}

bool DeadlineServer::clientDisconnected() { return current_connection && current_connection->peerClosed(); }

void DeadlineServer::closeAfterAnswer(httplib::Response& response) {
  response.set_header("Connection", "close");
  if (current_connection) current_connection->closeAfterAnswer();
}

bool DeadlineServer::process_and_close_socket(socket_t sock) {
  if (refusing_connection) {
    writeTooManyConnectionsAnswer(sock);
    shutdown(sock, SHUT_WR);
    close(sock);
    return false;
  }
  const auto timeout = [](time_t seconds, time_t microseconds) {
    return std::chrono::seconds(seconds) + std::chrono::microseconds(microseconds);
  };
  DeadlineStream stream(sock, timeout(write_timeout_sec_, write_timeout_usec_), svr_sock_);
  current_connection = &stream;
  bool ok = false;
  for (size_t left = keep_alive_max_count_; left > 0; --left) {
    if (!stream.awaitRequest(std::chrono::seconds(keep_alive_timeout_sec_))) break;
    stream.startRequest(header_deadline_);
    bool closed = false;
    // Called once the headers are parsed, before the body is read.
    ok = process_request(stream, left == 1, closed,
                         [&](httplib::Request&) { stream.startPart("body", body_deadline_); });
    if (stream.cut()) {
      // Cut in the request line, the library answers nothing; later, the error handler has.
      if (!stream.answered()) writeCutAnswer(stream);
      ok = false;
      break;
    }
    if (!ok || closed || stream.closingAfterAnswer()) break;
  }
  current_connection = nullptr;
  if (stream.closingAfterAnswer()) {
    closeLeavingUnreadBody(sock, svr_sock_);
    return ok;
  }
  shutdown(sock, SHUT_RDWR);
  close(sock);
  return ok;
}

}  // namespace ffloc
