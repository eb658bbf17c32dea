#include "ffloc/data/text_file.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>

#include "ffloc/core/error.h"
#include "ffloc/geometry/camera.h"
#include "ffloc/io/input_file.h"

namespace ffloc {

std::vector<TextLine> readTextLines(const std::filesystem::path& file) {
  requireRegularFile(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throwInputError(file.string(), 0, "cannot open file");
  std::vector<TextLine> lines;
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    if (!text.empty() && text.back() == '\r') text.pop_back();
    // A UTF-8 byte order mark (what Windows editors save) is not text: "# comment" after one was
    // refused as "expected an integer for CAMERA_ID, got '#'", the mark invisible.
    if (number == 0 && text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);
    lines.push_back({++number, text});
  }
  if (in.bad()) throwInputError(file.string(), number, "read error");
  return lines;
}

std::string_view trimmed(std::string_view text) {
  constexpr std::string_view kBlank = " \t\r";
  const size_t first = text.find_first_not_of(kBlank);
  return first == std::string_view::npos ? std::string_view() : text.substr(first, text.find_last_not_of(kBlank) + 1 - first);
}

std::vector<TextLine> contentLines(std::vector<TextLine> lines, bool skip_comments) {
  const auto without_content = [&](const TextLine& line) {
    const std::string_view content = trimmed(line.text);
    return content.empty() || (skip_comments && content.front() == '#');
  };
  lines.erase(std::remove_if(lines.begin(), lines.end(), without_content), lines.end());
  return lines;
}

bool TokenReader::next(std::string_view* token) {
  constexpr std::string_view kWhitespace = " \t\r\n";
  const size_t start = text_.find_first_not_of(kWhitespace, at_);
  if (start == std::string_view::npos) {
    at_ = text_.size();
    return false;
  }
  at_ = std::min(text_.find_first_of(kWhitespace, start), text_.size());
  *token = text_.substr(start, at_ - start);
  return true;
}

size_t TokenReader::next(std::string_view* tokens, size_t wanted) {
  size_t read = 0;
  while (read < wanted && next(&tokens[read])) ++read;
  return read;
}

std::vector<std::string> splitWhitespace(const std::string& text) {
  std::vector<std::string> tokens;
  TokenReader reader(text);
  for (std::string_view token; reader.next(&token);) tokens.emplace_back(token);
  return tokens;
}

double parseDouble(const std::string& token, const std::filesystem::path& file, int line,
                   const std::string& field) {
  errno = 0;
  char* end = nullptr;
  const double value = std::strtod(token.c_str(), &end);
  // ERANGE on underflow (denormals) is harmless; only reject what did not parse. strtod also
  // reads C's hexadecimal ("0x10" as 16), which no dataset's tools write or read.
  if (token.empty() || end != token.c_str() + token.size() || token.find_first_of("xX") != std::string::npos)
    throwInputError(file.string(), line, "expected a number for " + field + ", got '" + token + "'");
  return value;
}

long parseInteger(const std::string& token, const std::filesystem::path& file, int line,
                  const std::string& field) {
  errno = 0;
  char* end = nullptr;
  const long value = std::strtol(token.c_str(), &end, 10);
  if (token.empty() || end != token.c_str() + token.size() || errno == ERANGE)
    throwInputError(file.string(), line, "expected an integer for " + field + ", got '" + token + "'");
  return value;
}

std::vector<double> parseNumbers(const TextLine& line, const std::filesystem::path& file) {
  std::vector<double> values;
  TokenReader reader(line.text);
  for (std::string_view token; reader.next(&token);)
    values.push_back(parseDouble(std::string(token), file, line.number, "value " + std::to_string(values.size() + 1)));
  return values;
}

void requireLensDistortion(const Intrinsics& camera, const std::filesystem::path& file, int line) {
  const std::string problem = distortionProblem(camera);
  if (!problem.empty()) throwInputError(file.string(), line, problem);
}

MatrixFile readMatrixFile(const std::filesystem::path& file, int rows, int cols) {
  const auto lines = contentLines(readTextLines(file), false);
  if (static_cast<int>(lines.size()) != rows)
    throwInputError(file.string(), lines.empty() ? 0 : lines.back().number,
                    "expected a " + std::to_string(rows) + "x" + std::to_string(cols) + " matrix, found " +
                        std::to_string(lines.size()) + " non-empty lines");
  MatrixFile matrix{Eigen::MatrixXd(rows, cols), {}};
  for (int r = 0; r < rows; ++r) {
    const auto values = parseNumbers(lines[r], file);
    if (static_cast<int>(values.size()) != cols)
      throwInputError(file.string(), lines[r].number,
                      "expected " + std::to_string(cols) + " numbers in matrix row " + std::to_string(r + 1) +
                          ", found " + std::to_string(values.size()));
    for (int c = 0; c < cols; ++c) {
      if (!std::isfinite(values[c])) throwInputError(file.string(), lines[r].number, "non-finite value (NaN or inf)");
      matrix.values(r, c) = values[c];
    }
    matrix.row_lines.push_back(lines[r].number);
  }
  return matrix;
}

}  // namespace ffloc
