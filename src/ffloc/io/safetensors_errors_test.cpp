#include <gtest/gtest.h>

#include <fstream>
#include <random>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/io/tensor_archive.h"

namespace ffloc {
namespace {

class SafetensorsErrors : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::makeTempDir("ffloc-safetensors-errors"); }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path write(const std::string& bytes) {
    const auto path = dir_ / "bad.safetensors";
    std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
  }
  // A file with `header` (padded to 8) followed by `data_bytes` zero bytes.
  std::filesystem::path withHeader(std::string header, size_t data_bytes) {
    header.append((8 - header.size() % 8) % 8, ' ');
    std::string bytes(8, '\0');
    for (int i = 0; i < 8; ++i) bytes[i] = static_cast<char>((header.size() >> (8 * i)) & 0xff);
    return write(bytes + header + std::string(data_bytes, '\0'));
  }
  // The InputError message of opening `path` (by content sniffing or as safetensors).
  static std::string failure(const std::filesystem::path& path, bool sniff = false) {
    try {
      if (sniff) {
        openTensorArchive(path);
      } else {
        openSafetensors(path);
      }
    } catch (const InputError& error) {
      return error.what();
    }
    return "(opened without error)";
  }
  void expectFailure(const std::filesystem::path& path, const std::vector<std::string>& parts,
                     bool sniff = false) {
    const std::string message = failure(path, sniff);
    EXPECT_NE(message.find("bad.safetensors"), std::string::npos) << message;
    for (const std::string& part : parts) EXPECT_NE(message.find(part), std::string::npos) << message;
  }

  std::filesystem::path dir_;
};

TEST_F(SafetensorsErrors, ShortAndGarbageFiles) {
  expectFailure(write(""), {"too short"});
  expectFailure(write(""), {"file too short (0 bytes)"}, true);
  expectFailure(write("{}"), {"file too short (2 bytes)"}, true);
  expectFailure(write("abc"), {"too short"});
  expectFailure(write("this is not a weights file at all"), {"exceeds the file size"});
  expectFailure(write("this is not a weights file at all"), {"unrecognised"}, true);
  expectFailure(write(std::string("\x80\x02}q\x00.", 6)), {"legacy"}, true);
  expectFailure(withHeader("{not json", 0), {"malformed JSON header"});
  expectFailure(withHeader("[1, 2]", 0), {"expected a JSON object"});
}

TEST_F(SafetensorsErrors, HeaderLengthBeyondFileOrLimit) {
  std::string huge(8, '\xff');
  expectFailure(write(huge + "{}"), {"exceeds the file size"});
  // Within the file but above the 100 MB cap is refused before parsing anything.
  std::string capped(8, '\0');
  capped[3] = 0x08;  // 2^27 = 128 MiB
  const auto path = dir_ / "bad.safetensors";
  {
    std::ofstream out(path, std::ios::binary);
    out.write(capped.data(), 8);
    out.seekp((1 << 27) + 16);
    out.put('\0');
  }
  expectFailure(path, {"100 MB"});
}

