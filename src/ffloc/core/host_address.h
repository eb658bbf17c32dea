#pragma once

#include <string>

namespace ffloc {

// Whether a host name or address reaches only this machine: "localhost", 127.x.y.z or "::1".
inline bool isLoopbackHost(const std::string& host) {
  return host == "localhost" || host.rfind("127.", 0) == 0 || host == "::1";
}

}  // namespace ffloc
