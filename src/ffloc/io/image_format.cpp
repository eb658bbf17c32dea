#include "ffloc/io/image_format.h"

#include <array>
#include <cerrno>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <type_traits>

// jpeglib.h first: it brings the configuration jerror.h numbers its messages by, and in the other
// order every message after the arithmetic-coding ones is numbered two lower than libjpeg's.
#include <jpeglib.h>
#include <jerror.h>

#include "ffloc/core/error.h"
#include "ffloc/io/image_size.h"

namespace ffloc {

bool startsLikePng(std::string_view bytes) { return bytes.substr(0, 8) == "\x89PNG\r\n\x1a\n"; }

bool startsLikeJpeg(std::string_view bytes) { return bytes.substr(0, 3) == "\xFF\xD8\xFF"; }

bool hasDecodableImageSignature(std::string_view bytes) {
  const auto startsWith = [&](std::string_view prefix, size_t at = 0) {
    return bytes.size() >= at + prefix.size() && bytes.substr(at, prefix.size()) == prefix;
  };
  if (startsLikePng(bytes) || startsLikeJpeg(bytes)) return true;
  if (startsWith(std::string_view("II*\0", 4)) || startsWith(std::string_view("MM\0*", 4))) return true;
  if (startsWith(std::string_view("II+\0", 4)) || startsWith(std::string_view("MM\0+", 4))) return true;  // BigTIFF
  if (startsWith("BM")) return true;
  if (startsWith("RIFF") && startsWith("WEBP", 8)) return true;
  if (bytes.size() >= 2 && bytes[0] == 'P' && ((bytes[1] >= '1' && bytes[1] <= '7') || bytes[1] == 'F' || bytes[1] == 'f')) {
    return true;
  }
  return startsWith("\x76\x2F\x31\x01");  // OpenEXR
}

bool jpegReachesItsEnd(std::string_view bytes) {
  const auto byteAt = [&](size_t at) { return static_cast<unsigned char>(bytes[at]); };
  if (!startsLikeJpeg(bytes)) return false;
  size_t at = 2;
  while (true) {
    // A marker: 0xFF, fill bytes 0xFF, its type. Bytes where a marker should start are skipped,
    // as libjpeg skips them.
    while (at < bytes.size() && byteAt(at) != 0xFF) ++at;
    while (at < bytes.size() && byteAt(at) == 0xFF) ++at;
    if (at >= bytes.size()) return false;
    const unsigned type = byteAt(at++);
    if (type == 0xD9) return true;                                  // end of image
    if (type == 0x00 || type == 0x01 || (type >= 0xD0 && type <= 0xD7)) continue;  // no length
    if (at + 2 > bytes.size()) return false;
    const size_t length = (size_t{byteAt(at)} << 8) | byteAt(at + 1);
    if (length < 2 || at + length > bytes.size()) return false;
    at += length;
    if (type != 0xDA) continue;
    // After a start of scan, the compressed data: 0xFF is followed by 0x00 (a stuffed byte), a
    // restart marker, or the marker that ends the scan.
    while (true) {
      while (at < bytes.size() && byteAt(at) != 0xFF) ++at;
      if (at + 1 >= bytes.size()) return false;
      const unsigned next = byteAt(at + 1);
      if (next == 0x00 || (next >= 0xD0 && next <= 0xD7)) {
        at += 2;
      } else if (next == 0xFF) {
        ++at;
      } else {
        break;
      }
    }
  }
}

namespace {

// libjpeg's error and progress managers, with the first problem kept as text; fatal errors and
// problems jump back to jpegDataProblem (libjpeg's default error exit ends the process).
struct JpegWatch {
  jpeg_error_mgr manager;  // first: libjpeg hands back a pointer to it
  jpeg_progress_mgr progress;
  std::jmp_buf stop;
  char problem[JMSG_LENGTH_MAX + 128] = {};
};
static_assert(std::is_standard_layout_v<JpegWatch>);

JpegWatch& watchOf(j_common_ptr cinfo) { return *reinterpret_cast<JpegWatch*>(cinfo->err); }

// Compressed data left over after a scan's last block: a baseline JPEG with a flipped bit decodes
// without a bad code (libjpeg-turbo's fast Huffman path reads one as a zero) and ends with
// hundreds of such bytes (298-3014 in the tests); encoders pad a scan by a byte or two (some
// webcams' "2 extraneous bytes before marker 0xd9"). No JPEG in ../shared/data has any.
constexpr int kMostPaddingBytes = 64;
// A progressive JPEG has about ten scans; each costs a pass over the image (2.5 ms at 40
// megapixels), and a 32 MB upload of tiny repeated scans held hours of them.
constexpr int kMostScans = 256;

bool isDamage(const jpeg_decompress_struct& decoder, const jpeg_error_mgr& message) {
  switch (message.msg_code) {
    case JWRN_HIT_MARKER:       // "Corrupt JPEG data: premature end of data segment"
    case JWRN_HUFF_BAD_CODE:    // "Corrupt JPEG data: bad Huffman code"
    case JWRN_MUST_RESYNC:      // "Corrupt JPEG data: found marker ... instead of RST"
    case JWRN_JPEG_EOF:         // "Premature end of JPEG file"
    case JWRN_BOGUS_PROGRESSION:
      return true;
    case JWRN_EXTRANEOUS_DATA: {  // "Corrupt JPEG data: N extraneous bytes before marker 0x.."
      // Between header segments, before any scan, stray bytes are harmless; before a restart
      // marker no encoder pads.
      if (decoder.input_scan_number == 0) return false;
      const int marker = message.msg_parm.i[1];
      return message.msg_parm.i[0] > kMostPaddingBytes || (marker >= 0xD0 && marker <= 0xD7);
    }
    default:
      return false;
  }
}

}  // namespace

std::string jpegDataProblem(std::string_view bytes) {
  if (!startsLikeJpeg(bytes)) return "";
  jpeg_decompress_struct decoder{};
  JpegWatch watch;
  decoder.err = jpeg_std_error(&watch.manager);
  watch.manager.error_exit = [](j_common_ptr cinfo) { std::longjmp(watchOf(cinfo).stop, 1); };
  watch.manager.emit_message = [](j_common_ptr cinfo, int level) {
    JpegWatch& own = watchOf(cinfo);
    if (level >= 0 || !isDamage(*reinterpret_cast<j_decompress_ptr>(cinfo), own.manager)) return;
    char damage[JMSG_LENGTH_MAX];
    own.manager.format_message(cinfo, damage);
    std::snprintf(own.problem, sizeof(own.problem),
                  "damaged JPEG data, which the decoder would fill with garbage (libjpeg: %s)", damage);
    std::longjmp(own.stop, 1);  // no need to read on
  };
  watch.progress.progress_monitor = [](j_common_ptr cinfo) {
    if (reinterpret_cast<j_decompress_ptr>(cinfo)->input_scan_number <= kMostScans) return;
    JpegWatch& own = watchOf(cinfo);
    std::snprintf(own.problem, sizeof(own.problem),
                  "a JPEG of more than %d scans (a progressive one has about ten), each a pass of the decoder over "
                  "the image",
                  kMostScans);
    std::longjmp(own.stop, 1);
  };
  if (setjmp(watch.stop) != 0) {
    // A fatal error is the decoder's to report (OpenCV then cannot decode the file either).
    jpeg_destroy_decompress(&decoder);
    return watch.problem;
  }
  jpeg_create_decompress(&decoder);
  decoder.progress = &watch.progress;
  jpeg_mem_src(&decoder, reinterpret_cast<const unsigned char*>(bytes.data()), static_cast<unsigned long>(bytes.size()));
  jpeg_read_header(&decoder, TRUE);
  // Past OpenCV's pixel limit (OPENCV_IO_MAX_IMAGE_PIXELS' default) the decoder refuses the file
  // from its header, where a progressive one's coefficients would take gigabytes here first.
  if (static_cast<uint64_t>(decoder.image_width) * decoder.image_height > (uint64_t{1} << 30)) {
    jpeg_destroy_decompress(&decoder);
    return "";
  }
  // Every coefficient is read, for the damage is in the entropy-coded data, but the image comes
  // out an eighth of the size in grey: a fraction of a decode's time, and of its memory for a
  // single-scan JPEG (a progressive one holds its coefficients as any decode of it does).
  decoder.scale_num = 1;
  decoder.scale_denom = 8;
  if (decoder.jpeg_color_space == JCS_YCbCr) decoder.out_color_space = JCS_GRAYSCALE;
  decoder.dct_method = JDCT_IFAST;
  decoder.do_fancy_upsampling = FALSE;
  jpeg_start_decompress(&decoder);
  // From libjpeg's pool, freed with the decoder: a jump out of libjpeg skips C++ destructors.
  JSAMPARRAY rows = (*decoder.mem->alloc_sarray)(reinterpret_cast<j_common_ptr>(&decoder), JPOOL_IMAGE,
                                                 decoder.output_width * decoder.output_components, 1);
  while (decoder.output_scanline < decoder.output_height) jpeg_read_scanlines(&decoder, rows, 1);
  jpeg_finish_decompress(&decoder);
  jpeg_destroy_decompress(&decoder);
  return watch.problem;
}

void requireDecodableImageFile(const std::filesystem::path& path, const std::string& refusal) {
  std::ifstream in(path, std::ios::binary);
  // A file that cannot be opened (no read permission) read as no bytes: "not a PNG, JPEG, ...".
  if (!in) throwInputError(path.string(), 0, refusal + ": cannot open the file: " + std::strerror(errno));
  std::array<char, 12> leading{};
  in.read(leading.data(), leading.size());
  const std::string_view bytes(leading.data(), static_cast<size_t>(in.gcount()));
  if (!hasDecodableImageSignature(bytes)) {
    throwInputError(path.string(), 0,
                    refusal + ": not a PNG, JPEG, TIFF, BMP, WebP, Netpbm or OpenEXR file (the image formats ffloc decodes)");
  }
  const bool png = startsLikePng(bytes);
  if ((png || startsLikeJpeg(bytes)) && !fileFrameSize(path)) {
    throwInputError(path.string(), 0, refusal + ": a " + (png ? "PNG" : "JPEG") + " whose header does not give its size");
  }
  if (startsLikeJpeg(bytes)) {
    in.clear();
    in.seekg(0);
    const std::string whole((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!jpegReachesItsEnd(whole)) throwInputError(path.string(), 0, refusal + ": " + kJpegCutShort);
    if (const std::string problem = jpegDataProblem(whole); !problem.empty())
      throwInputError(path.string(), 0, refusal + ": " + problem);
  }
}

}  // namespace ffloc
