#pragma once

#include <filesystem>
#include <optional>

namespace ffloc {

// The file `path` names once its symbolic links are followed: itself when it is no link, and
// what a link points to even when that does not exist yet. For writers that replace a file by
// renaming a new one over it, which would replace the link and leave its target as it was.
// InputError naming the path for a loop of links.
std::filesystem::path followSymlinks(const std::filesystem::path& path);

// The descriptor of this process that `path` names (/dev/stdout, /dev/stderr, /dev/fd/N,
// /proc/self/fd/N), if it names one. Such a path is written through that descriptor: followed
// and replaced, `--json /dev/stdout >> runs.log` replaced runs.log.
std::optional<int> openDescriptorNamed(const std::filesystem::path& path);

}  // namespace ffloc
