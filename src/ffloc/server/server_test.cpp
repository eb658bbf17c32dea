#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <regex>
#include <sstream>
#include <thread>

#include "ffloc/classical/classical_localizer.h"
#include "ffloc/classical/classical_mapper.h"
#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/synthetic/synthetic.h"
#include "ffloc/io/image.h"
#include "ffloc/io/image_size.h"
#include "ffloc/model/torch_threads.h"
#include "ffloc/localization/localization_json.h"
#include "ffloc/pipeline/fastforward_localizer.h"
#include "ffloc/pipeline/mapper.h"
#include "ffloc/server/localization_server.h"
#include "ffloc/server/localize_request.h"
#include "ffloc/server/testing/raw_exchange.h"

// Last: it brings <resolv.h>, whose _res macro breaks Eigen headers included after it.
#include <httplib.h>

namespace ffloc {
namespace {

namespace fs = std::filesystem;

std::string pngBytes(const cv::Mat& rgb) {
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<uchar> bytes;
  cv::imencode(".png", bgr, bytes);
  return std::string(bytes.begin(), bytes.end());
}

std::map<std::string, std::string> pinholeFields() {
  return {{"fx", "100"}, {"fy", "101"}, {"cx", "31.5"}, {"cy", "23.5"}};
}

RequestLimits pixelLimit(size_t max_image_pixels) {
  RequestLimits limits;
  limits.max_image_pixels = max_image_pixels;
  return limits;
}

std::string requestErrorOf(const std::map<std::string, std::string>& fields, const std::string& image,
                           const RequestLimits& limits = {}) {
  try {
    parseLocalizeRequest(fields, image, LocalizeOptions{}, limits);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

using testing::rawExchange;

TEST(LocalizeRequest, ReadsIntrinsicsOverridesAndTheImageInRgbOrder) {
  cv::Mat rgb(48, 64, CV_8UC3, cv::Scalar(0, 0, 0));
  rgb.at<cv::Vec3b>(5, 7) = cv::Vec3b(255, 0, 0);
  auto fields = pinholeFields();
  fields["distortion"] = "0.1,-0.02,0.001,0";
  fields["name"] = "door.png";
  fields["top_k"] = "3";
  fields["features"] = "200";
  fields["seed"] = "17";
  fields["selection"] = "uniform";
  LocalizeOptions defaults;
  defaults.top_k = 10;
  const LocalizeRequest request = parseLocalizeRequest(fields, pngBytes(rgb), defaults);

  EXPECT_EQ(request.name, "door.png");
  EXPECT_DOUBLE_EQ(request.intrinsics.fx, 100);
  EXPECT_DOUBLE_EQ(request.intrinsics.fy, 101);
  EXPECT_DOUBLE_EQ(request.intrinsics.cx, 31.5);
  EXPECT_DOUBLE_EQ(request.intrinsics.cy, 23.5);
  EXPECT_EQ(request.intrinsics.width, 64);
  EXPECT_EQ(request.intrinsics.height, 48);
  EXPECT_EQ(request.intrinsics.distortion, (std::vector<double>{0.1, -0.02, 0.001, 0}));
  EXPECT_EQ(request.options.top_k, 3u);
  EXPECT_EQ(request.options.num_features, 200);
  EXPECT_EQ(request.options.seed, 17u);
  EXPECT_EQ(request.options.pnp.seed, 17u);
  EXPECT_EQ(request.options.selection, ImageSelection::kUniform);
  ASSERT_EQ(request.rgb.size(), rgb.size());
  EXPECT_EQ(request.rgb.at<cv::Vec3b>(5, 7), cv::Vec3b(255, 0, 0));

  const LocalizeRequest plain = parseLocalizeRequest(pinholeFields(), pngBytes(rgb), defaults);
  EXPECT_EQ(plain.options.top_k, 10u);
  EXPECT_EQ(plain.name, "query");
  EXPECT_TRUE(plain.intrinsics.distortion.empty());
}

TEST(LocalizeRequest, RefusesBadInputNamingTheField) {
  const std::string image = pngBytes(cv::Mat(48, 64, CV_8UC3, cv::Scalar(90, 90, 90)));
  struct Case {
    std::string field, value, expected_prefix;
  };
  const std::vector<Case> cases = {
      {"fx", "abc", "fx:"},       {"fx", "-3", "fx:"},          {"fy", "nan", "fy:"},
      {"cx", "1e9", "cx, cy:"},   {"cy", "-5", "cx, cy:"},      {"top_k", "0", "top_k:"},
      {"top_k", "2.5", "top_k:"}, {"features", "", "features:"}, {"seed", "-1", "seed:"},
      {"topk", "3", "topk:"},     {"distortion", "0.1,0.2", "distortion:"},
      {"distortion", "a,b,c,d", "distortion:"}, {"distortion", "0,0,0,0,", "distortion:"},
      {"selection", "best", "selection:"},      {"fx", " 100", "fx:"},         {"fx", "0x64", "fx:"},
      {"top_k", "101", "top_k:"},               {"features", "20001", "features:"},
  };
  for (const Case& c : cases) {
    auto fields = pinholeFields();
    fields[c.field] = c.value;
    const std::string error = requestErrorOf(fields, image);
    EXPECT_EQ(error.rfind(c.expected_prefix, 0), 0u) << c.field << "=" << c.value << " gave '" << error << "'";
  }
  // A client's long value, or a field name holding control characters, was quoted whole and raw.
  auto long_value = pinholeFields();
  long_value["fx"] = std::string(100000, '7') + "x";
  EXPECT_EQ(requestErrorOf(long_value, image),
            "fx: expected a finite number, got '" + std::string(64, '7') + "... (100001 bytes, cut)'");
  auto odd_name = pinholeFields();
  odd_name["a\nb"] = "1";
  EXPECT_EQ(requestErrorOf(odd_name, image).rfind("a\\nb: unknown field (known: ", 0), 0u);
  auto missing = pinholeFields();
  missing.erase("cy");
  EXPECT_EQ(requestErrorOf(missing, image).rfind("cy: missing", 0), 0u);
  EXPECT_EQ(requestErrorOf(pinholeFields(), "").rfind("image:", 0), 0u);
  EXPECT_EQ(requestErrorOf(pinholeFields(), "not an image at all").rfind("image:", 0), 0u);
  EXPECT_EQ(requestErrorOf(pinholeFields(), image, pixelLimit(64 * 48 - 1)).rfind("image: 64x48 is more", 0), 0u);
  EXPECT_EQ(requestErrorOf(pinholeFields(), image, pixelLimit(64 * 48)), "");
  // A 16-bit PNG at half the limit's pixels: twice the bytes (a probe's 280 KB one took 580 MB).
  const std::string deep = pngBytes(cv::Mat(48, 64, CV_16UC3, cv::Scalar(9000, 9000, 9000)));
  EXPECT_EQ(requestErrorOf(pinholeFields(), deep, pixelLimit(2 * 64 * 48 - 1)),
            "image: a 16-bit PNG of 64x48 is more than the 3071 pixels this server accepts at 16 bits (half its limit at 8)");
  EXPECT_EQ(requestErrorOf(pinholeFields(), deep, pixelLimit(2 * 64 * 48)), "");
  // A PNG header announcing 30000x30000 is refused from the header, before decoding allocates.
  std::string huge = "\x89PNG\r\n\x1a\n" + std::string("\0\0\0\x0dIHDR", 8) + std::string("\0\0\x75\x30\0\0\x75\x30", 8);
  EXPECT_EQ(requestErrorOf(pinholeFields(), huge).rfind("image: 30000x30000 is more", 0), 0u);
}

// Found by the localize_request fuzzer. Bytes with "DICM" at offset 128 went to OpenCV's DICOM
// decoder, whose GDCM library failed an assertion and aborted the server. And a JPEG whose APP0
// segment claims a length of 1 made the header walk give up, while libjpeg skips on to a frame of
// 65272 x 13041 and OpenCV allocated 2.5 GB for it: OpenCV's own pixel limit, which the server
// believed it had set, is read once when the library loads. Only PNG and JPEG bodies whose header
// declares their pixel grid reach a decoder now.
TEST(LocalizeRequest, OnlyPngAndJpegBodiesOfADeclaredSizeReachADecoder) {
  EXPECT_EQ(requestErrorOf(pinholeFields(), std::string(128, '\n') + "DICM.5\n"),
            "image: not a PNG or JPEG file (the server decodes those two, whose size it reads before decoding)");
  // The fuzzer's input, byte for byte.
  static const char kBadApp0Length[] =
      "\xff\xd8\xff\xe0\x00\x01\x00\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a"
      "\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\xff\xc0\x00\x11\x08\xfe\xf8\x32\xf1\x03\x01\x22\x00"
      "\x02\x11\x01\x03\x11\x01\xc3\xd3\xd4\xd5\xd6\xe2\xe3\xe4\xe5\xe6\xe7\xe8\xe9\xff\xda\x00"
      "\x0c\x03\x01\x00\x02\x11\x03\x11\x00\x3f\x05\x00\x00\x00\x0e\x00\x00\x00\xf9\x7c\xff\xd9";
  const std::string bad_app0_length(kBadApp0Length, sizeof(kBadApp0Length) - 1);
  ASSERT_EQ(bad_app0_length.size(), 88u);
  EXPECT_EQ(requestErrorOf(pinholeFields(), bad_app0_length),
            "image: a JPEG whose header does not give its size; it is not decoded");
  const cv::Mat pixels(48, 64, CV_8UC3, cv::Scalar(90, 60, 30));
  for (const std::string extension : {".png", ".jpg", ".tiff", ".bmp", ".ppm"}) {
    std::vector<uchar> encoded;
    ASSERT_TRUE(cv::imencode(extension, pixels, encoded)) << extension;
    const std::string error = requestErrorOf(pinholeFields(), std::string(encoded.begin(), encoded.end()));
    if (extension == ".png" || extension == ".jpg") {
      EXPECT_EQ(error, "") << extension;
    } else {
      EXPECT_EQ(error.rfind("image: not a PNG or JPEG file", 0), 0u) << extension << ": " << error;
    }
  }
}

// An upload whose compressed data is damaged was decoded, the blocks after the damage garbage
// (libjpeg only warned on stderr).
TEST(LocalizeRequest, AJpegWithDamagedDataIsRefused) {
  cv::Mat3b pixels(48, 64);
  cv::randu(pixels, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<uchar> encoded;
  ASSERT_TRUE(cv::imencode(".jpg", pixels, encoded));
  std::string damaged(encoded.begin(), encoded.end());
  const size_t scan = damaged.find("\xFF\xDA");
  ASSERT_NE(scan, std::string::npos);
  damaged.replace(scan + (damaged.size() - scan) / 3, 8, std::string("\xFF\x00\xFF\x00\xFF\x00\xFF\x00", 8));
  EXPECT_EQ(requestErrorOf(pinholeFields(), damaged).rfind(
                "image: damaged JPEG data, which the decoder would fill with garbage (libjpeg: Corrupt JPEG data: ", 0),
            0u)
      << requestErrorOf(pinholeFields(), damaged);
}

// An upload cut short was decoded with its missing rows grey (libjpeg only warned on stderr).
TEST(LocalizeRequest, AJpegCutShortIsRefused) {
  cv::Mat3b pixels(48, 64);
  cv::randu(pixels, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<uchar> encoded;
  ASSERT_TRUE(cv::imencode(".jpg", pixels, encoded));
  const std::string whole(encoded.begin(), encoded.end());
  EXPECT_EQ(requestErrorOf(pinholeFields(), whole), "");
  EXPECT_EQ(requestErrorOf(pinholeFields(), whole.substr(0, whole.size() * 2 / 3)),
            "image: a JPEG cut short: its compressed data ends before the end-of-image marker (a damaged or partial file)");
}

// Found by the localize_request fuzzer: a JPEG whose quantisation table lost a byte, so that the
// header walk met no marker where one should start and gave up, while libjpeg skips such bytes,
// finds a 12040x14895 frame and decodes it (540 MB, more than 10 s). And a JPEG whose EXIF
// segment made the header walk give up by design, bypassing the pixel limit the same way.
TEST(LocalizeRequest, OversizedJpegsAreRefusedFromTheHeaderWhateverPrecedesTheFrame) {
  static const char kDamagedTable[] =
    "\xff\xd8\xff\xe0\x00\x10\x4a\x46\x49\x46\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00\xff\xdb\x00\x43\x00\x02\x01\x01\x01\x01\x01\x02\x01\x01\x01\x02"
    "\x02\x02\x02\x02\x04\x03\x02\x02\x02\x02\x05\x04\x04\x03\x04\xcf\x06\x05\x06\x06\x06\x05\x06\x06\x06\x07\x09\x08\x06\x07\x09\x07\x06\x06\x08\x0b"
    "\x08\x09\x0a\x0a\x0a\x0a\x0a\x06\x08\x0b\x0c\x0b\x0a\x0c\x09\x0a\x0a\x0a\xff\xdb\x00\x43\x01\x02\x02\x02\x02\x02\x02\x05\x03\x03\x05\x0a\x07\x06"
    "\x07\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a"
    "\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\xff\xc0\x00\x11\x08\x3a\x2f\x2f\x08\x03\x01\x22\x00\x02\x11\x01\x03\x11\x01\xff\xc4"
    "\x00\x1f\x00\x00\x01\x05\x01\x01\x01\x01\x01\x01\x00\x00\x00\x00\x00\x00\x00\x00\x01\x02\x03\x04\x05\x06\x07\x08\x09\x0a\x0b\x81\x91\xa1\x08\x23"
    "\x42\x00\x00\x00\x00\x01\x02\x03\x04\x05\x06\x07\x08\x09\x0a\x0b\xff\xc4\x00\xb5\x11\x00\x02\x01\x02\x04\x04\x03\x04\x07\x05\x04\x04\x00\x01\x02"
    "\x77\x00\x01\x02\x03\x11\x04\x05\x21\x31\x06\x12\x41\x51\x07\x61\x71\x13\x22\x32\x81\x08\x14\x42\x91\xa1\xb1\xc1\x09\x23\x33\x52\xf0\x15\x62\x72"
    "\xd1\x0a\x16\x24\x34\xe1\x25\xf1\x17\x18\x19\x1a\x26\x27\x28\x29\x2a\x35\x36\x37\x38\x39\x3a\x43\x44\x45\x46\x47\x48\x49\x4a\x53\x54\x55\x56\x57"
    "\x58\x59\x5a\x63\x64\x65\x66\x67\x68\x69\x6a\x73\x74\x75\x76\x77\x78\x79\x7a\x82\x83\x84\x85\x86\x87\x88\x89\x8a\x92\x93\x94\x95\x96\x97\x98\x99"
    "\x9a\xa2\xa3\xa4\xa5\xa6\xa7\x04\x07\x05\x04\x04\x00\x01\x02\x77\x00\x01\xba\xc2\xc3\xc4\xc5\xc6\xc7\xc8\xc9\xca\xd2\xd3\xd4\xd5\xd6\xd7\xd8\xd9"
    "\xda\xe2\xe3\xe4\xe5\xe6\xe7\xe8\xe9\xea\xf2\xf3\xf4\xf5\xf6\xf7\xf8\xf9\xfa\xff\xda\x00\x0c\x03\x01\x00\x02\x11\x03\x11\x00\x3f\x00\xf4\x4a\x28"
    "\xa2\xbf\xcc\xf3\xf9\x7c\xff\xd9";
  const std::string damaged(kDamagedTable, sizeof(kDamagedTable) - 1);
  // From the header: before, the same answer came only after the decoder had allocated the frame.
  EXPECT_EQ(encodedFrameSize(damaged), cv::Size(12040, 14895));
  EXPECT_EQ(requestErrorOf(pinholeFields(), damaged).rfind("image: 12040x14895 is more than the 40000000 pixels", 0), 0u)
      << requestErrorOf(pinholeFields(), damaged);

  const std::string exif_then_frame = std::string("\xff\xd8\xff\xe1\x00\x08" "Exif\0\0\xff\xc0\x00\x11\x08\x27\x10\x27\x10", 21);
  EXPECT_EQ(requestErrorOf(pinholeFields(), exif_then_frame).rfind("image: 10000x10000 is more", 0), 0u)
      << requestErrorOf(pinholeFields(), exif_then_frame);
}

// A localizer the test owns, served without the catalog owning it.
ServedMap unownedMap(const Localizer& localizer, const std::string& model) {
  return {std::shared_ptr<const Localizer>(&localizer, [](const Localizer*) {}), model};
}

// The server against the library it fronts: a synthetic scene, a random tiny model (its pose is
// meaningless, but deterministic), every route and every refusal over real sockets.
class ServerTest : public ::testing::Test {
 protected:
  static constexpr int kLongSide = 256;

  static void SetUpTestSuite() {
    setTorchThreadCount(1);
    dir_ = new fs::path(testing::makeTempDir("ffloc_server"));
    SyntheticOptions synthetic;
    synthetic.seed = 5;
    synthetic.mapping_frames = 6;
    synthetic.query_frames = 1;
    scene_ = new Scene(generateSyntheticScene(synthetic, *dir_));
    model_ = new LoadedModel(loadModel("random:tiny:3"));
    MappingOptions mapping;
    mapping.quiet = true;
    mapping.long_side = kLongSide;
    MapFile map = emptyMap(*model_, true);
    std::vector<size_t> mapping_frames;
    for (size_t i = 0; i < scene_->frames.size(); ++i)
      if (scene_->frames[i].split == Split::kMapping) mapping_frames.push_back(i);
    addToMap(map, *model_, *scene_, mapping_frames, mapping);
    localizer_ = new FastForwardLocalizer(*model_->model, std::move(map));
    catalog_ = new MapCatalog("scene", unownedMap(*localizer_, "random tiny"));
  }

  static void TearDownTestSuite() {
    delete catalog_;
    delete localizer_;
    delete model_;
    delete scene_;
    fs::remove_all(*dir_);
    delete dir_;
  }

  void SetUp() override {
    options_.port = 0;
    options_.max_body_bytes = size_t{2} << 20;
    options_.max_waiting_queries = 2;
    options_.localize.top_k = 4;
    options_.localize.num_features = 300;
    options_.localize.long_side = kLongSide;
    server_ = std::make_unique<LocalizationServer>(*catalog_, options_);
    port_ = server_->bind();
    serving_ = std::thread([this] { server_->serve(); });
    client_ = std::make_unique<httplib::Client>("127.0.0.1", port_);
    client_->set_read_timeout(120);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (!client_->Get("/health") && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ASSERT_TRUE(client_->Get("/health")) << "the server did not answer within 20 s";
  }

  void TearDown() override {
    server_->stop();
    serving_.join();
  }

  const Frame& query() const {
    for (const Frame& frame : scene_->frames)
      if (frame.split == Split::kQuery) return frame;
    throw std::logic_error("no query");
  }

  std::string queryFileBytes() const {
    std::ifstream file(query().image_path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(file), {});
  }

  std::string intrinsicsParameters() const {
    const Intrinsics& k = query().intrinsics;
    char text[200];
    std::snprintf(text, sizeof(text), "fx=%.17g&fy=%.17g&cx=%.17g&cy=%.17g", k.fx, k.fy, k.cx, k.cy);
    return text;
  }

  static nlohmann::json body(const httplib::Result& result) { return nlohmann::json::parse(result->body); }

  static inline fs::path* dir_ = nullptr;
  static inline Scene* scene_ = nullptr;
  static inline LoadedModel* model_ = nullptr;
  static inline FastForwardLocalizer* localizer_ = nullptr;
  static inline MapCatalog* catalog_ = nullptr;
  ServerOptions options_;
  std::unique_ptr<LocalizationServer> server_;
  int port_ = 0;
  std::thread serving_;
  std::unique_ptr<httplib::Client> client_;
};

TEST_F(ServerTest, HealthAndMapDescribeWhatIsServed) {
  const auto health = client_->Get("/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  EXPECT_EQ(body(health)["status"], "ok");
  EXPECT_EQ(body(health)["maps"], 1);

  const auto maps = client_->Get("/maps");
  ASSERT_TRUE(maps);
  EXPECT_EQ(maps->status, 200);
  ASSERT_EQ(body(maps)["maps"].size(), 1u);
  EXPECT_EQ(body(maps)["maps"][0]["name"], "scene");
  EXPECT_EQ(body(maps)["maps"][0]["images"], 6);
  EXPECT_EQ(body(maps)["maps"][0]["method"], "fastforward");
  EXPECT_EQ(body(maps)["maps"][0]["model"], "random tiny");
  const auto named = client_->Get("/maps/scene");
  ASSERT_TRUE(named);
  EXPECT_EQ(named->status, 200);
  EXPECT_EQ(body(named)["images"], 6);

  const auto map = client_->Get("/map");
  ASSERT_TRUE(map);
  EXPECT_EQ(map->status, 200);
  EXPECT_EQ(body(map)["images"], 6);
  EXPECT_EQ(body(map)["names"][0], localizer_->cameras()[0].name);
  EXPECT_EQ(body(map)["model_id"], model_->id);
  EXPECT_EQ(body(map)["defaults"]["top_k"], 4);
  EXPECT_TRUE(body(map)["defaults"].contains("features"));  // a FastForward map reads N
}

TEST_F(ServerTest, LocalizeAnswersWhatTheLibraryComputes) {
  LocalizeOptions options = options_.localize;
  options.seed = options.pnp.seed = 9;
  const LocalizationResult direct =
      localizer_->localize(readImageRgb(query().image_path), query().intrinsics, query().name, options);
  const nlohmann::json expected = localizationJson("q", direct, *localizer_);
  // Deterministic: this seed's scene and model give a pose, so the answers' poses are compared.
  ASSERT_TRUE(direct.pnp.ok()) << toString(direct.pnp.status);

  const auto raw = client_->Post(("/localize?name=q&seed=9&" + intrinsicsParameters()).c_str(), queryFileBytes(),
                                 "image/png");
  ASSERT_TRUE(raw);
  ASSERT_EQ(raw->status, 200) << raw->body;
  const httplib::MultipartFormDataItems form = {{"image", queryFileBytes(), "query.png", "image/png"},
                                                {"name", "q", "", ""},
                                                {"seed", "9", "", ""}};
  const auto multipart = client_->Post(("/localize?" + intrinsicsParameters()).c_str(), form);
  ASSERT_TRUE(multipart);
  ASSERT_EQ(multipart->status, 200) << multipart->body;

  for (const nlohmann::json& answer : {body(raw), body(multipart)}) {
    EXPECT_EQ(answer["name"], "q");
    EXPECT_EQ(answer["status"], expected["status"]);
    EXPECT_EQ(answer["selected"], expected["selected"]);
    EXPECT_EQ(answer["inliers"], expected["inliers"]);
    EXPECT_EQ(answer["pnp_correspondences"], expected["pnp_correspondences"]);
    EXPECT_GT(answer["pnp_correspondences"].get<int>(), 0);
    ASSERT_TRUE(answer.contains("camera_to_world"));
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        EXPECT_NEAR(answer["camera_to_world"][r][c].get<double>(), expected["camera_to_world"][r][c].get<double>(), 1e-9);
    EXPECT_GT(answer["timings_ms"]["total"].get<double>(), 0);
  }
}

TEST_F(ServerTest, RequestsOverrideTheDefaults) {
  const auto answer = client_->Post(
      ("/localize?top_k=2&features=100&selection=uniform&" + intrinsicsParameters()).c_str(), queryFileBytes(),
      "image/png");
  ASSERT_TRUE(answer);
  ASSERT_EQ(answer->status, 200) << answer->body;
  LocalizeOptions options = options_.localize;
  options.top_k = 2;
  options.num_features = 100;
  options.selection = ImageSelection::kUniform;
  const LocalizationResult direct =
      localizer_->localize(readImageRgb(query().image_path), query().intrinsics, query().name, options);
  EXPECT_EQ(body(answer)["selected"].size(), 2u);
  EXPECT_EQ(body(answer)["selected"], localizationJson("q", direct, *localizer_)["selected"]);
  EXPECT_EQ(body(answer)["inliers"], direct.pnp.inliers);
}

// More simultaneous queries than may wait: the surplus is told to retry, the others answered,
// and /health answers meanwhile.
TEST_F(ServerTest, QueriesBeyondTheWaitingLimitAreBusy) {
  constexpr int kQueries = 6;  // one runs, max_waiting_queries (2) wait, 3 or more refused
  std::vector<int> statuses(kQueries, 0);
  std::vector<std::thread> senders;
  const std::string path = "/localize?" + intrinsicsParameters();
  const std::string image = queryFileBytes();
  for (int i = 0; i < kQueries; ++i) {
    senders.emplace_back([&, i] {
      httplib::Client client("127.0.0.1", port_);
      client.set_read_timeout(300);
      if (const auto reply = client.Post(path.c_str(), image, "image/png")) statuses[i] = reply->status;
    });
  }
  for (std::thread& sender : senders) sender.join();
  const auto busy = std::count(statuses.begin(), statuses.end(), 503);
  const auto answered = std::count(statuses.begin(), statuses.end(), 200);
  EXPECT_EQ(busy + answered, kQueries);
  EXPECT_GE(answered, 1);
  EXPECT_LE(answered, 1 + static_cast<long>(options_.max_waiting_queries));
  const auto health = client_->Get("/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
}

TEST_F(ServerTest, StopBeforeServeReturnsAtOnce) {
  ServerOptions options = options_;
  LocalizationServer early(*catalog_, options);
  early.bind();
  early.stop();
  std::thread serving([&] { early.serve(); });
  serving.join();  // hangs, and the test times out, if the early stop was lost
}

TEST_F(ServerTest, RefusalsAreJsonNamingTheCause) {
  const auto no_fx = client_->Post("/localize?fy=1&cx=1&cy=1", queryFileBytes(), "image/png");
  ASSERT_TRUE(no_fx);
  EXPECT_EQ(no_fx->status, 400);
  EXPECT_EQ(body(no_fx)["error"].get<std::string>().rfind("fx: missing", 0), 0u) << no_fx->body;

  // The library's 414 said only "HTTP 414".
  const auto long_path = client_->Get(("/maps/" + std::string(9000, 'a')).c_str());
  ASSERT_TRUE(long_path);
  EXPECT_EQ(long_path->status, 414);
  EXPECT_EQ(body(long_path)["error"], "URI too long: the path and query string are over the HTTP library's limit of 8 KiB");

  const auto garbage = client_->Post(("/localize?" + intrinsicsParameters()).c_str(), "%PDF-1.4", "image/png");
  ASSERT_TRUE(garbage);
  EXPECT_EQ(garbage->status, 400);
  EXPECT_EQ(body(garbage)["error"].get<std::string>().rfind("image:", 0), 0u) << garbage->body;

  // What curl --data-binary sends without -H, refused before the body is read, whatever its size:
  // past the library's 8 KiB form limit it was 413 "payload too large", which it is not. The
  // message says how to send an image instead.
  for (const size_t size : {100, 100000}) {
    const auto form_encoded = client_->Post(("/localize?" + intrinsicsParameters()).c_str(),
                                            std::string(queryFileBytes() + std::string(size, 'x')).substr(0, size),
                                            "application/x-www-form-urlencoded");
    ASSERT_TRUE(form_encoded);
    EXPECT_EQ(form_encoded->status, 400) << size << " bytes: " << form_encoded->body;
    const std::string error = body(form_encoded)["error"];
    EXPECT_EQ(error.rfind("Content-Type: the body is a URL-encoded form", 0), 0u) << error;
    EXPECT_NE(error.find("Content-Type: image/jpeg"), std::string::npos) << error;
  }

  const httplib::MultipartFormDataItems no_image = {{"fx", "100", "", ""}};
  const auto form = client_->Post("/localize", no_image);
  ASSERT_TRUE(form);
  EXPECT_EQ(form->status, 400);
  EXPECT_NE(body(form)["error"].get<std::string>().find("'image' part"), std::string::npos) << form->body;

  const auto twice = client_->Post(("/localize?seed=1&" + intrinsicsParameters()).c_str(),
                                   httplib::MultipartFormDataItems{{"image", queryFileBytes(), "q.png", "image/png"},
                                                                   {"seed", "2", "", ""}});
  ASSERT_TRUE(twice);
  EXPECT_EQ(twice->status, 400);
  EXPECT_EQ(body(twice)["error"].get<std::string>().rfind("seed:", 0), 0u) << twice->body;
  // The HTTP library merges a field given twice with one value into one: it passed.
  const auto same_twice = client_->Post(("/localize?seed=1&seed=1&" + intrinsicsParameters()).c_str(),
                                        queryFileBytes(), "image/png");
  ASSERT_TRUE(same_twice);
  EXPECT_EQ(same_twice->status, 400);
  EXPECT_EQ(body(same_twice)["error"], "seed: given more than once") << same_twice->body;

  // Text that is not UTF-8 is replaced in answers, not a failure.
  const auto not_utf8 = client_->Post(("/localize?name=%FF%FE&" + intrinsicsParameters()).c_str(), queryFileBytes(),
                                      "application/octet-stream");
  ASSERT_TRUE(not_utf8);
  EXPECT_EQ(not_utf8->status, 200) << not_utf8->body;
  EXPECT_EQ(body(not_utf8)["name"], "\xEF\xBF\xBD\xEF\xBF\xBD");
  const auto bad_field = client_->Post(("/localize?%FF=1&" + intrinsicsParameters()).c_str(), queryFileBytes(),
                                       "image/png");
  ASSERT_TRUE(bad_field);
  EXPECT_EQ(bad_field->status, 400);
  EXPECT_NE(body(bad_field)["error"].get<std::string>().find("unknown field"), std::string::npos);

  // A field with no name, fields joined by ';' (sent encoded), and a NUL byte that cut the
  // message quoting it short.
  for (const auto& [query, expected] : std::vector<std::pair<std::string, std::string>>{
           {"=5&", "a query field has no name ('=5')"},
           {"name=a;seed=2&", "name: 'name=a;seed=2' holds two '=': separate fields with '&' (not ';'), and write '=' "
                              "in a value as %3D"},
           {"seed=1%00&", "seed: expected an integer in [0, 9223372036854775807], got '1\\x00'"}}) {
    const auto refused = client_->Post(("/localize?" + query + intrinsicsParameters()).c_str(), queryFileBytes(),
                                       "image/png");
    ASSERT_TRUE(refused);
    EXPECT_EQ(refused->status, 400) << query;
    EXPECT_EQ(body(refused)["error"], expected) << refused->body;
  }

  const auto two_images = client_->Post(("/localize?" + intrinsicsParameters()).c_str(),
                                        httplib::MultipartFormDataItems{{"image", queryFileBytes(), "a.png", "image/png"},
                                                                        {"image", queryFileBytes(), "b.png", "image/png"}});
  ASSERT_TRUE(two_images);
  EXPECT_EQ(two_images->status, 400);
  EXPECT_EQ(body(two_images)["error"], "image: given more than once");

  // Chunked: no Content-Length, so the body limit could not hold; refused before reading. Sent
  // by hand, as a client sending a body the server does not read may fail before the answer.
  const std::string chunked = rawExchange(port_, "POST /localize?" + intrinsicsParameters() +
                                                     " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nTransfer-Encoding: chunked\r\n"
                                                     "Content-Type: image/png\r\n\r\n");
  EXPECT_EQ(chunked.rfind("HTTP/1.1 411", 0), 0u) << chunked;
  EXPECT_NE(chunked.find("Content-Length header"), std::string::npos) << chunked;

  // Headers that make the body's length ambiguous or its type not an image, refused before the
  // body is read.
  const auto exchange = [&](const std::string& headers) {
    return rawExchange(port_, "POST /localize?" + intrinsicsParameters() +
                                  " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n" + headers + "\r\n");
  };
  const std::string two_lengths = exchange("Content-Type: image/png\r\nContent-Length: 5\r\nContent-Length: 900\r\n");
  EXPECT_EQ(two_lengths.rfind("HTTP/1.1 400", 0), 0u) << two_lengths;
  EXPECT_NE(two_lengths.find("Content-Length: given more than once"), std::string::npos) << two_lengths;
  for (const std::string length : {"-5", "abc", "1e3"}) {
    const std::string bad = exchange("Content-Type: image/png\r\nContent-Length: " + length + "\r\n");
    EXPECT_EQ(bad.rfind("HTTP/1.1 400", 0), 0u) << length << ": " << bad;
    EXPECT_NE(bad.find("is not a byte count"), std::string::npos) << length << ": " << bad;
  }
  const std::string text = exchange("Content-Type: text/plain\r\nContent-Length: 4\r\n\r\nabcd");
  EXPECT_EQ(text.rfind("HTTP/1.1 415", 0), 0u) << text;
  EXPECT_NE(text.find("text/plain"), std::string::npos) << text;
  // A client that asks first is refused before it sends 100 MB, without a 100 Continue.
  const std::string asked =
      exchange("Content-Type: image/png\r\nContent-Length: 104857600\r\nExpect: 100-continue\r\n");
  EXPECT_EQ(asked.rfind("HTTP/1.1 413", 0), 0u) << asked;
  EXPECT_EQ(asked.find("100 Continue"), std::string::npos) << asked;

  const auto unknown = client_->Get("/localise");
  ASSERT_TRUE(unknown);
  EXPECT_EQ(unknown->status, 404);
  EXPECT_NE(body(unknown)["error"].get<std::string>().find("POST /localize"), std::string::npos);

  const auto too_large = client_->Post(("/localize?" + intrinsicsParameters()).c_str(),
                                       std::string(options_.max_body_bytes + 1, 'x'), "image/png");
  ASSERT_TRUE(too_large);
  EXPECT_EQ(too_large->status, 413);
  EXPECT_NE(body(too_large)["error"].get<std::string>().find("limit"), std::string::npos);

  // Still serving after every refusal.
  const auto health = client_->Get("/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
}

// The server fronts any Localizer: a classical map of the same scene answers what the library
// computes, says its method, and refuses intrinsics that do not fit the image.
TEST_F(ServerTest, ServesAClassicalMapAsTheLibraryLocalizesIt) {
  ClassicalMappingOptions mapping;
  mapping.quiet = true;
  ClassicalMap map = emptyClassicalMap(true, mapping);
  addToClassicalMap(map, *scene_, scene_->mappingIndices(), mapping);
  const ClassicalLocalizer classical(std::move(map));
  ServerOptions options = options_;
  const MapCatalog classical_catalog("classical", unownedMap(classical, "none"));
  LocalizationServer server(classical_catalog, options);
  const int port = server.bind();
  std::thread serving([&] { server.serve(); });
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(60);

  const auto described = client.Get("/map");
  ASSERT_TRUE(described);
  EXPECT_EQ(body(described)["method"], "classical");
  const LocalizationResult direct =
      classical.localize(readImageRgb(query().image_path), query().intrinsics, "q", options.localize);
  const auto answer = client.Post(("/localize?name=q&" + intrinsicsParameters()).c_str(), queryFileBytes(), "image/png");
  ASSERT_TRUE(answer);
  ASSERT_EQ(answer->status, 200) << answer->body;
  const nlohmann::json expected = localizationJson("q", direct, classical);
  EXPECT_EQ(body(answer)["method"], "classical");
  EXPECT_EQ(body(answer)["status"], expected["status"]);
  EXPECT_EQ(body(answer)["inliers"], expected["inliers"]);
  EXPECT_EQ(body(answer)["selected"], expected["selected"]);
  const auto outside = client.Post("/localize?fx=200&fy=200&cx=100000&cy=10", queryFileBytes(), "image/png");
  ASSERT_TRUE(outside);
  EXPECT_EQ(outside->status, 400);
  EXPECT_EQ(body(outside)["error"].get<std::string>().rfind("cx, cy:", 0), 0u);
  // FastForward's fields were ignored here without a word, where the CLI and Python refuse them.
  for (const std::string field : {"features=500", "selection=uniform"}) {
    const auto ignored =
        client.Post(("/localize?" + field + "&" + intrinsicsParameters()).c_str(), queryFileBytes(), "image/png");
    ASSERT_TRUE(ignored);
    EXPECT_EQ(ignored->status, 400) << field;
    EXPECT_EQ(body(ignored)["error"], field.substr(0, field.find('=')) +
                                          ": the map is a classical map, which does not use it");
  }
  // Media types are case-insensitive; two of them are refused as two lengths are.
  EXPECT_EQ(client.Post(("/localize?" + intrinsicsParameters()).c_str(), queryFileBytes(), "IMAGE/PNG")->status, 200);
  // The library parses a form only when its type is written in lower case: another spelling
  // passed, and the form was read as an image ("fx: missing").
  const auto mixed_form =
      client.Post("/localize", queryFileBytes(), "Multipart/Form-Data; boundary=xyz");
  ASSERT_TRUE(mixed_form);
  EXPECT_EQ(mixed_form->status, 415);
  EXPECT_NE(body(mixed_form)["error"].get<std::string>().find("in lower case"), std::string::npos) << mixed_form->body;
  // Nor after a parameter that follows the boundary: it was refused as a malformed request.
  const auto charset_form = client.Post("/localize", queryFileBytes(), "multipart/form-data; boundary=xyz; charset=utf-8");
  ASSERT_TRUE(charset_form);
  EXPECT_EQ(charset_form->status, 415);
  EXPECT_NE(body(charset_form)["error"].get<std::string>().find("put boundary=... last"), std::string::npos)
      << charset_form->body;
  const httplib::Headers two_types = {{"Content-Type", "image/png"}, {"Content-Type", "text/plain"}};
  const auto twice = client.Post(("/localize?" + intrinsicsParameters()).c_str(), two_types, queryFileBytes(), "");
  ASSERT_TRUE(twice);
  EXPECT_EQ(twice->status, 400);
  EXPECT_EQ(body(twice)["error"], "Content-Type: given more than once");
  server.stop();
  serving.join();
}

// PUT /localize was read as a form and answered 413 "payload too large"; GET /localize and
// DELETE /map were 404, as if the route did not exist.
TEST_F(ServerTest, AMethodTheRouteDoesNotAnswerIs405NamingTheMethodsItDoes) {
  const std::string image = queryFileBytes() + std::string(100000, 'x');
  const auto put = client_->Put(("/localize?" + intrinsicsParameters()).c_str(), image,
                                "application/x-www-form-urlencoded");
  ASSERT_TRUE(put);
  EXPECT_EQ(put->status, 405) << put->body;
  EXPECT_EQ(put->get_header_value("Allow"), "POST");
  EXPECT_EQ(body(put)["error"], "method not allowed: PUT /localize; this route answers POST");
  const auto get = client_->Get("/maps/scene/localize");
  ASSERT_TRUE(get);
  EXPECT_EQ(get->status, 405) << get->body;
  EXPECT_EQ(get->get_header_value("Allow"), "POST");
  const auto remove = client_->Delete("/map");
  ASSERT_TRUE(remove);
  EXPECT_EQ(remove->status, 405) << remove->body;
  EXPECT_EQ(remove->get_header_value("Allow"), "GET, HEAD");
  EXPECT_EQ(body(remove)["error"], "method not allowed: DELETE /map; this route answers GET, HEAD");
  // No route at all stays 404, whatever the method, and its body is not read either.
  const auto nowhere = client_->Put("/nowhere", image, "application/x-www-form-urlencoded");
  ASSERT_TRUE(nowhere);
  EXPECT_EQ(nowhere->status, 404) << nowhere->body;
  EXPECT_EQ(body(nowhere)["error"].get<std::string>().rfind("not found: PUT /nowhere", 0), 0u) << nowhere->body;
  const auto head = client_->Head("/health");
  ASSERT_TRUE(head);
  EXPECT_EQ(head->status, 200);
}

// cpp-httplib decodes the whole path before routing, so an encoded slash split its segment:
// GET /maps/scene%2Fscene answered the scene of map 'scene' and POST /maps/scene%2Flocalize
// localized against it. The slash stays in its segment: in a map's name it names a map that
// cannot exist (names hold no '/'), elsewhere a path no route serves.
TEST_F(ServerTest, AnEncodedSlashStaysInsideItsSegment) {
  const auto expectNoSuchMap = [](const httplib::Result& answer, const std::string& name) {
    ASSERT_TRUE(answer);
    EXPECT_EQ(answer->status, 404) << answer->body;
    EXPECT_EQ(body(answer)["error"], "map '" + name + "': no such map (map names hold no '/'; GET /maps lists them)");
  };
  expectNoSuchMap(client_->Get("/maps/scene%2Fscene"), "scene/scene");
  expectNoSuchMap(client_->Get("/maps/scene%2fscene"), "scene/scene");
  expectNoSuchMap(client_->Get("/maps/scene%u002Fscene"), "scene/scene");  // the library's %uXXXX
  expectNoSuchMap(client_->Post(("/maps/scene%2Flocalize?" + intrinsicsParameters()).c_str(), queryFileBytes(),
                                "image/png"),
                  "scene/localize");
  expectNoSuchMap(client_->Post(("/maps/a%2Fb/localize?" + intrinsicsParameters()).c_str(), queryFileBytes(),
                                "image/png"),
                  "a/b");
  const auto nowhere = client_->Get("/maps%2Fscene");
  ASSERT_TRUE(nowhere);
  EXPECT_EQ(nowhere->status, 404) << nowhere->body;
  EXPECT_EQ(body(nowhere)["error"].get<std::string>().rfind("not found: GET /maps%2Fscene (known:", 0), 0u)
      << nowhere->body;
  // Other escapes are decoded as before, and an escaped '%' is not a slash.
  const auto escaped = client_->Get("/maps/sc%65ne/scene");
  ASSERT_TRUE(escaped);
  EXPECT_EQ(escaped->status, 200) << escaped->body;
  const auto percent = client_->Get("/maps/scene%252Fscene");
  ASSERT_TRUE(percent);
  EXPECT_EQ(percent->status, 404) << percent->body;
  EXPECT_EQ(body(percent)["error"], "map 'scene%2Fscene': no such map (GET /maps lists them)");
}

// A server over `catalog` that logs to a string, serving on its own thread until stopped.
class LoggingServer {
 public:
  LoggingServer(const MapCatalog& catalog, const ServerOptions& options)
      : server_(catalog, logTo(options, &log_)), port_(server_.bind()), serving_([this] { server_.serve(); }) {}
  ~LoggingServer() {
    if (serving_.joinable()) stopAndReadLog();
  }
  int port() const { return port_; }
  // The log with each line's UTC time and client address taken off; a line without them is kept
  // whole, so that the test comparing it fails.
  std::string stopAndReadLog() {
    server_.stop();
    serving_.join();
    static const std::regex time_and_client(R"((^|\n)20[0-9]{2}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}:[0-9]{2}\.[0-9]{3}Z 127\.0\.0\.1 )");
    return std::regex_replace(log_.str(), time_and_client, "$1");
  }

 private:
  static ServerOptions logTo(ServerOptions options, std::ostream* log) {
    options.log = log;
    return options;
  }
  std::ostringstream log_;
  LocalizationServer server_;
  const int port_;
  std::thread serving_;
};

// The body of a request refused before it is read was left in the socket, and the kept-alive
// connection read it as the next requests: a PNG logged as a dozen malformed ones.
TEST_F(ServerTest, ARefusedBodyIsNotReadAsTheNextRequest) {
  LoggingServer server(*catalog_, options_);
  const std::string body = "\r\n\r\nGET /health HTTP/1.1\r\nHost: x\r\n\r\n" + std::string(5000, 'x');
  const std::string answer =
      rawExchange(server.port(), "PUT /localize HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: image/png\r\n"
                                 "Content-Length: " + std::to_string(body.size()) + "\r\n\r\n" + body);
  const std::string log = server.stopAndReadLog();
  EXPECT_EQ(answer.rfind("HTTP/1.1 405", 0), 0u) << answer;
  EXPECT_NE(answer.find("Connection: close"), std::string::npos) << answer;
  EXPECT_EQ(answer.find("HTTP/1.1", 1), std::string::npos) << "answered more than one request: " << answer;
  EXPECT_EQ(log, "PUT /localize 405 method not allowed: PUT /localize; this route answers POST\n");
}

// The library reads no body of a GET: one sent was parsed as the next request, so a GET /health
// carrying "GET /maps/NAME/scene" got both answers, which a proxy in front would hand to
// another client (request smuggling; found by an outside probe). A field name with a space was
// dropped, where a lenient proxy may read it as the header it spells.
TEST_F(ServerTest, AGetWithABodyOrASpacedFieldNameIsRefusedAndNothingHiddenRuns) {
  LoggingServer server(*catalog_, options_);
  const std::string hidden = "GET /map HTTP/1.1\r\nHost: x\r\n\r\n";
  const std::string answer = rawExchange(server.port(), "GET /health HTTP/1.1\r\nHost: x\r\nContent-Length: " +
                                                            std::to_string(hidden.size()) + "\r\n\r\n" + hidden);
  // A chunked GET was told to send a Content-Length; a length of "00" is none.
  const std::string chunked_get = rawExchange(server.port(), "GET /health HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: "
                                                               "chunked\r\n\r\n0\r\n\r\n");
  EXPECT_NE(chunked_get.find("a GET request carries no body; this one announced a chunked one"), std::string::npos)
      << chunked_get;
  EXPECT_EQ(rawExchange(server.port(), "GET /health HTTP/1.1\r\nHost: x\r\nContent-Length: 00\r\nConnection: close\r\n\r\n")
                .rfind("HTTP/1.1 200", 0),
            0u);
  // A field name with a space, which a lenient proxy may read as Transfer-Encoding.
  const std::string spaced = rawExchange(server.port(), "POST /localize HTTP/1.1\r\nHost: x\r\nTransfer-Encoding : "
                                                          "chunked\r\nContent-Length: 5\r\n\r\nhello");
  EXPECT_EQ(spaced.rfind("HTTP/1.1 400", 0), 0u) << spaced;
  EXPECT_NE(spaced.find("header 'Transfer-Encoding ': whitespace in a field name"), std::string::npos) << spaced;
  const std::string log = server.stopAndReadLog();
  EXPECT_EQ(answer.rfind("HTTP/1.1 400", 0), 0u) << answer;
  EXPECT_NE(answer.find("a GET request carries no body; this one announced " + std::to_string(hidden.size()) + " bytes"),
            std::string::npos)
      << answer;
  EXPECT_EQ(answer.find("HTTP/1.1", 1), std::string::npos) << "answered more than one request: " << answer;
  EXPECT_EQ(log.find("/map "), std::string::npos) << log;
}

// A client's name or path was logged as sent: a newline in it wrote a forged log line, a NUL a
// raw NUL, and a 5000-byte name 5000 bytes. The answer's JSON was, and is, escaped.
TEST_F(ServerTest, TheLogHoldsOneLineARequestWithControlCharactersEscapedAndLongNamesCut) {
  LoggingServer server(*catalog_, options_);
  httplib::Client client("127.0.0.1", server.port());
  client.set_read_timeout(120);
  const std::string forged = "x%0APOST%20/maps/f/localize%20200%20q%20localized%209999%20inliers%0D%00%09%7F%1B%5C";
  const auto named = client.Post(("/localize?name=" + forged + "&" + intrinsicsParameters()).c_str(), queryFileBytes(),
                                 "image/png");
  ASSERT_TRUE(named);
  EXPECT_EQ(named->status, 200) << named->body;
  EXPECT_EQ(body(named)["name"], std::string("x\nPOST /maps/f/localize 200 q localized 9999 inliers\r") + '\0' + "\t\x7f\x1b\\");
  const auto long_name = client.Post(("/localize?name=" + std::string(5000, 'n') + "&" + intrinsicsParameters()).c_str(),
                                     queryFileBytes(), "image/png");
  ASSERT_TRUE(long_name);
  EXPECT_EQ(long_name->status, 200) << long_name->body;
  const auto path = client.Get("/x%0Aforged%20line%00");
  ASSERT_TRUE(path);
  EXPECT_EQ(path->status, 404);
  const std::string log = server.stopAndReadLog();

  std::vector<std::string> lines;
  std::istringstream text(log);
  for (std::string line; std::getline(text, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 3u) << log;
  EXPECT_EQ(lines[0].rfind("POST /localize 200 x\\nPOST /maps/f/localize 200 q localized 9999 inliers\\r\\x00\\t\\x7f\\x1b\\ ", 0),
            0u)
      << lines[0];
  EXPECT_EQ(lines[1].rfind("POST /localize 200 " + std::string(200, 'n') + "... (5000 bytes, cut) ", 0), 0u) << lines[1];
  EXPECT_EQ(lines[2].rfind("GET /x\\nforged line\\x00 404 not found: GET /x\\nforged line\\x00 (known:", 0), 0u) << lines[2];
  for (const std::string& line : lines)
    for (const char c : line) EXPECT_TRUE(static_cast<unsigned char>(c) >= 0x20 && c != 0x7F) << line;
}

TEST_F(ServerTest, SecondServerOnTheSamePortIsAnInputError) {
  ServerOptions taken = options_;
  taken.port = port_;
  LocalizationServer second(*catalog_, taken);
  try {
    second.bind();
    FAIL() << "bound a port already in use";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("port " + std::to_string(port_)), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ffloc
