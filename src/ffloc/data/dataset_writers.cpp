#include "ffloc/data/dataset_writers.h"

#include <algorithm>
#include <functional>

#include "ffloc/core/error.h"
#include "ffloc/data/depth.h"
#include "ffloc/data/format_io.h"
#include "ffloc/core/utf8.h"
#include "ffloc/data/manifest.h"
#include "ffloc/io/input_file.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

struct DatasetWriter {
  const char* format;
  std::function<std::vector<std::string>(const Scene&, const fs::path&)> write;
};

const std::vector<DatasetWriter>& writers() {
  static const std::vector<DatasetWriter> kWriters = {
      {"manifest", writeManifestDataset}, {"mapfree", writeMapFree}, {"ace", writeAceLayout},
      {"rio10", writeRio10},              {"indoor6", writeIndoor6}, {"kapture", writeKapture},
  };
  return kWriters;
}

}  // namespace

std::vector<std::string> datasetWriterFormats() {
  std::vector<std::string> names;
  for (const auto& writer : writers()) names.push_back(writer.format);
  return names;
}

void writeIntoNewFolder(const fs::path& out_dir, const std::function<void(const fs::path& out)>& write) {
  fs::path out = fs::absolute(out_dir).lexically_normal();
  if (out.filename().empty()) out = out.parent_path();  // "out/" ends in an empty part
  requireEmptyOutputFolder(out);
  fs::path outermost_created;
  for (fs::path folder = out; !fs::exists(folder); folder = folder.parent_path()) outermost_created = folder;
  std::error_code created;
  fs::create_directories(out, created);
  if (created) throwInputError(out.string(), 0, "cannot create the output folder: " + created.message());
  try {
    try {
      write(out);
    } catch (const fs::filesystem_error& error) {
      // A folder that cannot be written (immutable, read-only mount) ended as an internal error.
      // A copy's error holds its source first and its destination second: the latter is written.
      const fs::path& written = !error.path2().empty() ? error.path2() : !error.path1().empty() ? error.path1() : out;
      throwInputError(written.string(), 0, std::string("cannot write: ") + error.code().message());
    }
  } catch (...) {
    std::error_code ignored;
    if (!outermost_created.empty()) {
      fs::remove_all(outermost_created, ignored);
    } else {
      // The error_code steps: a throw here would replace the error being handled.
      std::vector<fs::path> written;
      for (fs::directory_iterator entry(out, ignored); !ignored && entry != fs::directory_iterator();
           entry.increment(ignored))
        written.push_back(entry->path());
      for (const fs::path& path : written) fs::remove_all(path, ignored);
    }
    throw;
  }
}

std::vector<std::string> writeDataset(const Scene& scene, const std::string& format, const fs::path& out_dir) {
  for (const auto& writer : writers()) {
    if (format != writer.format) continue;
    // Written inside the dataset, the copy becomes part of it: a reader that searches the
    // dataset's folders (7-Scenes' seq-XX, kapture's sensors) then finds the copy's files too.
    if (!scene.root.empty() && liesWithin(out_dir, scene.root))
      throwInputError(out_dir.string(), 0, "output folder is inside the dataset it converts (" + scene.root.string() +
                                                "); write it elsewhere");
    std::vector<std::string> names;
    writeIntoNewFolder(out_dir, [&](const fs::path& out) { names = writer.write(scene, out); });
    return names;
  }
  std::string known;
  for (const auto& name : datasetWriterFormats()) known += (known.empty() ? "" : ", ") + name;
  throw InputError("format: cannot write '" + format + "' (known: " + known + ")");
}

std::vector<std::string> writeManifestDataset(const Scene& scene, const fs::path& out) {
  // Images are copied under images/ and the frames keep their names (the manifest's `name`): named
  // by their new paths, a converted copy's images were new to `map --append` (the map doubled)
  // and "images/" grew at every conversion (an outside probe). Depth maps keep their encoding.
  Scene copy = scene;
  copy.root = out;
  const std::vector<std::string> paths = portableFrameNames(scene);
  // Before anything is copied: the JSON writer's own error named no file (an internal error, exit 3).
  for (size_t i = 0; i < paths.size(); ++i)
    for (const std::string& name : {paths[i], scene.frames[i].name})
      if (!isUtf8(name))
        throwInputError(scene.frames[i].image_path.string(), 0,
                        "image name '" + name + "' is not UTF-8, which a manifest (JSON) cannot hold; rename the file");
  std::vector<std::string> names;
  for (size_t i = 0; i < copy.frames.size(); ++i) {
    Frame& frame = copy.frames[i];
    const std::string image = "images/" + paths[i];
    copyFrameImage(frame, out / image);
    if (frame.depth) {
      const fs::path depth = out / "depth" / (paths[i] + frame.depth->path.extension().string());
      // As the other writers, which read the depth, refuse it: copy_file's own error was an
      // internal one.
      requireRegularFile(frame.depth->path, "depth file");
      // Decoded once, as the other writers decode it, so that a corrupt or 8-bit depth map is
      // refused here too (it was copied, exit 0).
      readDepthMetres(scene.frames[i]);
      fs::create_directories(depth.parent_path());
      fs::copy_file(frame.depth->path, depth, fs::copy_options::overwrite_existing);
      frame.depth->path = depth;
    }
    frame.image_path = out / image;
    names.push_back(frame.name);
  }
  writeManifest(copy, out / kManifestFileName);
  return names;
}

}  // namespace ffloc
