#include "ffloc/core/text_file_writer.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <fcntl.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

std::string contents(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Found by an outside probe: `ffloc eval --csv /dev/null` run as root replaced /dev/null with a
// regular file of results, and `--json /dev/stdout` replaced the link; a link to a results file
// became a file beside the one it named.
TEST(TextFileWriter, WritesThroughPipesAndLinksInsteadOfReplacingThem) {
  const fs::path dir = testing::makeTempDir("ffloc-text-writer");
  const fs::path fifo = dir / "pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  {
    // The reader opens first in non-blocking mode, so that the writer's open does not wait.
    const int read_end = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
    ASSERT_GE(read_end, 0);
    writeTextFile(fifo, "through the pipe\n");
    char buffer[64] = {};
    const ssize_t got = ::read(read_end, buffer, sizeof(buffer) - 1);
    ::close(read_end);
    ASSERT_GT(got, 0);
    received.assign(buffer, static_cast<size_t>(got));
  }
  EXPECT_EQ(received, "through the pipe\n");
  struct stat info {};
  ASSERT_EQ(::stat(fifo.c_str(), &info), 0);
  EXPECT_TRUE(S_ISFIFO(info.st_mode));

  writeTextFile(dir / "results.csv", "old\n");
  fs::create_symlink("results.csv", dir / "latest.csv");
  writeTextFile(dir / "latest.csv", "new\n");
  EXPECT_TRUE(fs::is_symlink(dir / "latest.csv"));
  EXPECT_EQ(contents(dir / "results.csv"), "new\n");

  fs::create_directory(dir / "folder");
  EXPECT_THROW(writeTextFile(dir / "folder", "x"), InputError);

  // A dangling link: its target is created, the link kept.
  fs::create_symlink("later.csv", dir / "pending.csv");
  writeTextFile(dir / "pending.csv", "first\n");
  EXPECT_TRUE(fs::is_symlink(dir / "pending.csv"));
  EXPECT_EQ(contents(dir / "later.csv"), "first\n");

  // A pipe no process reads is said so, not waited on for ever.
  EXPECT_THROW(writeTextFile(fifo, "nobody\n"), InputError);
}

// `--json /dev/stdout >> runs.log`: followed to runs.log and replaced by a rename, the log's
// earlier lines were lost (a review). This process's descriptors are written where they stand.
TEST(TextFileWriter, AProcessDescriptorIsWrittenWhereItStands) {
  const fs::path dir = testing::makeTempDir("ffloc-text-writer-fd");
  const fs::path log = dir / "runs.log";
  writeTextFile(log, "earlier\n");
  const int descriptor = ::open(log.c_str(), O_WRONLY | O_APPEND);
  ASSERT_GE(descriptor, 0);
  writeTextFile("/proc/self/fd/" + std::to_string(descriptor), "appended\n");
  ::close(descriptor);
  EXPECT_EQ(contents(log), "earlier\nappended\n");
}

}  // namespace
}  // namespace ffloc
