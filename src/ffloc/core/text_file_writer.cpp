#include "ffloc/core/text_file_writer.h"

#include <fstream>
#include <unistd.h>

#include "ffloc/core/error.h"

namespace ffloc {

void writeTextFile(const std::filesystem::path& path, const std::string& text) {
  const std::filesystem::path folder = path.has_parent_path() ? path.parent_path() : ".";
  if (!std::filesystem::is_directory(folder)) throwInputError(path.string(), 0, "output folder does not exist");
  const std::filesystem::path temporary =
      folder / ("." + path.filename().string() + ".tmp-" + std::to_string(getpid()));
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) throwInputError(temporary.string(), 0, "cannot create file");
    out << text;
    // What fits the stream's buffer reaches the disk only at close, whose failure (a full disk)
    // would otherwise leave an empty file reported as written.
    out.close();
    if (out.fail()) {
      std::filesystem::remove(temporary);
      throwInputError(path.string(), 0, "write failed");
    }
  }
  std::error_code error;
  std::filesystem::rename(temporary, path, error);
  if (error) {
    std::filesystem::remove(temporary);
    throwInputError(path.string(), 0, "cannot replace file: " + error.message());
  }
}

}  // namespace ffloc
