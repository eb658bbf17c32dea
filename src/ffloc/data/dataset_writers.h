#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "ffloc/data/scene.h"

// Writing a Scene in another dataset format, so data moves between ffloc and the tools of each
// benchmark (`ffloc convert-dataset`). Each writer lays the files out as its format's published
// description says and as the matching reader (readers.h) reads them back; docs/datasets.md
// lists what each format keeps.
namespace ffloc {

// The formats writeDataset knows: {"manifest", "mapfree", "ace", "rio10", "indoor6", "kapture"}.
std::vector<std::string> datasetWriterFormats();

// Writes `scene` as `format` into `out_dir`, which must not exist or be empty. Images and depth
// maps are copied (re-encoded only where the format demands an encoding), so the output stands on
// its own. Formats with only a mapping and a query side store unassigned frames with the mapping
// frames. Returns, for each frame of `scene` in order, its Frame::name when `out_dir` is read back.
// Throws InputError for an unknown format, a non-empty output folder, or a scene the format cannot
// hold (lens distortion where it has no field for it); a failed write leaves no files behind
// (writeIntoNewFolder).
std::vector<std::string> writeDataset(const Scene& scene, const std::string& format,
                                      const std::filesystem::path& out_dir);

// Creates `out_dir` (checked by requireEmptyOutputFolder) and runs `write` on it, normalised to an
// absolute path. When `write` throws, what this run wrote is removed before the exception goes
// on: the folders it created, or what it put into the empty folder it was given, never what was
// there before; a partial output would otherwise have blocked the rerun as not empty.
void writeIntoNewFolder(const std::filesystem::path& out_dir,
                        const std::function<void(const std::filesystem::path& out)>& write);

// The writers writeDataset dispatches to; each expects an empty `out` folder.
std::vector<std::string> writeManifestDataset(const Scene& scene, const std::filesystem::path& out);
std::vector<std::string> writeMapFree(const Scene& scene, const std::filesystem::path& out);
std::vector<std::string> writeAceLayout(const Scene& scene, const std::filesystem::path& out);
std::vector<std::string> writeRio10(const Scene& scene, const std::filesystem::path& out);
std::vector<std::string> writeIndoor6(const Scene& scene, const std::filesystem::path& out);
std::vector<std::string> writeKapture(const Scene& scene, const std::filesystem::path& out);

}  // namespace ffloc
