#pragma once

#include <filesystem>
#include <string>

namespace ffloc {

// Checks that `path` names a regular file (after following symbolic links) before a reader
// opens it. Opening a FIFO blocks until someone writes to it, a device can be endless, and a
// symbolic link loop makes std::filesystem throw its own error, which the CLI would report as
// an internal error. InputError naming the file: "<what> not found", "not a regular file (...)",
// or the system's reason ("Too many levels of symbolic links", "Permission denied").
void requireRegularFile(const std::filesystem::path& path, const std::string& what = "file");

// Whether `path` is `folder` or lies below it, however either is spelt ("d/../d/x", links):
// outputs written into a dataset's folder became part of it, or replaced its files.
bool liesWithin(const std::filesystem::path& path, const std::filesystem::path& folder);

}  // namespace ffloc
