#include "ffloc/io/image_size.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <jpeglib.h>
#include <opencv2/imgcodecs.hpp>

#include "ffloc/core/testing/shared_data.h"
#include "ffloc/io/image.h"
#include "ffloc/io/image_format.h"
#include "ffloc/io/testing/exif_jpeg.h"
#include "ffloc/data/scene_test_util.h"

namespace ffloc {
namespace {

// Bytes with "DICM" at offset 128 reached OpenCV's DICOM decoder, whose GDCM library failed an
// assertion and aborted the process (found by the localize_request fuzzer); image files of
// formats ffloc does not decode are refused before any decoder sees them.
TEST(ImageFormat, FilesOfOtherFormatsAreRefusedBeforeDecoding) {
  const auto dir = testing::makeTempDir("ffloc-image-format");
  testing::writeTextFile(dir / "scan.png", std::string(128, '\n') + "DICM.5\n");
  testing::expectInputError([&] { readImageSize(dir / "scan.png"); },
                            {"scan.png", "cannot decode image: not a PNG, JPEG, TIFF, BMP, WebP, Netpbm or OpenEXR file"});
  testing::expectInputError([&] { readImageRgb(dir / "scan.png"); }, {"scan.png", "image: cannot decode: not a PNG"});
  // A file that cannot be opened (an unreadable depth map, found by an outside probe) was called
  // "not a PNG, ...".
  testing::expectInputError([&] { requireDecodableImageFile(dir / "gone.png", "cannot decode depth image"); },
                            {"gone.png", "cannot decode depth image: cannot open the file: No such file or directory"});
  // A JPEG whose damaged APP0 length stops the header walk, while libjpeg skips on to a frame of
  // 65272 x 13041 (2.5 GB; found by the localize_request fuzzer, docs/fuzzing.md).
  static const char kBadApp0Length[] =
      "\xff\xd8\xff\xe0\x00\x01\x00\x0a\x0a\x0a\xff\xc0\x00\x11\x08\xfe\xf8\x32\xf1\x03\x01\x22\x00"
      "\x02\x11\x01\x03\x11\x01\xff\xda\x00\x0c\x03\x01\x00\x02\x11\x03\x11\x00\x3f\x05\x00\xff\xd9";
  testing::writeTextFile(dir / "damaged.jpg", std::string(kBadApp0Length, sizeof(kBadApp0Length) - 1));
  testing::expectInputError([&] { readImageSize(dir / "damaged.jpg"); },
                            {"damaged.jpg", "cannot decode image: a JPEG whose header does not give its size"});
  testing::expectInputError([&] { readImageRgb(dir / "damaged.jpg"); },
                            {"damaged.jpg", "image: cannot decode: a JPEG whose header does not give its size"});
  for (const char* signature : {"\x89PNG\r\n\x1a\n", "\xFF\xD8\xFF", "BM", "P6", "RIFF0000WEBP"}) {
    EXPECT_TRUE(hasDecodableImageSignature(signature)) << signature;
  }
  EXPECT_TRUE(hasDecodableImageSignature(std::string("II*\0", 4)));
  EXPECT_TRUE(hasDecodableImageSignature(std::string("\x76\x2F\x31\x01", 4)));
  for (const char* other : {"", "P", "RIFF0000WAVE", "GIF89a", "#?RADIANCE", "\xFF\x4F\xFF\x51"}) {
    EXPECT_FALSE(hasDecodableImageSignature(other)) << other;
  }
}

// A JPEG cut short decoded without an error, its missing rows grey (libjpeg printed "Premature end
// of JPEG file", naming no file). Every cut inside the compressed data is refused now, naming the
// file; a whole file, baseline or progressive (several scans), or with bytes after its end, is not.
// A 128 x 96 image of noise as a baseline JPEG and as a progressive one (several scans).
std::vector<std::string> noiseJpegs() {
  cv::Mat3b image(96, 128);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<std::string> jpegs;
  for (const std::vector<int>& parameters : {std::vector<int>{}, std::vector<int>{cv::IMWRITE_JPEG_PROGRESSIVE, 1}}) {
    std::vector<uchar> encoded;
    EXPECT_TRUE(cv::imencode(".jpg", image, encoded, parameters));
    jpegs.emplace_back(encoded.begin(), encoded.end());
  }
  return jpegs;
}

TEST(ImageFormat, JpegsCutShortAreRefused) {
  const auto dir = testing::makeTempDir("ffloc-jpeg-cut");
  for (const std::string& whole : noiseJpegs()) {
    EXPECT_TRUE(jpegReachesItsEnd(whole));
    EXPECT_TRUE(jpegReachesItsEnd(whole + "trailer a camera appended"));
    for (size_t kept : {whole.size() / 3, whole.size() / 2, whole.size() - 2, whole.size() - 1}) {
      EXPECT_FALSE(jpegReachesItsEnd(whole.substr(0, kept))) << kept << " of " << whole.size();
    }
    testing::writeTextFile(dir / "whole.jpg", whole);
    EXPECT_EQ(readImageRgb(dir / "whole.jpg").size(), cv::Size(128, 96));
    testing::writeTextFile(dir / "half.jpg", whole.substr(0, whole.size() / 2));
    testing::expectInputError([&] { readImageRgb(dir / "half.jpg"); },
                              {"half.jpg", "image: cannot decode: a JPEG cut short"});
  }
  EXPECT_FALSE(jpegReachesItsEnd("\x89PNG\r\n\x1a\n"));
}

// Damaged compressed data (here 32 one-bits, longer than any Huffman code) decoded without an
// error, the blocks after it garbage (libjpeg printed "Corrupt JPEG data", naming no file): it is
// refused, naming the file, baseline or progressive. A clean file, one with bytes after its end,
// one with stray bytes between its header segments and one padded by two bytes before its end
// (some webcams) are not; data left over after the last block is.
TEST(ImageFormat, JpegsWithDamagedDataAreRefused) {
  const auto dir = testing::makeTempDir("ffloc-jpeg-damage");
  for (const std::string& whole : noiseJpegs()) {
    EXPECT_EQ(jpegDataProblem(whole), "");
    EXPECT_EQ(jpegDataProblem(whole + "trailer a camera appended"), "");
    const size_t scan = whole.find("\xFF\xDA");
    ASSERT_NE(scan, std::string::npos);
    std::string stray = whole;
    stray.insert(whole.find("\xFF\xDB"), std::string(100, '\0'));  // before the quantisation tables
    EXPECT_EQ(jpegDataProblem(stray), "");
    std::string padded = whole;
    padded.insert(whole.size() - 2, std::string(2, '\0'));
    EXPECT_EQ(jpegDataProblem(padded), "");
    std::string run_on = whole;
    run_on.insert(whole.size() - 2, std::string(100, '\x55'));
    EXPECT_EQ(jpegDataProblem(run_on).rfind("damaged JPEG data", 0), 0u) << jpegDataProblem(run_on);

    for (int quarter = 1; quarter <= 3; ++quarter) {
      std::string damaged = whole;
      damaged.replace(scan + (whole.size() - scan) * quarter / 4, 8, std::string("\xFF\x00\xFF\x00\xFF\x00\xFF\x00", 8));
      ASSERT_TRUE(jpegReachesItsEnd(damaged));
      const std::string problem = jpegDataProblem(damaged);
      EXPECT_EQ(problem.rfind("damaged JPEG data, which the decoder would fill with garbage (libjpeg: Corrupt JPEG data: ", 0), 0u)
          << quarter << ": " << problem;
      testing::writeTextFile(dir / "damaged.jpg", damaged);
      testing::expectInputError([&] { readImageRgb(dir / "damaged.jpg"); },
                                {"damaged.jpg", "image: cannot decode: damaged JPEG data", "(libjpeg: Corrupt JPEG data"});
    }
  }
  EXPECT_EQ(jpegDataProblem("\x89PNG\r\n\x1a\n"), "");
  EXPECT_EQ(jpegDataProblem("\xFF\xD8\xFF"),  // the start and nothing after
            "damaged JPEG data, which the decoder would fill with garbage (libjpeg: Premature end of JPEG file)");
}

// A colour JPEG of 380 valid progressive scans: each coefficient of each component alone, a first
// pass and a refinement, written with libjpeg's own encoder.
std::string jpegOfManyScans() {
  jpeg_compress_struct encoder;
  jpeg_error_mgr errors;
  encoder.err = jpeg_std_error(&errors);
  jpeg_create_compress(&encoder);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&encoder, &buffer, &size);
  encoder.image_width = 32;
  encoder.image_height = 24;
  encoder.input_components = 3;
  encoder.in_color_space = JCS_RGB;
  jpeg_set_defaults(&encoder);
  std::vector<jpeg_scan_info> scans;
  scans.push_back({3, {0, 1, 2, 0}, 0, 0, 0, 1});  // DC of every component, then its last bit
  scans.push_back({3, {0, 1, 2, 0}, 0, 0, 1, 0});
  for (int refinement = 0; refinement < 2; ++refinement)
    for (int component = 0; component < 3; ++component)
      for (int k = 1; k < 64; ++k) scans.push_back({1, {component, 0, 0, 0}, k, k, refinement, 1 - refinement});
  encoder.scan_info = scans.data();
  encoder.num_scans = static_cast<int>(scans.size());
  jpeg_start_compress(&encoder, TRUE);
  std::vector<unsigned char> row(32 * 3);
  for (int y = 0; y < 24; ++y) {
    for (size_t x = 0; x < row.size(); ++x) row[x] = static_cast<unsigned char>((x * 37 + y * 91) % 256);
    JSAMPROW rows[1] = {row.data()};
    jpeg_write_scanlines(&encoder, rows, 1);
  }
  jpeg_finish_compress(&encoder);
  jpeg_destroy_compress(&encoder);
  std::string jpeg(reinterpret_cast<const char*>(buffer), size);
  std::free(buffer);
  return jpeg;
}

// A 32 MB upload of tiny scans held the decoder for hours (2.5 ms a scan at 40 megapixels): a JPEG
// of more than 256 scans is refused, before any decoder runs over them.
TEST(ImageFormat, JpegsOfHundredsOfScansAreRefused) {
  const std::string jpeg = jpegOfManyScans();
  size_t scans = 0;
  for (size_t at = jpeg.find("\xFF\xDA"); at != std::string::npos; at = jpeg.find("\xFF\xDA", at + 2)) ++scans;
  ASSERT_EQ(scans, 380u);
  EXPECT_EQ(jpegDataProblem(jpeg).rfind("a JPEG of more than 256 scans", 0), 0u) << jpegDataProblem(jpeg);
  for (const std::string& progressive : noiseJpegs()) EXPECT_EQ(jpegDataProblem(progressive), "");
}

// Every JPEG of the real datasets is clean: the test passes none of the cameras' own quirks off
// as damage.
TEST(ImageFormat, TheRealDatasetsJpegsAreNotDamaged) {
  FFLOC_REQUIRE_SHARED(data, "data");
  int jpegs = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(data)) {
    const std::string extension = entry.path().extension().string();
    if (extension != ".jpg" && extension != ".JPG" && extension != ".jpeg") continue;
    std::ifstream in(entry.path(), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(jpegDataProblem(bytes), "") << entry.path();
    ++jpegs;
  }
  EXPECT_GT(jpegs, 300);
}

TEST(ImageSize, ReadsHeadersOfEveryEncoding) {
  const auto dir = testing::makeTempDir("ffloc-image-size");
  const cv::Mat3b image(7, 13, cv::Vec3b(10, 20, 30));
  const std::vector<std::pair<std::string, std::vector<int>>> files = {
      {"a.png", {}},
      {"b.jpg", {}},
      {"c.jpg", {cv::IMWRITE_JPEG_PROGRESSIVE, 1}},  // SOF2 instead of SOF0
      {"d.tiff", {}},                                // not parsed: decoded instead
  };
  for (const auto& [name, parameters] : files) {
    ASSERT_TRUE(cv::imwrite((dir / name).string(), image, parameters));
    EXPECT_EQ(readImageSize(dir / name), cv::Size(13, 7)) << name;
  }
  testing::writeTextFile(dir / "bad.jpg", std::string("\xFF\xD8\xFF\xE0\x00\x02garbage", 13));
  testing::expectInputError([&] { readImageSize(dir / "bad.jpg"); }, {"bad.jpg", "cannot decode"});
  testing::expectInputError([&] { readImageSize(dir / "none.png"); }, {"none.png", "not found"});
}

TEST(ImageSize, ReadsHeadersInMemory) {
  const cv::Mat3b image(7, 13, cv::Vec3b(10, 20, 30));
  for (const std::string extension : {".png", ".jpg"}) {
    std::vector<uchar> bytes;
    ASSERT_TRUE(cv::imencode(extension, image, bytes));
    EXPECT_EQ(encodedImageSize(std::string(bytes.begin(), bytes.end())), cv::Size(13, 7)) << extension;
  }
  std::vector<uchar> tiff;
  ASSERT_TRUE(cv::imencode(".tiff", image, tiff));
  EXPECT_FALSE(encodedImageSize(std::string(tiff.begin(), tiff.end())));
  EXPECT_FALSE(encodedImageSize("\x89PNG"));
  EXPECT_FALSE(encodedImageSize(""));
}

// Found by the image_size fuzzer: an APP1 segment whose length (2) leaves no room for its tag
// sent the header walk back to the same marker forever, on a request body of 17 bytes.
TEST(ImageSize, ShortApp1SegmentDoesNotLoop) {
  const std::string bytes("\xff\xd8\xff\xe1\x00\x02\x00\x08\x00\x97\xff\xff\xff\x10\x11\xff\xff", 17);
  EXPECT_FALSE(encodedImageSize(bytes));
  const auto dir = testing::makeTempDir("ffloc-image-size");
  testing::writeTextFile(dir / "short_app1.jpg", bytes);
  testing::expectInputError([&] { readImageSize(dir / "short_app1.jpg"); }, {"short_app1.jpg", "cannot decode"});
  // The same segment with room for a tag that is not EXIF is still skipped.
  const std::vector<uchar> jpeg = [] {
    std::vector<uchar> encoded;
    cv::imencode(".jpg", cv::Mat3b(7, 13, cv::Vec3b(1, 2, 3)), encoded);
    return encoded;
  }();
  const std::string with_app1 = std::string(jpeg.begin(), jpeg.begin() + 2) + std::string("\xff\xe1\x00\x06XMP\0", 8) +
                                std::string(jpeg.begin() + 2, jpeg.end());
  EXPECT_EQ(encodedImageSize(with_app1), cv::Size(13, 7));
}

// libjpeg skips bytes where a marker should start; the header walk must find the frame it then
// decodes (the localize_request fuzzer found a 12040x14895 frame behind such bytes). A frame
// after EXIF data has a size as stored, though not necessarily as decoded.
TEST(ImageSize, JpegFrameBehindExtraneousBytesOrExif) {
  const std::vector<uchar> jpeg = [] {
    std::vector<uchar> encoded;
    cv::imencode(".jpg", cv::Mat3b(7, 13, cv::Vec3b(1, 2, 3)), encoded);
    return encoded;
  }();
  const std::string extraneous = std::string(jpeg.begin(), jpeg.begin() + 2) + "\x12\x34\xff" +
                                 std::string(jpeg.begin() + 2, jpeg.end());
  EXPECT_EQ(encodedImageSize(extraneous), cv::Size(13, 7));
  EXPECT_EQ(encodedFrameSize(extraneous), cv::Size(13, 7));
  const std::string exif = std::string(jpeg.begin(), jpeg.begin() + 2) + std::string("\xff\xe1\x00\x08" "Exif\0\0", 10) +
                           std::string(jpeg.begin() + 2, jpeg.end());
  EXPECT_FALSE(encodedImageSize(exif));
  EXPECT_EQ(encodedFrameSize(exif), cv::Size(13, 7));
}

// PNG's chunk checksum (CRC-32, reflected, polynomial 0xEDB88320).
uint32_t crc32(const std::string& bytes) {
  uint32_t crc = 0xFFFFFFFFu;
  for (const unsigned char byte : bytes) {
    crc ^= byte;
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

// A phone's portrait JPEG is stored sideways with an EXIF orientation; the size checked against
// intrinsics must be the size decoding gives, as the image is used upright.
TEST(ImageSize, AJpegsExifOrientationTurnsItsSizeAsDecodingDoes) {
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", cv::Mat3b(7, 13, cv::Vec3b(1, 2, 3)), jpeg);
  const std::string app1 = testing::exifOrientationSegment(6);
  const auto dir = testing::makeTempDir("ffloc-exif-orientation");
  testing::writeTextFile(dir / "portrait.jpg", testing::jpegWithExifOrientation(cv::Mat3b(7, 13, cv::Vec3b(1, 2, 3)), 6));
  EXPECT_EQ(readImageRgb(dir / "portrait.jpg").size(), cv::Size(7, 13));
  EXPECT_EQ(readImageSize(dir / "portrait.jpg"), cv::Size(7, 13));

  // libjpeg reads the segments up to the scan, so EXIF data after the frame header counts too.
  const size_t frame_at = std::string(jpeg.begin(), jpeg.end()).find("\xff\xc0");
  ASSERT_NE(frame_at, std::string::npos);
  const size_t frame_end = frame_at + 2 + (jpeg[frame_at + 2] << 8 | jpeg[frame_at + 3]);
  testing::writeTextFile(dir / "late_exif.jpg", std::string(jpeg.begin(), jpeg.begin() + frame_end) + app1 +
                                                    std::string(jpeg.begin() + frame_end, jpeg.end()));
  EXPECT_EQ(readImageRgb(dir / "late_exif.jpg").size(), cv::Size(7, 13));
  EXPECT_EQ(readImageSize(dir / "late_exif.jpg"), cv::Size(7, 13));
  // OpenCV takes an APP1 holding a TIFF header as EXIF whatever its tag.
  std::string other_tag = app1;
  other_tag.replace(4, 4, "XXXX");
  testing::writeTextFile(dir / "other_tag.jpg",
                         std::string(jpeg.begin(), jpeg.begin() + 2) + other_tag + std::string(jpeg.begin() + 2, jpeg.end()));
  EXPECT_EQ(readImageSize(dir / "other_tag.jpg"), readImageRgb(dir / "other_tag.jpg").size());

  // A PNG's eXIf chunk (before the image data) is applied alike.
  std::vector<uchar> png;
  cv::imencode(".png", cv::Mat3b(7, 13, cv::Vec3b(1, 2, 3)), png);
  const std::string tiff = app1.substr(10);
  const std::string chunk = std::string("\0\0\0", 3) + static_cast<char>(tiff.size()) + "eXIf" + tiff;
  const uint32_t crc = crc32(chunk.substr(4));
  std::string crc_bytes;
  for (int shift = 24; shift >= 0; shift -= 8) crc_bytes += static_cast<char>((crc >> shift) & 0xFF);
  const size_t after_header = 8 + 8 + 13 + 4;
  testing::writeTextFile(dir / "portrait.png", std::string(png.begin(), png.begin() + after_header) + chunk +
                                                   crc_bytes + std::string(png.begin() + after_header, png.end()));
  EXPECT_EQ(readImageRgb(dir / "portrait.png").size(), cv::Size(7, 13));
  EXPECT_EQ(readImageSize(dir / "portrait.png"), cv::Size(7, 13));
  // After the image data, just before IEND (12 bytes: length, type, CRC), it is applied too.
  const size_t iend = png.size() - 12;
  testing::writeTextFile(dir / "late.png", std::string(png.begin(), png.begin() + iend) + chunk + crc_bytes +
                                               std::string(png.begin() + iend, png.end()));
  EXPECT_EQ(readImageRgb(dir / "late.png").size(), cv::Size(7, 13));
  EXPECT_EQ(readImageSize(dir / "late.png"), cv::Size(7, 13));
}

TEST(ImageSize, AgreesWithDecodingOnTheSharedSamples) {
  FFLOC_REQUIRE_SHARED(data, "data");
  for (const std::string name :
       {"7scenes_redkitchen/frame-000000.color.jpg", "7scenes_redkitchen/frame-000000.depth.png",
        "7scenes_redkitchen_png/rgbd-frames/frame-000150.color.png", "instant_ngp_fox/images/0001.jpg",
        "colmap_maupertuis_kapture_sample/images/00.jpg", "strecha_herzjesu_p8/images/0000.jpg"}) {
    const cv::Mat decoded = cv::imread((data / name).string(), cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
    ASSERT_FALSE(decoded.empty()) << name;
    EXPECT_EQ(readImageSize(data / name), decoded.size()) << name;
  }
}

}  // namespace
}  // namespace ffloc
