#include "ffloc/io/input_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/data/scene_test_util.h"
#include "ffloc/io/image.h"
#include "ffloc/io/image_size.h"
#include "ffloc/io/json_fields.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;
using testing::expectInputError;

// Each of these blocked forever (a FIFO opened for reading waits for a writer) or escaped as
// std::filesystem's own error, reported by the CLI as an internal error.
TEST(InputFile, NonRegularFilesAndLinkLoopsAreInputErrors) {
  const auto dir = testing::makeTempDir("ffloc-input-file");
  ASSERT_EQ(::mkfifo((dir / "fifo.png").c_str(), 0600), 0);
  fs::create_symlink("loop.json", dir / "loop.json");
  fs::create_directories(dir / "folder.json");

  expectInputError([&] { requireRegularFile(dir / "fifo.png", "image file"); },
                   {"fifo.png", "image file expected, found something that is not a regular file"});
  expectInputError([&] { requireRegularFile(dir / "missing.txt"); }, {"missing.txt", "file not found"});
  expectInputError([&] { requireRegularFile(dir / "folder.json"); }, {"folder.json", "found a folder"});
  expectInputError([&] { requireRegularFile(dir / "loop.json"); }, {"loop.json", "Too many levels of symbolic links"});

  expectInputError([&] { readImageSize(dir / "fifo.png"); }, {"fifo.png", "not a regular file"});
  expectInputError([&] { readImageRgb(dir / "fifo.png"); }, {"fifo.png", "not a regular file"});
  expectInputError([&] { readImageRgb(dir / "loop.json"); }, {"loop.json", "Too many levels"});
  expectInputError([&] { parseJsonFile(dir / "loop.json"); }, {"loop.json", "Too many levels"});
  expectInputError([&] { parseJsonFile(dir / "folder.json"); }, {"folder.json", "found a folder"});
}

}  // namespace
}  // namespace ffloc
