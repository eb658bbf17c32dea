// The server against clients that misbehave on the wire: headers and bodies trickled slower
// than their deadlines, clients that leave while their query waits, and images that are not
// decoded while the server is busy. A localizer the test holds stands in for a map, so that
// what runs, and when, is the test's to say.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <sstream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <thread>
#include <vector>

#include "ffloc/core/error.h"
#include "ffloc/server/localization_server.h"
// Last: it brings <resolv.h>, whose _res macro breaks Eigen headers included after it.
#include <httplib.h>

namespace ffloc {
namespace {

// Records the names of the queries it runs; each waits until the test opens the gate.
class GatedLocalizer : public Localizer {
 public:
  LocalizationMethod method() const override { return LocalizationMethod::kClassical; }
  bool metric() const override { return true; }
  const std::vector<MapCamera>& cameras() const override { return cameras_; }

  void open() {
    std::lock_guard<std::mutex> lock(mutex_);
    open_ = true;
    changed_.notify_all();
  }
  void awaitQueries(size_t count) const {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return names_.size() >= count; });
  }
  std::vector<std::string> names() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return names_;
  }

 protected:
  void predict(const cv::Mat&, const Intrinsics& intrinsics, const std::string& name, const LocalizeOptions&,
               LocalizationResult& result, std::optional<PnpResult>&, PoseGuidedMatching&) const override {
    std::unique_lock<std::mutex> lock(mutex_);
    names_.push_back(name);
    changed_.notify_all();
    changed_.wait(lock, [&] { return open_; });
    result.camera = intrinsics;
  }

 private:
  std::vector<MapCamera> cameras_;
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  mutable std::vector<std::string> names_;
  bool open_ = false;
};

int connectTo(int port) {
  const int socket_fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address = {};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  EXPECT_EQ(connect(socket_fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)), 0);
  return socket_fd;
}

