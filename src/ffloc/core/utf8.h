#pragma once

#include <cstddef>
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

// `text` cut after at most `max_bytes` bytes, not inside a UTF-8 character, with its length said
// ("... (5000 bytes, cut)"): a client's 5000-byte name filled log lines and answers at its will.
std::string cutText(std::string_view text, size_t max_bytes);

// `text` with A-Z as a-z (media types, URL schemes, file extensions: ASCII and case-blind).
std::string asciiLowercase(std::string_view text);

// `text` on one line: control characters and DEL written as \n, \r, \t or \xHH. A client's
// newline in a log line would start a forged line, and a NUL ends a line (and an exception's
// message) for many readers.
std::string escapeControlCharacters(std::string_view text);

}  // namespace ffloc
