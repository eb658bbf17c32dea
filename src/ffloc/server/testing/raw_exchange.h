#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <string>

namespace ffloc::testing {

// Sends `request` as it is on a new connection and returns what comes back until the server
// closes it (or `timeout_s` seconds pass): for requests no HTTP client would send.
inline std::string rawExchange(int port, const std::string& request, int timeout_s = 20) {
  const int socket_fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address = {};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string answer;
  if (connect(socket_fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0 &&
      send(socket_fd, request.data(), request.size(), 0) == static_cast<ssize_t>(request.size())) {
    timeval timeout = {timeout_s, 0};
    setsockopt(socket_fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
    char buffer[4096];
    for (ssize_t got; (got = recv(socket_fd, buffer, sizeof(buffer), 0)) > 0;) answer.append(buffer, got);
  }
  close(socket_fd);
  return answer;
}

}  // namespace ffloc::testing
