#include "ffloc/data/dataset_writers.h"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "ffloc/core/error.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/depth.h"
#include "ffloc/data/format_io.h"
#include "ffloc/data/readers.h"
#include "ffloc/core/testing/child_process.h"
#include "ffloc/core/testing/shared_data.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

// Mapping frames of 64 x 48 images named `names` in `dir`, their images not written.
Scene sceneOfFrames(const fs::path& dir, const std::vector<std::string>& names) {
  Scene scene;
  scene.name = "source";
  scene.root = dir;
  scene.format = "manifest";
  for (const std::string& name : names) {
    Frame frame;
    frame.name = name;
    frame.image_path = dir / name;
    frame.intrinsics = {50, 50, 31.5, 23.5, 64, 48};
    frame.split = Split::kMapping;
    scene.frames.push_back(frame);
  }
  return scene;
}

void writeImage(const fs::path& path) {
  fs::create_directories(path.parent_path());
  cv::imwrite(path.string(), cv::Mat(48, 64, CV_8UC3, cv::Scalar(40, 80, 120)));
}

// Two frames; the second's image does not exist, so a writer fails after copying the first.
Scene sceneFailingAtItsSecondFrame(const fs::path& dir) {
  writeImage(dir / "a.png");
  return sceneOfFrames(dir, {"a.png", "missing.png"});
}

std::vector<fs::path> entriesOf(const fs::path& dir) {
  std::vector<fs::path> entries;
  for (const fs::directory_entry& entry : fs::recursive_directory_iterator(dir)) entries.push_back(entry.path());
  std::sort(entries.begin(), entries.end());
  return entries;
}

class DatasetWriters : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::makeTempDir("ffloc_dataset_writers"); }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

// A conversion failing at a corrupt frame left the frames before it, and the rerun into the same
// folder was refused as not empty.
TEST_F(DatasetWriters, AFailedWriteRemovesWhatItWroteAndNothingElse) {
  fs::create_directories(dir_ / "source");
  const Scene scene = sceneFailingAtItsSecondFrame(dir_ / "source");
  fs::create_directories(dir_ / "empty");
  std::ofstream(dir_ / "beside.txt") << "kept";
  const std::vector<fs::path> before = entriesOf(dir_);
  for (const fs::path& out : {dir_ / "new" / "deeper", dir_ / "empty"}) {
    for (const std::string& format : datasetWriterFormats()) {
      EXPECT_THROW(writeDataset(scene, format, out), InputError) << format << " into " << out;
      EXPECT_EQ(entriesOf(dir_), before) << format << " into " << out;
    }
  }
}

// A full disk was named without its cause ("cannot write depth file"), and a depth file's last
// buffered bytes were written only as the stream closed, where a failure went unseen. A file size
// limit stands in for the disk; each format's depth writer is tried.
TEST_F(DatasetWriters, AFailedDepthWriteSaysWhy) {
  fs::create_directories(dir_ / "source");
  Scene scene = sceneFailingAtItsSecondFrame(dir_ / "source");
  scene.frames.pop_back();
  std::vector<uchar> png;
  cv::Mat1w depth(480, 640);
  cv::randu(depth, 500, 5000);  // incompressible, so that each writer's depth file is over the limit
  cv::imencode(".png", depth, png);
  std::ofstream(dir_ / "source" / "a.depth.png", std::ios::binary)
      .write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
  scene.frames[0].depth = DepthSource{dir_ / "source" / "a.depth.png"};
  scene.frames[0].intrinsics = {500, 500, 319.5, 239.5, 640, 480};
  cv::imwrite((dir_ / "source" / "a.png").string(), cv::Mat(480, 640, CV_8UC3, cv::Scalar(40, 80, 120)));
  for (const std::string format : {"kapture", "ace"}) {
    const fs::path out = dir_ / ("out_" + format);
    const testing::ChildOutput child = testing::runInChild([&] {
      std::signal(SIGXFSZ, SIG_IGN);  // the write fails with EFBIG instead of ending the process
      const rlimit small{16384, 16384};
      ::setrlimit(RLIMIT_FSIZE, &small);
      try {
        writeDataset(scene, format, out);
        std::printf("written\n");
      } catch (const InputError& error) {
        std::printf("refused: %s\n", error.what());
      }
      std::fflush(stdout);
    });
    EXPECT_NE(child.output.find("refused: "), std::string::npos) << format << ": " << child.output;
    EXPECT_NE(child.output.find(": File too large"), std::string::npos) << format << ": " << child.output;
  }
}

