#include "ffloc/core/text_file_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "ffloc/core/error.h"
#include "ffloc/core/file_paths.h"
#include "ffloc/core/temporary_file.h"

namespace ffloc {
namespace {

void writeAll(int descriptor, const std::string& text, const std::string& named) {
  for (size_t written = 0; written < text.size();) {
    const ssize_t wrote = ::write(descriptor, text.data() + written, text.size() - written);
    if (wrote < 0 && errno == EINTR) continue;
    if (wrote <= 0) throwInputError(named, 0, std::string("write failed: ") + std::strerror(errno));
    written += static_cast<size_t>(wrote);
  }
}

// A device or a pipe, links followed: written through, as no rename may replace it.
bool isDeviceOrPipe(const std::filesystem::file_status& target) {
  return std::filesystem::exists(target) && !std::filesystem::is_regular_file(target) &&
         !std::filesystem::is_directory(target);
}

}  // namespace

bool writesThrough(const std::filesystem::path& path) {
  std::error_code error;
  return openDescriptorNamed(path) || isDeviceOrPipe(std::filesystem::status(path, error));
}

std::string folderWriteProblem(const std::filesystem::path& folder) {
  std::string probe = (folder / ".ffloc-write-test-XXXXXX").string();
  const int descriptor = ::mkstemp(probe.data());
  if (descriptor < 0) return std::string("is not writable: ") + std::strerror(errno);
  ::close(descriptor);
  // An append-only folder takes new files but no rename over them: writeTextFile's would fail.
  if (::unlink(probe.c_str()) != 0)
    return "keeps what is written in it (files cannot be removed or renamed there: " + std::string(std::strerror(errno)) +
           "); " + probe + " is left";
  return "";
}

void writeTextFile(const std::filesystem::path& named, const std::string& text) {
  // This process's own descriptor (/dev/stdout): written where it stands, not reopened (which
  // truncates) nor followed to the file it is redirected to (which a rename replaced).
  if (const std::optional<int> descriptor = openDescriptorNamed(named)) {
    writeAll(*descriptor, text, named.string());
    return;
  }
  std::error_code error;
  const std::filesystem::file_status target = std::filesystem::status(named, error);  // links followed
  if (std::filesystem::is_directory(target)) throwInputError(named.string(), 0, "is a folder, not a file to write");
  if (isDeviceOrPipe(target)) {
    // A device or a pipe (/dev/null, bash's >(cat)) is written through: replaced by a rename,
    // /dev/null became a regular file of results. A pipe no process reads is said so, not waited on.
    const int descriptor = ::open(named.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (descriptor < 0)
      throwInputError(named.string(), 0,
                      errno == ENXIO ? "a pipe no process reads" : std::string("cannot open: ") + std::strerror(errno));
    ::fcntl(descriptor, F_SETFL, ::fcntl(descriptor, F_GETFL) & ~O_NONBLOCK);
    try {
      writeAll(descriptor, text, named.string());
    } catch (...) {
      ::close(descriptor);
      throw;
    }
    ::close(descriptor);
    return;
  }
  // A link's target is replaced, not the link, even where the target does not exist yet.
  const std::filesystem::path path = followSymlinks(named);
  const std::filesystem::path folder = path.has_parent_path() ? path.parent_path() : ".";
  if (!std::filesystem::is_directory(folder)) throwInputError(path.string(), 0, "output folder does not exist");
  TemporaryFile temporary(folder / ("." + path.filename().string() + ".tmp-" + std::to_string(getpid())));
  const int descriptor = ::open(temporary.path().c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (descriptor < 0)
    throwInputError(path.string(), 0, std::string("cannot make a file in its folder: ") + std::strerror(errno));
  // Errors carry the system's reason (a full disk); the temporary file goes with them (TemporaryFile).
  try {
    writeAll(descriptor, text, path.string());
  } catch (...) {
    ::close(descriptor);
    throw;
  }
  if (::close(descriptor) != 0)
    throwInputError(path.string(), 0, std::string("write failed: ") + std::strerror(errno));
  std::filesystem::rename(temporary.path(), path, error);
  if (error) throwInputError(path.string(), 0, "cannot replace file: " + error.message());
  temporary.keep();
}

}  // namespace ffloc
