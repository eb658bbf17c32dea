#pragma once

#include <stdexcept>
#include <string>

namespace ffloc {

// Raised for bad user input: a missing or malformed file, an unknown camera model, an empty
// split. The message always names the file and the line or field at fault, so the CLI can print
// it as it is and exit non-zero.
class InputError : public std::runtime_error {
 public:
  // A NUL in the message (from the input it quotes) is written as \x00: what() is read as a C
  // string, and the message ended there.
  explicit InputError(const std::string& message) : std::runtime_error(withoutNul(message)) {}

 private:
  static std::string withoutNul(const std::string& message);
};

// "<file>:<line>: <what>" or "<file>: <what>" when the line is unknown (line <= 0).
std::string locate(const std::string& file, int line, const std::string& what);

[[noreturn]] void throwInputError(const std::string& file, int line, const std::string& what);

// `message` without the "<file>: " that starts it, when it does: the reason of an error about
// `file`, to be quoted in another that names the file itself.
std::string withoutFileName(const std::string& message, const std::string& file);

// ": <the system's message>" for errno when it is set, else "": the cause of a failure that an
// API reports as a bare false (cv::imwrite, a stream), such as a full disk. Clear errno first.
std::string systemErrorSuffix();

}  // namespace ffloc
