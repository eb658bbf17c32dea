#pragma once

#include <string>
#include <string_view>

namespace ffloc {

// Whether `text` is well-formed UTF-8 (RFC 3629: no overlong forms, no surrogates, nothing past
// U+10FFFF). JSON text must be, so names that reach map files and --json answers are checked up
// front rather than failing, or being replaced, after the work is done.
bool isUtf8(std::string_view text);

// `text` with each byte that is not part of well-formed UTF-8 written as \xhh: an error naming a
// file whose name is not UTF-8 was itself not valid text for the terminal or a log.
std::string escapeInvalidUtf8(std::string_view text);

// `text` on one line: control characters and DEL written as \n, \r, \t or \xHH. A client's
// newline in a log line would start a forged line, and a NUL ends a line (and an exception's
// message) for many readers.
std::string escapeControlCharacters(std::string_view text);

}  // namespace ffloc
