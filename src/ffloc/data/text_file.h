#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

// Helpers the text-format readers share. Every failure is an InputError naming file and line.
namespace ffloc {

struct Intrinsics;

struct TextLine {
  int number = 0;    // 1-based line number in the file
  std::string text;  // without the line end (LF or CRLF)
};

// All lines of a text file, a leading UTF-8 byte order mark dropped. Throws InputError when the
// file is missing or unreadable.
std::vector<TextLine> readTextLines(const std::filesystem::path& file);

// Lines that hold something other than whitespace, minus `#` comment lines when asked. Takes the
// lines by value and keeps them in place, so a large file is not held twice.
std::vector<TextLine> contentLines(std::vector<TextLine> lines, bool skip_comments);

// The text without the spaces, tabs and CRs at its ends; a view into `text`.
std::string_view trimmed(std::string_view text);

// Whitespace-separated tokens (spaces, tabs, CR).
std::vector<std::string> splitWhitespace(const std::string& text);

// The same one at a time, as views into the text, for lines that may be megabytes long (a
// COLMAP POINTS2D line): a vector of token strings costs about 20 times the line.
class TokenReader {
 public:
  explicit TokenReader(std::string_view text) : text_(text) {}
  // The next token; false at the end of the text.
  bool next(std::string_view* token);
  // Up to `wanted` next tokens into `tokens`; returns how many there were.
  size_t next(std::string_view* tokens, size_t wanted);

 private:
  std::string_view text_;
  size_t at_ = 0;
};

// A decimal number (with `e-001`-style exponents); the whole token must be consumed.
double parseDouble(const std::string& token, const std::filesystem::path& file, int line,
                   const std::string& field);
long parseInteger(const std::string& token, const std::filesystem::path& file, int line,
                  const std::string& field);

// Every token of the line as a number.
std::vector<double> parseNumbers(const TextLine& line, const std::filesystem::path& file);

// Throws "<file>:<line>: <distortionProblem>" (geometry/camera.h) when a coefficient is not finite
// or the distortion moves the image's points beyond any lens's. Called once the camera's size and
// focal lengths are read; without them only finiteness is checked here, and checkIntrinsicsFitImage
// checks the rest for every frame.
void requireLensDistortion(const Intrinsics& camera, const std::filesystem::path& file, int line);

// A rows x cols matrix of finite numbers written one row per non-empty line (7-Scenes pose and
// intrinsics files), with the line number of each row for later messages.
struct MatrixFile {
  Eigen::MatrixXd values;
  std::vector<int> row_lines;
};
MatrixFile readMatrixFile(const std::filesystem::path& file, int rows, int cols);

}  // namespace ffloc
