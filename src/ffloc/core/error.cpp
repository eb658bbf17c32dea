#include "ffloc/core/error.h"

#include <cerrno>
#include <cstring>

namespace ffloc {

std::string InputError::withoutNul(const std::string& message) {
  if (message.find('\0') == std::string::npos) return message;
  std::string escaped;
  for (const char c : message) escaped += c == '\0' ? std::string("\\x00") : std::string(1, c);
  return escaped;
}

std::string locate(const std::string& file, int line, const std::string& what) {
  if (line > 0) return file + ":" + std::to_string(line) + ": " + what;
  return file + ": " + what;
}

std::string systemErrorSuffix() { return errno != 0 ? std::string(": ") + std::strerror(errno) : std::string(); }

std::string withoutFileName(const std::string& message, const std::string& file) {
  const std::string named = file + ": ";
  return message.rfind(named, 0) == 0 ? message.substr(named.size()) : message;
}

void throwInputError(const std::string& file, int line, const std::string& what) {
  throw InputError(locate(file, line, what));
}

}  // namespace ffloc
