#pragma once

#include <netdb.h>
#include <sys/socket.h>

#include <string>

namespace ffloc {

// Whether a host name or address reaches only this machine: "localhost", 127.x.y.z or "::1".
inline bool isLoopbackHost(const std::string& host) {
  return host == "localhost" || host.rfind("127.", 0) == 0 || host == "::1";
}

// Why `host` names no address ("" when it resolves): the resolver's own words.
inline std::string hostResolutionProblem(const std::string& host) {
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const int status = ::getaddrinfo(host.c_str(), nullptr, &hints, &found);
  if (found != nullptr) ::freeaddrinfo(found);
  return status == 0 ? "" : ::gai_strerror(status);
}

}  // namespace ffloc
