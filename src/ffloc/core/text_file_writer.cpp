#include "ffloc/core/text_file_writer.h"

#include <fstream>
#include <unistd.h>

#include "ffloc/core/error.h"

namespace ffloc {

void writeTextFile(const std::filesystem::path& named, const std::string& text) {
  std::error_code error;
  const std::filesystem::file_status target = std::filesystem::status(named, error);  // links followed
  if (std::filesystem::is_directory(target)) throwInputError(named.string(), 0, "is a folder, not a file to write");
  if (std::filesystem::exists(target) && !std::filesystem::is_regular_file(target)) {
    // A device or a pipe (/dev/null, /dev/stdout, bash's >(cat)) is written through: replaced by a
    // rename, /dev/null became a regular file of results.
    std::ofstream out(named, std::ios::binary);
    if (!out) throwInputError(named.string(), 0, "cannot open for writing");
    out << text;
    out.close();
    if (out.fail()) throwInputError(named.string(), 0, "write failed");
    return;
  }
  // A link's target is replaced, not the link.
  std::filesystem::path path = named;
  if (std::filesystem::is_symlink(std::filesystem::symlink_status(named, error))) {
    path = std::filesystem::weakly_canonical(named, error);
    if (error) throwInputError(named.string(), 0, "cannot follow the symbolic link: " + error.message());
  }
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
  std::filesystem::rename(temporary, path, error);
  if (error) {
    std::filesystem::remove(temporary);
    throwInputError(path.string(), 0, "cannot replace file: " + error.message());
  }
}

}  // namespace ffloc
