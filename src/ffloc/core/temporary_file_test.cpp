#include "ffloc/core/temporary_file.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <csignal>
#include <filesystem>
#include <fstream>

#include "ffloc/core/testing/child_process.h"
#include "ffloc/core/testing/shared_data.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

TEST(TemporaryFile, IsRemovedUnlessKept) {
  const fs::path dir = testing::makeTempDir("ffloc_temporary_file");
  const fs::path dropped = dir / ".a.tmp", kept = dir / ".b.tmp";
  {
    TemporaryFile file(dropped);
    std::ofstream(file.path()) << "partial";
  }
  EXPECT_FALSE(fs::exists(dropped));
  {
    TemporaryFile file(kept);
    std::ofstream(file.path()) << "complete";
    file.keep();
  }
  EXPECT_TRUE(fs::exists(kept));
}

// A Ctrl-C or a kill while a 2.2 GB checkpoint was converted left its temporary behind each time.
TEST(TemporaryFile, ASignalThatEndsTheProcessRemovesIt) {
  const fs::path dir = testing::makeTempDir("ffloc_temporary_file_signal");
  // Not SIGINT: a shell starts background jobs with it ignored, and then it ends nothing.
  for (const int signal_number : {SIGTERM, SIGHUP}) {
    const fs::path path = dir / (".m." + std::to_string(signal_number) + ".tmp");
    const testing::ChildOutput child = testing::runInChild([&] {
      TemporaryFile file(path);
      std::ofstream(file.path()) << "partial";
      std::raise(signal_number);
    });
    ASSERT_TRUE(WIFSIGNALED(child.status)) << signal_number << ": " << child.output;
    EXPECT_EQ(WTERMSIG(child.status), signal_number);
    EXPECT_FALSE(fs::exists(path)) << signal_number;
  }
}

}  // namespace
}  // namespace ffloc
