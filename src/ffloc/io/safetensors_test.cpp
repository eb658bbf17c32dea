#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <sys/stat.h>
#include <unistd.h>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/io/half.h"
#include "ffloc/io/tensor_archive.h"

namespace ffloc {
namespace {

template <typename T>
std::vector<T> elements(const TensorView& view) {
  std::vector<T> values(view.nbytes / sizeof(T));
  if (!values.empty()) std::memcpy(values.data(), view.data, view.nbytes);
  return values;
}

TEST(Safetensors, ReadsTinyModel) {
  FFLOC_REQUIRE_SHARED(path, "fixtures/dust3r/tiny_model.safetensors");
  const auto archive = openSafetensors(path);
  EXPECT_EQ(archive->names().size(), 653u);
  EXPECT_EQ(archive->metadata().at("format"), "pt");
  // The fixture stores tensors in name order, so data order equals name order.
  std::vector<std::string> sorted = archive->names();
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(archive->names(), sorted);

  const TensorView& conv = archive->at("patch_embed.proj.weight");
  EXPECT_EQ(conv.dtype, DType::kF32);
  EXPECT_EQ(conv.shape, (std::vector<int64_t>{64, 3, 16, 16}));
  EXPECT_EQ(conv.shapeString(), "(64, 3, 16, 16)");
  EXPECT_EQ(conv.nbytes, 64u * 3 * 16 * 16 * 4);
  EXPECT_TRUE(archive->contains("downstream_head1.dpt.scratch.layer1_rn.weight"));
  EXPECT_FALSE(archive->contains("downstream_head1.dpt.scratch.layer_rn.0.weight"));

  // LayerNorm weights were drawn from U(0.6, 1.4): a wrong offset would show garbage here.
  for (float value : toFloat32(archive->at("enc_norm.weight"))) {
    EXPECT_GE(value, 0.6f);
    EXPECT_LE(value, 1.4f);
  }
  try {
    archive->at("no.such.tensor");
    FAIL() << "expected InputError";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find("tiny_model.safetensors"), std::string::npos);
    EXPECT_NE(std::string(error.what()).find("no.such.tensor"), std::string::npos);
  }
}

// A tensor "x" of the one float `value`, which must outlive it.
TensorView oneFloat(const float& value) {
  TensorView x;
  x.name = "x";
  x.dtype = DType::kF32;
  x.shape = {1};
  x.data = reinterpret_cast<const uint8_t*>(&value);
  x.nbytes = sizeof(value);
  return x;
}

// A writer killed while saving (Ctrl-C during `ffloc map`) leaves its temporary file; the next
// write to the same target removes those of processes that no longer run, and no other.
TEST(Safetensors, AbandonedTemporaryFilesAreRemovedByTheNextWrite) {
  const auto dir = testing::makeTempDir("ffloc-safetensors");
  const auto path = dir / "m.safetensors";
  const auto abandoned = dir / ".m.safetensors.999999999.0.tmp";  // beyond any pid_max
  const auto live = dir / (".m.safetensors." + std::to_string(::getpid()) + ".7.tmp");
  const auto other = dir / ".n.safetensors.999999999.0.tmp";
  const auto of_a_longer_name = dir / ".m.safetensors.5.999999998.0.tmp";  // a temporary of "m.safetensors.5"
  for (const auto& file : {abandoned, live, other, of_a_longer_name}) std::ofstream(file) << "partial";
  const float value = 1;
  writeSafetensors(path, {oneFloat(value)}, {});
  EXPECT_FALSE(std::filesystem::exists(abandoned));
  EXPECT_TRUE(std::filesystem::exists(live));
  EXPECT_TRUE(std::filesystem::exists(other));
  EXPECT_TRUE(std::filesystem::exists(of_a_longer_name));
  EXPECT_TRUE(std::filesystem::exists(path));
}

// `ffloc convert --output /dev/null` renamed the file over the device; through a link the link
// itself was replaced and what it named kept its old contents.
TEST(Safetensors, WritesThroughLinksAndNeverOverADeviceOrFifo) {
  const auto dir = testing::makeTempDir("ffloc-safetensors-targets");
  const float value = 2;
  const TensorView x = oneFloat(value);
  const auto fifo = dir / "fifo.safetensors";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  try {
    writeSafetensors(fifo, {x});
    FAIL() << "wrote over a FIFO";
  } catch (const InputError& error) {
    EXPECT_NE(std::string(error.what()).find(fifo.string() + ": exists and is not a regular file"), std::string::npos)
        << error.what();
  }
  EXPECT_TRUE(std::filesystem::is_fifo(fifo));
  const auto real = dir / "real.safetensors", link = dir / "link.safetensors";
  std::ofstream(real) << "old";
  std::filesystem::create_symlink("real.safetensors", link);
  writeSafetensors(link, {x});
  EXPECT_TRUE(std::filesystem::is_symlink(link));
  EXPECT_EQ(toFloat32(openSafetensors(real)->at("x")), std::vector<float>{2});
}

TEST(Safetensors, ReadsIntegerAndByteTensors) {
  FFLOC_REQUIRE_SHARED(path, "fixtures/dust3r/case_encoder_single.safetensors");
  const auto archive = openTensorArchive(path);
  EXPECT_EQ(archive->metadata().count("case"), 1u);

  const TensorView& true_shape = archive->at("view1.true_shape");
  EXPECT_EQ(true_shape.dtype, DType::kI32);
  EXPECT_EQ(elements<int32_t>(true_shape), (std::vector<int32_t>{80, 48}));

  // (y, x) patch coordinates, row-major over a 5x3 grid.
  const TensorView& pos = archive->at("view1.patch_embed.pos");
  EXPECT_EQ(pos.dtype, DType::kI64);
  const std::vector<int64_t> coordinates = elements<int64_t>(pos);
  ASSERT_EQ(coordinates.size(), 30u);
  for (int64_t n = 0; n < 15; ++n) {
    EXPECT_EQ(coordinates[2 * n], n / 3);
    EXPECT_EQ(coordinates[2 * n + 1], n % 3);
  }

  // img = (u8 / 255 - 0.5) / 0.5 with HWC u8 and NCHW float.
  const TensorView& pixels = archive->at("view1.img_uint8");
  EXPECT_EQ(pixels.dtype, DType::kU8);
  EXPECT_EQ(pixels.shape, (std::vector<int64_t>{80, 48, 3}));
  const std::vector<float> normalised = toFloat32(archive->at("view1.img"));
  for (int y = 0; y < 80; y += 7) {
    for (int x = 0; x < 48; x += 5) {
      for (int c = 0; c < 3; ++c) {
        const float expected = (pixels.data[(y * 48 + x) * 3 + c] / 255.0f - 0.5f) / 0.5f;
        EXPECT_NEAR(normalised[(c * 80 + y) * 48 + x], expected, 1e-6);
      }
    }
  }
}

TEST(Safetensors, RoundTripsEveryDtypeAndMetadata) {
  const auto dir = testing::makeTempDir("ffloc-safetensors");
  const std::vector<float> f32 = {1.5f, -2.25f, 3.0f, 0.0f, 1e-8f, -7.0f};
  const std::vector<uint16_t> f16 = {floatToHalf(1.0f), floatToHalf(-0.5f), floatToHalf(65504.0f)};
  const std::vector<uint16_t> bf16 = {floatToBfloat16(3.0f), floatToBfloat16(-1e30f)};
  const std::vector<int64_t> i64 = {-1, 1ll << 40, 7};
  const std::vector<uint8_t> u8 = {0, 127, 255};
  const std::vector<uint8_t> boolean = {1, 0};
  const double f64 = 2.5;
  auto view = [](std::string name, DType dtype, std::vector<int64_t> shape, const void* data,
                 size_t nbytes) {
    TensorView v;
    v.name = std::move(name);
    v.dtype = dtype;
    v.shape = std::move(shape);
    v.data = static_cast<const uint8_t*>(data);
    v.nbytes = nbytes;
    return v;
  };
  // Deliberately not in name order: the writer keeps the given order.
  const std::vector<TensorView> tensors = {
      view("z.f32", DType::kF32, {2, 3}, f32.data(), 24),
      view("a.f16", DType::kF16, {3}, f16.data(), 6),
      view("m.bf16", DType::kBF16, {1, 2}, bf16.data(), 4),
      view("i64", DType::kI64, {3}, i64.data(), 24),
      view("u8", DType::kU8, {3}, u8.data(), 3),
      view("flag", DType::kBool, {2}, boolean.data(), 2),
      view("scalar", DType::kF64, {}, &f64, 8),
      view("empty", DType::kF32, {0, 4}, nullptr, 0),
  };
  const auto path = dir / "round_trip.safetensors";
  size_t progress_calls = 0;
  writeSafetensors(path, tensors, {{"format", "pt"}, {"note", "with \"quotes\" and ünïcode"}},
                   [&](size_t written) { progress_calls = written; });
  EXPECT_EQ(progress_calls, tensors.size());
  // Only the target remains: the temporary file was renamed into place.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), {}), 1);

  std::ifstream raw(path, std::ios::binary);
  uint64_t header_size = 0;
  raw.read(reinterpret_cast<char*>(&header_size), 8);
  EXPECT_EQ(header_size % 8, 0u);

  const auto archive = openSafetensors(path);
  EXPECT_EQ(archive->metadata().at("note"), "with \"quotes\" and ünïcode");
  ASSERT_EQ(archive->names().size(), tensors.size());
  for (size_t i = 0; i < tensors.size(); ++i) {
    const TensorView& read = archive->at(tensors[i].name);
    EXPECT_EQ(archive->names()[i], tensors[i].name);
    EXPECT_EQ(read.dtype, tensors[i].dtype);
    EXPECT_EQ(read.shape, tensors[i].shape);
    ASSERT_EQ(read.nbytes, tensors[i].nbytes);
    if (read.nbytes > 0) EXPECT_EQ(std::memcmp(read.data, tensors[i].data, read.nbytes), 0);
  }
  EXPECT_EQ(toFloat32(archive->at("a.f16")), (std::vector<float>{1.0f, -0.5f, 65504.0f}));
  EXPECT_EQ(toFloat32(archive->at("scalar")), (std::vector<float>{2.5f}));

  // Overwriting keeps the file valid and replaces it whole.
  writeSafetensors(path, {tensors[0]});
  EXPECT_EQ(openSafetensors(path)->names(), (std::vector<std::string>{"z.f32"}));
  std::filesystem::remove_all(dir);
}

TEST(Safetensors, WriterRejectsInconsistentViews) {
  const auto dir = testing::makeTempDir("ffloc-safetensors-write");
  const std::vector<float> data(4, 1.0f);
  TensorView good;
  good.name = "x";
  good.shape = {4};
  good.data = reinterpret_cast<const uint8_t*>(data.data());
  good.nbytes = 16;
  TensorView short_view = good;
  short_view.nbytes = 12;
  const auto path = dir / "out.safetensors";
  EXPECT_THROW(writeSafetensors(path, {good, good}), InputError);
  EXPECT_THROW(writeSafetensors(path, {short_view}), InputError);
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), {}), 0);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace ffloc
