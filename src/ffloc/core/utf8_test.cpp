#include "ffloc/core/utf8.h"

#include <gtest/gtest.h>

#include <string>

namespace ffloc {
namespace {

TEST(Utf8, AcceptsWellFormedText) {
  EXPECT_TRUE(isUtf8(""));
  EXPECT_TRUE(isUtf8("seq-01/frame-000000.color.png"));
  EXPECT_TRUE(isUtf8("caf\xC3\xA9 \xE2\x82\xAC \xF0\x9F\x93\xB7"));  // é € and a camera emoji
  EXPECT_TRUE(isUtf8(std::string("a\0b", 3)));
  EXPECT_TRUE(isUtf8("\xF4\x8F\xBF\xBF"));  // U+10FFFF, the last code point
}

TEST(Utf8, RefusesMalformedText) {
  EXPECT_FALSE(isUtf8("\xFF\xFE"));              // never in UTF-8
  EXPECT_FALSE(isUtf8("latin1 caf\xE9.png"));    // a Latin-1 é
  EXPECT_FALSE(isUtf8("\xC3"));                  // cut short
  EXPECT_FALSE(isUtf8("\xE2\x82"));              // cut short
  EXPECT_FALSE(isUtf8("\x80"));                  // a continuation byte alone
  EXPECT_FALSE(isUtf8("\xC0\xAF"));              // overlong '/'
  EXPECT_FALSE(isUtf8("\xE0\x80\xAF"));          // overlong '/'
  EXPECT_FALSE(isUtf8("\xED\xA0\x80"));          // a UTF-16 surrogate
  EXPECT_FALSE(isUtf8("\xF4\x90\x80\x80"));      // past U+10FFFF
}

TEST(Utf8, EscapesOnlyTheBytesThatAreNotUtf8) {
  EXPECT_EQ(escapeInvalidUtf8("q/caf\xC3\xA9.png"), "q/caf\xC3\xA9.png");
  EXPECT_EQ(escapeInvalidUtf8("q/q\xE9.png: not UTF-8"), "q/q\\xe9.png: not UTF-8");
  EXPECT_EQ(escapeInvalidUtf8("a\nb\xC0\xAF"), "a\nb\\xc0\\xaf");  // newlines kept; an overlong '/' escaped
  EXPECT_EQ(escapeInvalidUtf8("\xF0\x9F\x93"), "\\xf0\\x9f\\x93");  // cut short
}

TEST(Utf8, AsciiLowercaseLeavesOtherBytes) {
  EXPECT_EQ(asciiLowercase("IMAGE/Png; Boundary=X"), "image/png; boundary=x");
  EXPECT_EQ(asciiLowercase("CAF\xC3\x89.JPG"), "caf\xC3\x89.jpg");  // the E-acute's bytes as they were
}

TEST(Utf8, CutTextSaysItsLengthAndKeepsWholeCharacters) {
  EXPECT_EQ(cutText("short", 5), "short");
  EXPECT_EQ(cutText("abcdef", 3), "abc... (6 bytes, cut)");
  EXPECT_EQ(cutText("ab\xC3\xA9z", 3), "ab... (5 bytes, cut)");  // not between the two bytes of e-acute
}

}  // namespace
}  // namespace ffloc