// A frame whose depth file is missing: the manifest writer's copy failed as an internal error
// (exit 3) where every other writer names the file (probe). And a depth map cut short: the
// manifest writer copied it, exit 0, where every other writer, which decodes it, refused it
// (another probe).
TEST_F(DatasetWriters, AMissingOrBrokenDepthFileIsNamedByEveryWriter) {
  fs::create_directories(dir_ / "source");
  Scene scene = sceneFailingAtItsSecondFrame(dir_ / "source");
  scene.frames.pop_back();
  scene.frames[0].depth = DepthSource{dir_ / "source" / "a.depth.png"};
  std::vector<uchar> png;
  cv::imencode(".png", cv::Mat1w(48, 64, uint16_t{1500}), png);
  for (const std::string problem : {"missing", "cut short"}) {
    if (problem == "cut short")
      std::ofstream(dir_ / "source" / "a.depth.png", std::ios::binary)
          .write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size() / 2));
    for (const std::string& format : datasetWriterFormats()) {
      if (format == "indoor6") continue;  // the format holds no depth, so its writer reads none
      try {
        writeDataset(scene, format, dir_ / ("out-" + format));
        ADD_FAILURE() << format << " wrote a frame whose depth is " << problem;
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("a.depth.png"), std::string::npos) << format << ": " << e.what();
      }
    }
  }
}

// Found by an outside probe: depth beyond 65.534 m was written as 0, "no depth", by the formats
// of 16-bit millimetres (ace, mapfree, rio10), exit 0. Refused, naming the frame; kapture keeps it.
TEST_F(DatasetWriters, DepthBeyondSixteenBitMillimetresIsRefusedWhereItCannotBeStored) {
  fs::create_directories(dir_ / "source");
  Scene scene = sceneFailingAtItsSecondFrame(dir_ / "source");
  scene.frames.pop_back();
  cv::imwrite((dir_ / "source" / "a.depth.png").string(), cv::Mat1w(48, 64, uint16_t{10000}));
  scene.frames[0].depth = DepthSource{dir_ / "source" / "a.depth.png", 0.01};
  for (const std::string format : {"ace", "mapfree", "rio10"}) {
    try {
      writeDataset(scene, format, dir_ / ("out-" + format));
      ADD_FAILURE() << format << " wrote depth of 100 m";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("a.png: 3072 depth pixels lie beyond 65.534 m (up to 100 m)", 0), 0u)
          << format << ": " << e.what();
    }
  }
  writeDataset(scene, "kapture", dir_ / "out-kapture");
  EXPECT_FLOAT_EQ(readDepthMetres(readKapture(dir_ / "out-kapture").frames[0])(10, 10), 100.0f);

  // A scene in small units: depth under half a millimetre was written as "no depth", exit 0.
  scene.frames[0].depth->scale = 1e-8;
  for (const std::string format : {"ace", "mapfree", "rio10"}) {
    try {
      writeDataset(scene, format, dir_ / ("near-" + format));
      ADD_FAILURE() << format << " wrote depth of 0.1 mm as none";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("a.png: 3072 depth pixels lie nearer than 0.5 mm (down to 0.0001 m)", 0),
                0u)
          << format << ": " << e.what();
    }
  }
}

// A frame whose name is not UTF-8 failed in the JSON writer: "internal error", no file named.
TEST_F(DatasetWriters, AManifestRefusesANameItCannotHold) {
  writeImage(dir_ / "source" / "caf\xE9.png");
  const Scene scene = sceneOfFrames(dir_ / "source", {"caf\xE9.png"});
  try {
    writeDataset(scene, "manifest", dir_ / "out");
    ADD_FAILURE() << "written";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), (dir_ / "source" / "caf\xE9.png").string() +
                                         ": image name 'caf\xE9.png' is not UTF-8, which a manifest (JSON) cannot "
                                         "hold; rename the file");
  }
  EXPECT_FALSE(fs::exists(dir_ / "out" / "manifest.json"));
}

// Named by their new paths, a converted copy's frames were new images to `map --append` (the map
// doubled), and every manifest-to-manifest conversion added an "images/" (an outside probe).
TEST_F(DatasetWriters, AManifestKeepsTheFrameNamesThroughEveryConversion) {
  writeImage(dir_ / "source" / "seq 1" / "caf\u00e9.png");
  const Scene scene = sceneOfFrames(dir_ / "source", {"seq 1/caf\u00e9.png"});
  EXPECT_EQ(writeDataset(scene, "manifest", dir_ / "once"), std::vector<std::string>{"seq 1/caf\u00e9.png"});
  const Scene once = loadDataset(dir_ / "once");
  ASSERT_EQ(once.frames.size(), 1u);
  EXPECT_EQ(once.frames[0].name, "seq 1/caf\u00e9.png");
  EXPECT_TRUE(fs::exists(dir_ / "once" / "images" / "seq 1" / "caf\u00e9.png"));
  writeDataset(once, "manifest", dir_ / "twice");
  const Scene twice = loadDataset(dir_ / "twice");
  EXPECT_EQ(twice.frames[0].name, "seq 1/caf\u00e9.png");
  EXPECT_TRUE(fs::exists(dir_ / "twice" / "images" / "seq 1" / "caf\u00e9.png")) << "no images/images/";
}

