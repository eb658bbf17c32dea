#include "ffloc/io/input_file.h"

#include "ffloc/core/error.h"

namespace ffloc {

void requireRegularFile(const std::filesystem::path& path, const std::string& what) {
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  if (status.type() == std::filesystem::file_type::not_found) throwInputError(path.string(), 0, what + " not found");
  if (error) throwInputError(path.string(), 0, what + ": " + error.message());
  if (status.type() == std::filesystem::file_type::directory)
    throwInputError(path.string(), 0, what + " expected, found a folder");
  if (status.type() != std::filesystem::file_type::regular)
    throwInputError(path.string(), 0, what + " expected, found something that is not a regular file (FIFO, device or socket)");
}

}  // namespace ffloc
