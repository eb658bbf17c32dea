#pragma once

#include <filesystem>

#include "ffloc/data/scene.h"

namespace ffloc {

// ffloc's native scene description ("ffloc-manifest", version 1), a JSON file named
// manifest.json. Schema and an example: docs/datasets.md. Conventions are the project's:
// camera-to-world poses with OpenCV axes, OpenCV pixel convention (top-left pixel centre at
// (0, 0)); paths are relative to the manifest's folder.
inline constexpr const char* kManifestFileName = "manifest.json";
inline constexpr const char* kManifestFormat = "ffloc-manifest";
inline constexpr int kManifestVersion = 1;

// Reads a manifest. Poses are checked (finite, last row 0 0 0 1, rotation orthonormal to 1e-2)
// but kept exactly as written, so write -> read round-trips bit for bit. Scene::root is the
// manifest's folder. Throws InputError naming the file and the offending field.
Scene readManifest(const std::filesystem::path& manifest_json);

// Writes `scene` as a manifest (temporary file, then rename, so readers never see a partial
// file). Frames with identical intrinsics share one camera entry. Scene::points are not stored.
void writeManifest(const Scene& scene, const std::filesystem::path& manifest_json);

// Whether `file` is a JSON object whose "format" is "ffloc-manifest", or a file that does not
// parse as JSON but names that format, or something there that is not a readable regular file
// (readManifest then reports the syntax error or what the file is).
bool isManifestFile(const std::filesystem::path& file);

}  // namespace ffloc
