#pragma once

#include <chrono>
#include <cstddef>
#include <string>

// Last: it brings <resolv.h>, whose _res macro breaks Eigen headers included after it.
#include <httplib.h>

namespace ffloc {

// cpp-httplib 0.11 bounds each read of a request (5 s) but not the request: a client sending
// one header line every 2 s held a connection thread for as long as it liked, and eight such
// clients stopped every answer, /health included. This is an httplib::Server whose connections are read through our own stream, which holds each
// request to its deadlines: past the headers' deadline the client gets 408 and the connection is
// closed; past the body's, reading stops, the error handler sees requestCut() and the
// connection is closed after its answer. Once the server stops (Server::stop()), no read or
// write waits for a client: a request still arriving is cut the same way, answered 503, so that
// a slow client does not hold the stop until its deadline. The keep-alive loop, request parsing
// and routing are the library's (Server::process_request); only the socket reads and writes are
// ours.
class DeadlineServer : public httplib::Server {
 public:
  // `headers`: from a request's first byte to its blank line; `body`: from there to the body's
  // last byte.
  DeadlineServer(std::chrono::milliseconds headers, std::chrono::milliseconds body);

  // Serves connections on `threads` threads with at most `max_pending` accepted connections
  // waiting for one: beyond them a connection is answered 503 at once, on the accepting thread,
  // and closed. The library's own pool queues without a bound, so slow clients opened faster
  // than the deadlines cut them would pile up until the process ran out of descriptors.
  void setConnectionLimits(size_t threads, size_t max_pending);

  // Why a request was cut before it had all arrived: 408 past its deadline, 503 when the server
  // stopped first; status 0 when it was not cut.
  struct RequestCut {
    int status = 0;
    std::string message;
  };
  // For handlers, on the thread that serves the request: the current request's cut (the error
  // handler turns the library's 400 into it).
  static RequestCut requestCut();
  // Whether the current request's client has closed its side of the connection (a query whose
  // client left need not run). A client that half-closes after sending counts as gone.
  static bool clientDisconnected();
  // For handlers that answer before the request's body is read: the answer says
  // `Connection: close` and the connection ends after it, as the body left in the socket would
  // otherwise be read as the next request (a PNG's bytes logged as a dozen malformed requests).
  static void closeAfterAnswer(httplib::Response& response);

 private:
  bool process_and_close_socket(socket_t sock) override;

  std::chrono::milliseconds header_deadline_;
  std::chrono::milliseconds body_deadline_;
};

}  // namespace ffloc
