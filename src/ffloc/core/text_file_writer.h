#pragma once

#include <filesystem>
#include <string>

namespace ffloc {

// Writes text to a file atomically: a temporary file beside it, then a rename, so a reader never
// sees half a file and an interrupted write leaves the old one intact. A symbolic link's target
// is written, and a device or pipe (/dev/null, /dev/stdout) written through, never replaced.
// Throws InputError naming the file when its folder does not exist or the write fails.
void writeTextFile(const std::filesystem::path& path, const std::string& text);

// Whether writeTextFile writes `path` through rather than replacing a file: a descriptor of this
// process (/dev/stdout), a device or a pipe. Such an output has no folder to write beside it.
bool writesThrough(const std::filesystem::path& path);

// What keeps writeTextFile from replacing a file in `folder` ("is not writable: ...", "keeps what
// is written in it ..."), or "": tried with a file made and removed at once, as permission bits
// do not say it (root passes them in /proc, whose files no one can make; an append-only folder
// takes new files but no rename).
std::string folderWriteProblem(const std::filesystem::path& folder);

}  // namespace ffloc