bool sendAll(int socket_fd, const std::string& bytes) {
  return send(socket_fd, bytes.data(), bytes.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(bytes.size());
}

std::string receiveUntilClosed(int socket_fd) {
  timeval timeout = {5, 0};
  setsockopt(socket_fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  std::string answer;
  char buffer[4096];
  for (ssize_t got; (got = recv(socket_fd, buffer, sizeof(buffer), 0)) > 0;) answer.append(buffer, got);
  return answer;
}

// Sends `head`, then `piece` every 100 ms, at most `pieces` times, as a slow client does, and
// returns what the server answered once it answers or closes; empty when it let the client send
// everything without a word.
std::string trickle(int port, const std::string& head, const std::string& piece, int pieces) {
  const int socket_fd = connectTo(port);
  std::string answer;
  if (sendAll(socket_fd, head)) {
    for (int i = 0; i < pieces; ++i) {
      pollfd entry = {socket_fd, POLLIN, 0};
      if (poll(&entry, 1, 100) > 0 || !sendAll(socket_fd, piece)) {
        answer = receiveUntilClosed(socket_fd);
        break;
      }
    }
  }
  close(socket_fd);
  return answer;
}

std::string pngBytes() {
  std::vector<uchar> bytes;
  cv::imencode(".png", cv::Mat(48, 64, CV_8UC3, cv::Scalar(90, 90, 90)), bytes);
  return std::string(bytes.begin(), bytes.end());
}

const std::string kQueryPath = "/localize?fx=100&fy=100&cx=31.5&cy=23.5&name=";

class ConnectionTest : public ::testing::Test {
 protected:
  void start(ServerOptions options) {
    options.port = 0;
    server_ = std::make_unique<LocalizationServer>(catalog_, options);
    port_ = server_->bind();
    serving_ = std::thread([this] { server_->serve(); });
  }
  void TearDown() override {
    localizer_.open();
    for (std::thread& client : clients_) client.join();
    stop();
  }
  // Returns once every accepted request has been handled.
  void stop() {
    if (!serving_.joinable()) return;
    server_->stop();
    serving_.join();
  }

  // A query on its own thread, answered once the gate opens.
  void query(const std::string& name) {
    clients_.emplace_back([this, name] {
      httplib::Client client("127.0.0.1", port_);
      client.set_read_timeout(30);
      client.Post((kQueryPath + name).c_str(), pngBytes(), "image/png");
    });
  }

  GatedLocalizer localizer_;
  MapCatalog catalog_{"scene", ServedMap{std::shared_ptr<const Localizer>(&localizer_, [](const Localizer*) {}), "none"}};
  std::unique_ptr<LocalizationServer> server_;
  int port_ = 0;
  std::thread serving_;
  std::vector<std::thread> clients_;
};

// Eight clients, each sending one header line every 100 ms, against a server of two connection
// threads whose headers must arrive within 300 ms: each is told 408 and disconnected long before
// its 40 lines are out, and /health answers meanwhile. Before the deadlines, each held a thread
// as long as it kept sending (the library bounds each read, not the request).
TEST_F(ConnectionTest, SlowHeadersAreCutAtTheirDeadlineAndHealthAnswers) {
  ServerOptions options;
  options.max_connections = 2;
  options.max_waiting_queries = 0;
  options.header_timeout = std::chrono::milliseconds(300);
  start(options);
  std::vector<std::string> answers(8);
  std::vector<std::thread> slow;
  for (size_t i = 0; i < answers.size(); ++i) {
    slow.emplace_back([&, i] {
      answers[i] = trickle(port_, "GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n", "X-Slow: 1\r\n", 40);
    });
  }
  httplib::Client client("127.0.0.1", port_);
  client.set_read_timeout(30);
  const auto health = client.Get("/health");
  for (std::thread& thread : slow) thread.join();
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  for (const std::string& answer : answers) {
    EXPECT_EQ(answer.rfind("HTTP/1.1 408", 0), 0u) << "'" << answer << "'";
    EXPECT_NE(answer.find("request timeout: the request's headers did not arrive within 0.3 s"), std::string::npos)
        << answer;
  }
}

// Connections beyond the threads and the pending limit are answered 503 at once and closed,
// instead of queueing without a bound behind slow clients; once the slow ones are cut at their
// deadline, /health answers again.
TEST_F(ConnectionTest, ConnectionsBeyondThePendingLimitAre503AtOnce) {
  ServerOptions options;
  options.max_connections = 2;
  options.max_waiting_queries = 0;
  options.max_pending_connections = 2;
  options.header_timeout = std::chrono::milliseconds(3000);
  start(options);
  std::vector<std::thread> slow;
  std::vector<std::string> slow_answers(4);
  for (size_t i = 0; i < slow_answers.size(); ++i) {
    slow.emplace_back([&, i] {
      slow_answers[i] = trickle(port_, "GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n", "X-Slow: 1\r\n", 80);
    });
    // One at a time, so that a thread has taken each of the first two before the next arrives.
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  httplib::Client client("127.0.0.1", port_);
  client.set_read_timeout(30);
  const auto start_time = std::chrono::steady_clock::now();
  const auto refused = client.Get("/health");
  const double refused_after_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();
  for (std::thread& thread : slow) thread.join();
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 503);
  EXPECT_NE(refused->body.find("too many connections are waiting"), std::string::npos) << refused->body;
  EXPECT_LT(refused_after_s, 1.0) << "refused at once, not after a slow client's deadline";
  // Two were served and cut at their deadline, two waited and were cut after them (a slow
  // machine that took a thread late may have refused one of those at the cap).
  size_t cut = 0;
  for (const std::string& answer : slow_answers) {
    const bool timed_out = answer.rfind("HTTP/1.1 408", 0) == 0;
    cut += timed_out ? 1 : 0;
    EXPECT_TRUE(timed_out || answer.rfind("HTTP/1.1 503", 0) == 0) << answer;
  }
  EXPECT_GE(cut, 2u);
  const auto health = client.Get("/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
}

// The request line itself trickled: the library answers nothing there, the server does.
TEST_F(ConnectionTest, SlowRequestLineIsAnswered408) {
  ServerOptions options;
  options.header_timeout = std::chrono::milliseconds(300);
  start(options);
  const std::string answer = trickle(port_, "G", "E", 40);
  EXPECT_EQ(answer.rfind("HTTP/1.1 408", 0), 0u) << "'" << answer << "'";
  EXPECT_NE(answer.find("\"error\":\"request timeout: the request's headers"), std::string::npos) << answer;
}

TEST_F(ConnectionTest, SlowBodyIsCutAtItsDeadline) {
  ServerOptions options;
  options.body_timeout = std::chrono::milliseconds(300);
  start(options);
  const std::string answer =
      trickle(port_, "POST " + kQueryPath + "slow HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: image/png\r\n"
                     "Content-Length: 1000\r\n\r\n", std::string(20, 'x'), 40);
  EXPECT_EQ(answer.rfind("HTTP/1.1 408", 0), 0u) << "'" << answer << "'";
  EXPECT_NE(answer.find("request timeout: the request's body did not arrive within 0.3 s"), std::string::npos)
      << answer;
  EXPECT_TRUE(localizer_.names().empty());
}

// A client that sends its query and leaves while another runs: its query is never run. Whether
// the server sees it leave before decoding or once the running query ends, it must not run.
TEST_F(ConnectionTest, QueryOfAClientThatLeftIsNotRun) {
  start(ServerOptions{});
  query("stays");
  localizer_.awaitQueries(1);
  const std::string image = pngBytes();
  const int socket_fd = connectTo(port_);
  ASSERT_TRUE(sendAll(socket_fd, "POST " + kQueryPath + "leaves HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                                 "Content-Type: image/png\r\nContent-Length: " +
                                     std::to_string(image.size()) + "\r\n\r\n" + image));
  close(socket_fd);
  localizer_.open();
  for (std::thread& client : clients_) client.join();
  clients_.clear();
  stop();
  EXPECT_EQ(localizer_.names(), std::vector<std::string>{"stays"});
}

// A client that leaves while its query runs: the query stops at its next stage (here before PnP,
// once the localizer's prediction returns) and no answer is made.
TEST_F(ConnectionTest, QueryOfAClientThatLeftWhileItRanStopsAtTheNextStage) {
  std::ostringstream log;  // written under the server's lock, read once it has stopped
  ServerOptions options;
  options.log = &log;
  start(options);
  const std::string image = pngBytes();
  const int socket_fd = connectTo(port_);
  ASSERT_TRUE(sendAll(socket_fd, "POST " + kQueryPath + "leaves HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                                 "Content-Type: image/png\r\nContent-Length: " +
                                     std::to_string(image.size()) + "\r\n\r\n" + image));
  localizer_.awaitQueries(1);
  close(socket_fd);
  localizer_.open();
  stop();
  EXPECT_NE(log.str().find("POST /localize 499 client closed the connection while its query ran; stopped before PnP"),
            std::string::npos)
      << log.str();
}

// Images are decoded only once a query is admitted: with no room to wait, a body that is not an
// image is refused as busy, not as undecodable, so busy refusals cost no decoding (eight 113 KB
// PNG bombs once took 1.17 GB before the busy check).
TEST_F(ConnectionTest, ImagesAreNotDecodedWhileTheServerIsBusy) {
  ServerOptions options;
  options.max_waiting_queries = 0;
  start(options);
  query("runs");
  localizer_.awaitQueries(1);
  httplib::Client client("127.0.0.1", port_);
  const auto busy = client.Post((kQueryPath + "garbage").c_str(), std::string(5000, 'x'), "image/png");
  ASSERT_TRUE(busy);
  EXPECT_EQ(busy->status, 503) << busy->body;
}

// A client announcing more than the limit and sending nothing: the library read (to drop) the
// announced bytes first, so it was answered 408 at the body's deadline instead of 413.
TEST_F(ConnectionTest, ContentLengthOverTheLimitIs413BeforeAnyBodyArrives) {
  ServerOptions options;
  options.max_body_bytes = size_t{1} << 20;
  options.body_timeout = std::chrono::milliseconds(30000);
  start(options);
  const int socket_fd = connectTo(port_);
  const auto sent_at = std::chrono::steady_clock::now();
  ASSERT_TRUE(sendAll(socket_fd, "POST " + kQueryPath + "big HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                                 "Content-Type: image/png\r\nContent-Length: 40000000\r\n\r\n"));
  const std::string answer = receiveUntilClosed(socket_fd);
  const double answered_after_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - sent_at).count();
  close(socket_fd);
  EXPECT_EQ(answer.rfind("HTTP/1.1 413", 0), 0u) << "'" << answer << "'";
  EXPECT_NE(answer.find("over the server's limit of 1048576 bytes"), std::string::npos) << answer;
  EXPECT_LT(answered_after_s, 3.0);
}

// --max-waiting 100000 started 32,000 threads and ignored SIGTERM while creating them. Beyond
// the bounds the server refuses to start, naming the field; at them it starts and stops at once.
TEST_F(ConnectionTest, ThreadCountsBeyondTheirBoundsAreRefusedAndTheBoundsStopPromptly) {
  for (const auto& [field, options] : std::vector<std::pair<std::string, ServerOptions>>{
           {"max_waiting_queries", [] {
              ServerOptions o;
              o.max_waiting_queries = ServerOptions::kMaxWaitingQueries + 1;
              return o;
            }()},
           {"max_connections", [] {
              ServerOptions o;
              o.max_connections = ServerOptions::kMaxConnections + 1;
              return o;
            }()},
           {"max_connections", [] {
              ServerOptions o;
              o.max_connections = 0;
              return o;
            }()}}) {
    try {
      LocalizationServer refused(catalog_, options);
      ADD_FAILURE() << field << " beyond its bound accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(field + ": must be in [", 0), 0u) << e.what();
    }
  }
  ServerOptions at_bounds;
  at_bounds.max_connections = ServerOptions::kMaxConnections;
  at_bounds.max_waiting_queries = ServerOptions::kMaxWaitingQueries;
  start(at_bounds);
  httplib::Client client("127.0.0.1", port_);
  const auto health = client.Get("/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  const auto stop_at = std::chrono::steady_clock::now();
  stop();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - stop_at).count(), 5.0);
}

}  // namespace
}  // namespace ffloc