// Found by an outside probe: ACE files pair by the name up to its first '.', so frames in folders
// 'a.1' and 'a.2' were written as frame 'a' twice: read back, one frame was lost and the other
// had its pose. Dots in folders are now written as '_' (and a clash so made is refused), and the
// reader refuses two files of one frame, as an editor's backup of a pose file beside it.
TEST_F(DatasetWriters, AceFramesInDottedFoldersReadBackAsWrittenAndStrayFilesAreRefused) {
  Scene scene = sceneOfFrames(dir_ / "source", {"a.1/img.png", "a.2/img.png"});
  for (size_t i = 0; i < 2; ++i) {
    scene.frames[i].camera_to_world.t = Eigen::Vector3d(static_cast<double>(i + 1), 0, 0);
    writeImage(scene.frames[i].image_path);
  }
  writeDataset(scene, "ace", dir_ / "ace");
  const Scene back = readAceLayout(dir_ / "ace");
  ASSERT_EQ(back.frames.size(), 2u);
  for (const Frame& frame : back.frames) {
    const bool first = frame.name.find("a_1_img") != std::string::npos;
    EXPECT_TRUE(first || frame.name.find("a_2_img") != std::string::npos) << frame.name;
    EXPECT_EQ(frame.camera_to_world.t.x(), first ? 1 : 2) << frame.name;
  }
  std::ofstream(dir_ / "ace" / "train" / "poses" / "a_1_img.pose.txt~") << "1 0 0 5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  try {
    readAceLayout(dir_ / "ace");
    ADD_FAILURE() << "a stray file beside a pose was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'a_1_img.pose.txt' and 'a_1_img.pose.txt~' are both files of frame 'a_1_img'"),
              std::string::npos)
        << e.what();
  }
  scene.frames[1].name = "a_1/img.png";
  try {
    writeDataset(scene, "ace", dir_ / "clash");
    ADD_FAILURE() << "'a.1/img.png' and 'a_1/img.png' were written as one frame";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("a_1_img"), std::string::npos) << e.what();
  }
}

// Found by an outside probe: frames x.png and x.jpg both wrote their depth to x.depth, the
// second replacing the first's, exit 0; a name starting with a space was written and then not
// found by kapture's own reader (it trims fields); a folder named as kapture read as no frames.
TEST_F(DatasetWriters, KaptureRefusesNamesItCouldNotReadBackAndAFolderThatIsNoKapture) {
  fs::create_directories(dir_ / "source");
  Scene scene = sceneFailingAtItsSecondFrame(dir_ / "source");
  cv::imwrite((dir_ / "source" / "depth.png").string(), cv::Mat(48, 64, CV_16UC1, cv::Scalar(1500)));
  for (Frame& frame : scene.frames) {
    frame.image_path = dir_ / "source" / "a.png";
    frame.depth = DepthSource{dir_ / "source" / "depth.png"};
  }
  scene.frames[0].name = "x.png";
  scene.frames[1].name = "x.jpg";
  try {
    writeDataset(scene, "kapture", dir_ / "collide");
    ADD_FAILURE() << "two frames' depth written to one file";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("its depth would be written to 'x.depth', as another frame's is"),
              std::string::npos)
        << e.what();
  }
  scene.frames.pop_back();
  scene.frames[0].name = " lead.png";
  try {
    writeDataset(scene, "kapture", dir_ / "spaced");
    ADD_FAILURE() << "a name kapture's reader trims was written";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("kapture paths cannot start or end with a space"), std::string::npos)
        << e.what();
  }
  fs::create_directories(dir_ / "not_kapture");
  try {
    loadDataset(dir_ / "not_kapture", "kapture");
    ADD_FAILURE() << "an empty folder read as kapture";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not a kapture dataset"), std::string::npos) << e.what();
  }
}

// A copy written inside the dataset it converts became part of it (probe).
TEST_F(DatasetWriters, AnOutputInsideTheDatasetIsRefused) {
  fs::create_directories(dir_ / "source");
  const Scene scene = sceneFailingAtItsSecondFrame(dir_ / "source");
  for (const fs::path& out : {dir_ / "source" / "copy", dir_ / "source" / "a" / ".." / "copy2"}) {
    try {
      writeDataset(scene, "manifest", out);
      ADD_FAILURE() << out << " accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("output folder is inside the dataset it converts"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(out));
  }
}

TEST_F(DatasetWriters, AnOutputFolderThatCannotBeExaminedIsRefusedNamingIt) {
  const fs::path loop = dir_ / "selfloop";
  fs::create_directory_symlink(loop, loop);
  try {
    requireEmptyOutputFolder(loop);
    ADD_FAILURE() << "a loop of links accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(loop.string() + ": cannot examine the output folder: ", 0), 0u) << e.what();
  }
  EXPECT_THROW(writeDataset(Scene(), "manifest", loop), InputError);
}

}  // namespace
}  // namespace ffloc