TEST_F(SafetensorsErrors, BadTensorEntriesNameTheTensorAndField) {
  expectFailure(withHeader(R"({"w":{"dtype":"F8","shape":[1],"data_offsets":[0,1]}})", 1),
                {"tensor 'w'", "unknown dtype 'F8'"});
  expectFailure(withHeader(R"({"w":{"shape":[1],"data_offsets":[0,4]}})", 4),
                {"tensor 'w'", "dtype"});
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":[-1],"data_offsets":[0,4]}})", 4),
                {"tensor 'w'", "shape entry -1"});
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":[1.5],"data_offsets":[0,4]}})", 4),
                {"tensor 'w'", "shape entry 1.5"});
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":"4","data_offsets":[0,4]}})", 4),
                {"tensor 'w'", "shape"});
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":[4294967296,4294967296],"data_offsets":[0,4]}})", 4),
                {"tensor 'w'", "overflows"});
  expectFailure(withHeader(R"({"w":{"dtype":"F64","shape":[2305843009213693952],"data_offsets":[0,4]}})", 4),
                {"tensor 'w'", "overflows the byte size"});
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})", 4),
                {"tensor 'w'", "run past the data section"});
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":[2],"data_offsets":[0,4]}})", 8),
                {"tensor 'w'", "needs 8"});
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":[1],"data_offsets":[4,0]}})", 8),
                {"tensor 'w'", "end before begin"});
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":[1],"data_offsets":[0]}})", 8),
                {"tensor 'w'", "data_offsets"});
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":[2],"data_offsets":[0,8]},)"
                           R"("v":{"dtype":"F32","shape":[2],"data_offsets":[4,12]}})",
                           12),
                {"tensor 'v'", "overlap tensor 'w'"});
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},)"
                           R"("w":{"dtype":"F32","shape":[1],"data_offsets":[4,8]}})",
                           8),
                {"duplicated key 'w'"});
  expectFailure(withHeader(R"({"__metadata__":{"format":1}})", 0), {"__metadata__", "format"});
  expectFailure(withHeader(R"({"w":7})", 0), {"tensor 'w'"});
  // Deep nesting must neither overflow the stack while parsing nor while reporting.
  const std::string deep = std::string(200000, '[') + std::string(200000, ']');
  expectFailure(withHeader(R"({"w":{"dtype":"F32","shape":[1,)" + deep + R"(],"data_offsets":[0,4]}})", 4),
                {"nested deeper than 8"});
  // A long list is refused while parsing: 50 million zeros took 2.5 GB before (outside probe).
  std::string zeros = "0";
  for (int i = 0; i < 64; ++i) zeros += ",0";
  expectFailure(withHeader(R"({"w":{"dtype":"U8","shape":[)" + zeros + R"(],"data_offsets":[0,0]}})", 0),
                {"a list of more than 64 values"});
  EXPECT_EQ(failure(withHeader(R"({"w":{"dtype":"U8","shape":[)" + zeros.substr(2) + R"(],"data_offsets":[0,0]}})", 0)),
            "(opened without error)");  // 64 values: an empty tensor of rank 64
  // So is a tensor entry of many keys (a review: 100 MB of them parsed to about 1 GB).
  std::string keys;
  for (int i = 0; i < 17; ++i) keys += ",\"k" + std::to_string(i) + "\":0";
  expectFailure(withHeader(R"({"w":{"dtype":"U8","shape":[0],"data_offsets":[0,0])" + keys + "}}", 0),
                {"tensor 'w' has more than 16 fields"});
}

TEST_F(SafetensorsErrors, EmptyTensorsMayShareOffsets) {
  const auto archive = openSafetensors(
      withHeader(R"({"e":{"dtype":"F32","shape":[0],"data_offsets":[4,4]},)"
                 R"("w":{"dtype":"I32","shape":[2],"data_offsets":[0,8]}})",
                 8));
  EXPECT_EQ(archive->names(), (std::vector<std::string>{"w", "e"}));
  EXPECT_EQ(archive->at("e").nbytes, 0u);
}

// Two files joined by `cat` opened as the first (an outside probe, with map files).
TEST_F(SafetensorsErrors, BytesAfterTheLastTensorAreRefused) {
  const std::string header = R"({"w":{"dtype":"I32","shape":[2],"data_offsets":[0,8]}})";
  EXPECT_NO_THROW(openSafetensors(withHeader(header, 8)));
  expectFailure(withHeader(header, 11), {"3 bytes follow the last tensor's data (which ends at byte 72 of 75)"});
}

// Random damage ends in InputError or a valid archive whose views stay inside the file.
TEST_F(SafetensorsErrors, RandomDamageNeverCrashes) {
  const std::string header =
      R"({"__metadata__":{"k":"v"},"a":{"dtype":"F32","shape":[2,2],"data_offsets":[0,16]},)"
      R"("b":{"dtype":"I64","shape":[1],"data_offsets":[16,24]}})";
  const auto original = withHeader(header, 24);
  std::ifstream in(original, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::mt19937 random(3);
  for (int trial = 0; trial < 1000; ++trial) {
    std::string damaged = bytes;
    for (int i = 0; i <= trial % 3; ++i) {
      // Mostly the header, where the parsing is.
      const size_t at = random() % 4 == 0 ? random() % 8 : random() % damaged.size();
      damaged[at] = static_cast<char>(random() & 0xff);
    }
    const auto path = write(damaged);
    try {
      const auto archive = openTensorArchive(path);
      for (const std::string& name : archive->names()) {
        const TensorView& view = archive->at(name);
        volatile uint8_t sink = 0;
        for (size_t b = 0; b < view.nbytes; ++b) sink = sink ^ view.data[b];
      }
    } catch (const InputError& error) {
      EXPECT_NE(std::string(error.what()).find("bad.safetensors"), std::string::npos) << error.what();
    }
  }
}

TEST_F(SafetensorsErrors, TruncatedFixture) {
  FFLOC_REQUIRE_SHARED(fixture, "fixtures/dust3r/case_encoder_single.safetensors");
  std::ifstream in(fixture, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (size_t length : {size_t{7}, size_t{64}, bytes.size() / 2, bytes.size() - 1}) {
    const std::string message = failure(write(bytes.substr(0, length)), true);
    EXPECT_NE(message.find("bad.safetensors"), std::string::npos) << length << ": " << message;
  }
}

}  // namespace
}  // namespace ffloc
