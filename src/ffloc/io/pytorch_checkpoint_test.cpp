#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "ffloc/core/error.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/io/pickle.h"
#include "ffloc/io/tensor_archive.h"
#include "ffloc/io/testing/torch_save_writer.h"
#include "ffloc/io/zip_reader.h"

namespace ffloc {
namespace {

using testing::makeZip;
using testing::PickleWriter;
using testing::ZipMember;

std::string floatBytes(const std::vector<float>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * 4);
}

void writeFile(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::vector<float> floats(const TensorView& view) {
  std::vector<float> values(view.nbytes / 4);
  std::memcpy(values.data(), view.data, view.nbytes);
  return values;
}

// A plain state dict (no "model" wrapper) exercising storage offsets, a transposed view, an
// alias, a half tensor and a non-tensor entry.
std::string plainStateDictPickle() {
  PickleWriter pickle;
  pickle.global("collections", "OrderedDict");
  pickle.op(')');
  pickle.op('R');
  pickle.op('(');
  pickle.text("a");
  pickle.tensor("FloatStorage", "0", 8, 2, {2, 3}, {3, 1});
  pickle.text("b.t");
  pickle.tensor("FloatStorage", "0", 8, 0, {3, 2}, {1, 3});
  pickle.text("h");
  pickle.tensor("HalfStorage", "1", 2, 0, {2}, {1});
  pickle.text("alias");
  pickle.tensor("FloatStorage", "0", 8, 2, {2, 3}, {3, 1});
  pickle.text("epoch");
  pickle.integer(7);
  pickle.op('u');
  return pickle.finish();
}

std::vector<ZipMember> plainMembers(const std::string& pickle) {
  const std::string half("\x00\x3c\x00\xc0", 4);  // 1.0, -2.0
  return {{"archive/data.pkl", pickle},
          {"archive/data/0", floatBytes({0, 1, 2, 3, 4, 5, 6, 7})},
          {"archive/data/1", half},
          {"archive/version", "3\n"}};
}

std::string messageOf(const std::function<void()>& action) {
  try {
    action();
  } catch (const InputError& error) {
    return error.what();
  }
  return "(no InputError)";
}

TEST(PytorchCheckpoint, ReadsTinyModelLikeItsSafetensors) {
  FFLOC_REQUIRE_SHARED(pth, "fixtures/dust3r/tiny_model.pth");
  FFLOC_REQUIRE_SHARED(safetensors, "fixtures/dust3r/tiny_model.safetensors");
  FFLOC_REQUIRE_SHARED(config_path, "fixtures/dust3r/tiny_config.json");
  const auto checkpoint = openTensorArchive(pth);
  const auto reference = openTensorArchive(safetensors);
  EXPECT_TRUE(checkpoint->metadata().empty());

  // Names, order, shapes and dtypes as the state_dict listed them.
  // Python's json writes -inf (in the constructor arguments) as -Infinity, which is not JSON.
  std::ifstream config_file(config_path);
  std::string config_text((std::istreambuf_iterator<char>(config_file)), std::istreambuf_iterator<char>());
  for (size_t at; (at = config_text.find("Infinity")) != std::string::npos;) {
    config_text.replace(at, 8, "0");
  }
  const nlohmann::json config = nlohmann::json::parse(config_text);
  const auto& keys = config.at("keys");
  ASSERT_EQ(checkpoint->names().size(), 661u);
  ASSERT_EQ(keys.size(), 661u);
  for (size_t i = 0; i < keys.size(); ++i) {
    ASSERT_EQ(checkpoint->names()[i], keys[i].at("name").get<std::string>());
    const TensorView& view = checkpoint->at(checkpoint->names()[i]);
    EXPECT_EQ(view.shape, keys[i].at("shape").get<std::vector<int64_t>>()) << view.name;
    EXPECT_EQ(view.dtype, DType::kF32);
  }

  size_t compared = 0;
  for (const std::string& name : reference->names()) {
    const TensorView& expected = reference->at(name);
    const TensorView& actual = checkpoint->at(name);
    EXPECT_EQ(actual.shape, expected.shape) << name;
    ASSERT_EQ(actual.nbytes, expected.nbytes) << name;
    EXPECT_EQ(std::memcmp(actual.data, expected.data, actual.nbytes), 0) << name;
    ++compared;
  }
  EXPECT_EQ(compared, 653u);

  // Aliases are the same storage, hence the same bytes at the same address.
  for (const auto& group : config.at("alias_groups")) {
    const TensorView& first = checkpoint->at(group.at(0).get<std::string>());
    const TensorView& second = checkpoint->at(group.at(1).get<std::string>());
    EXPECT_EQ(first.data, second.data);
    EXPECT_EQ(first.nbytes, second.nbytes);
  }
}

TEST(PytorchCheckpoint, ReadsPlainStateDictsWithViewsAndZip64) {
  const auto dir = testing::makeTempDir("ffloc-pth");
  for (bool zip64 : {false, true}) {
    const auto path = dir / (zip64 ? "zip64.pth" : "plain.pth");
    writeFile(path, makeZip(plainMembers(plainStateDictPickle()), zip64));
    const auto archive = openPytorchCheckpoint(path);
    EXPECT_EQ(archive->names(), (std::vector<std::string>{"a", "b.t", "h", "alias"}));
    EXPECT_EQ(floats(archive->at("a")), (std::vector<float>{2, 3, 4, 5, 6, 7}));
    // The transposed view is gathered into C order.
    EXPECT_EQ(archive->at("b.t").shape, (std::vector<int64_t>{3, 2}));
    EXPECT_EQ(floats(archive->at("b.t")), (std::vector<float>{0, 3, 1, 4, 2, 5}));
    EXPECT_EQ(archive->at("alias").data, archive->at("a").data);
    EXPECT_EQ(archive->at("h").dtype, DType::kF16);
    EXPECT_EQ(archive->at("h").nbytes, 4u);
    EXPECT_FALSE(archive->contains("epoch"));
  }
  std::filesystem::remove_all(dir);
}

TEST(PytorchCheckpoint, ReadsParametersAndWrappedStateDicts) {
  PickleWriter pickle;
  pickle.op('}');
  pickle.text("state_dict");
  pickle.op('}');
  pickle.text("w");
  pickle.global("torch._utils", "_rebuild_parameter");
  pickle.op('(');
  pickle.tensor("FloatStorage", "0", 8, 0, {8}, {1});
  pickle.op('\x88');
  pickle.global("collections", "OrderedDict");
  pickle.op(')');
  pickle.op('R');
  pickle.op('t');
  pickle.op('R');
  pickle.op('s');
  pickle.op('s');
  const auto dir = testing::makeTempDir("ffloc-pth-param");
  const auto path = dir / "param.pth";
  writeFile(path, makeZip(plainMembers(pickle.finish()), false));
  const auto archive = openTensorArchive(path);
  EXPECT_EQ(archive->names(), (std::vector<std::string>{"w"}));
  EXPECT_EQ(floats(archive->at("w")), (std::vector<float>{0, 1, 2, 3, 4, 5, 6, 7}));
  std::filesystem::remove_all(dir);
}

TEST(PytorchCheckpoint, DamagedCheckpointsRaiseInputErrorNamingTheProblem) {
  const auto dir = testing::makeTempDir("ffloc-pth-errors");
  const auto path = dir / "bad.pth";
  auto openWith = [&](const std::vector<ZipMember>& members) {
    writeFile(path, makeZip(members, false));
    return messageOf([&] { openPytorchCheckpoint(path); });
  };
  const std::string good = plainStateDictPickle();
  auto contains = [](const std::string& message, const std::string& part) {
    return message.find(part) != std::string::npos;
  };

  std::vector<ZipMember> members = plainMembers(good);
  members.erase(members.begin() + 1);
  std::string message = openWith(members);
  EXPECT_TRUE(contains(message, "bad.pth") && contains(message, "archive/data/0")) << message;

  members = plainMembers(good);
  members[1].data.resize(12);  // storage shorter than its numel
  message = openWith(members);
  EXPECT_TRUE(contains(message, "tensor 'a'") && contains(message, "fewer than 8")) << message;

  PickleWriter out_of_bounds;
  out_of_bounds.op('}');
  out_of_bounds.text("x");
  out_of_bounds.tensor("FloatStorage", "0", 8, 4, {2, 3}, {3, 1});
  out_of_bounds.op('s');
  message = openWith(plainMembers(out_of_bounds.finish()));
  EXPECT_TRUE(contains(message, "tensor 'x'") && contains(message, "reaches element 9")) << message;

  PickleWriter complex_storage;
  complex_storage.op('}');
  complex_storage.text("c");
  complex_storage.tensor("ComplexFloatStorage", "0", 1, 0, {1}, {1});
  complex_storage.op('s');
  message = openWith(plainMembers(complex_storage.finish()));
  EXPECT_TRUE(contains(message, "unsupported storage type torch.ComplexFloatStorage")) << message;

  std::string unknown_opcode = good;
  unknown_opcode.insert(2, "\xff");
  message = openWith(plainMembers(unknown_opcode));
  EXPECT_TRUE(contains(message, "archive/data.pkl") && contains(message, "opcode 0xff") &&
              contains(message, "offset 2"))
      << message;

  message = openWith(plainMembers(good.substr(0, good.size() / 2)));
  EXPECT_TRUE(contains(message, "archive/data.pkl: pickle offset")) << message;

  message = openWith(plainMembers(std::string("\x80\x02h\x05.", 5)));
  EXPECT_TRUE(contains(message, "memo key 5")) << message;

  message = openWith(plainMembers(std::string("\x80\x02K\x01.", 5)));
  EXPECT_TRUE(contains(message, "not a dict")) << message;

  members = plainMembers(good);
  members[1].method = 8;
  message = openWith(members);
  EXPECT_TRUE(contains(message, "compressed")) << message;

  members = plainMembers(good);
  members.push_back({"archive/byteorder", "big"});
  message = openWith(members);
  EXPECT_TRUE(contains(message, "byteorder")) << message;

  members = plainMembers(good);
  members[0].name = "archive/other.pkl";
  message = openWith(members);
  EXPECT_TRUE(contains(message, "no data.pkl")) << message;

  const std::string zip = makeZip(plainMembers(good), false);
  writeFile(path, zip.substr(0, zip.size() - 30));
  message = messageOf([&] { openTensorArchive(path); });
  EXPECT_TRUE(contains(message, "bad.pth") && contains(message, "end-of-central-directory")) << message;
  std::filesystem::remove_all(dir);
}

TEST(PytorchCheckpoint, TruncatedFixtureRaisesInputError) {
  FFLOC_REQUIRE_SHARED(pth, "fixtures/dust3r/tiny_model.pth");
  const auto dir = testing::makeTempDir("ffloc-pth-truncated");
  std::ifstream in(pth, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto path = dir / "truncated.pth";
  for (size_t length : {size_t{0}, size_t{3}, size_t{100}, bytes.size() / 2, bytes.size() - 1}) {
    writeFile(path, bytes.substr(0, length));
    const std::string message = messageOf([&] { openTensorArchive(path); });
    EXPECT_NE(message.find("truncated.pth"), std::string::npos) << length << ": " << message;
  }
  std::filesystem::remove_all(dir);
}

// Random damage must end in InputError or a valid archive, never a crash or a hang (run under
// ASan/valgrind to catch out-of-bounds reads).
TEST(PytorchCheckpoint, RandomlyDamagedCheckpointsNeverCrash) {
  const auto dir = testing::makeTempDir("ffloc-pth-fuzz");
  const auto path = dir / "fuzz.pth";
  const std::string zip = makeZip(plainMembers(plainStateDictPickle()), true);
  std::mt19937 random(42);
  int rejected = 0;
  for (int trial = 0; trial < 400; ++trial) {
    std::string damaged = zip;
    const int flips = 1 + trial % 4;
    for (int i = 0; i < flips; ++i) {
      damaged[random() % damaged.size()] = static_cast<char>(random() & 0xff);
    }
    writeFile(path, damaged);
    try {
      const auto archive = openTensorArchive(path);
      for (const std::string& name : archive->names()) {
        const TensorView& view = archive->at(name);
        volatile uint8_t sink = 0;
        for (size_t b = 0; b < view.nbytes; ++b) sink = sink ^ view.data[b];
      }
    } catch (const InputError&) {
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 0);
  std::filesystem::remove_all(dir);
}

TEST(Pickle, FuzzedFixturePickleNeverCrashes) {
  const std::string good = plainStateDictPickle();
  std::mt19937 random(7);
  for (int trial = 0; trial < 2000; ++trial) {
    std::string damaged = good;
    damaged[random() % damaged.size()] = static_cast<char>(random() & 0xff);
    try {
      pickle::unpickle(reinterpret_cast<const uint8_t*>(damaged.data()), damaged.size(), "fuzz");
    } catch (const InputError& error) {
      EXPECT_EQ(std::string(error.what()).rfind("fuzz: pickle offset", 0), 0u) << error.what();
    }
  }
}

TEST(Pickle, DeepNestingNeedsNoRecursion) {
  const size_t depth = 200000;
  const std::string bytes =
      std::string("\x80\x02", 2) + std::string(depth, ']') + std::string(depth - 1, 'a') + ".";
  const pickle::Unpickled result =
      pickle::unpickle(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), "deep");
  EXPECT_EQ(result.root->kind, pickle::Kind::kList);
  EXPECT_EQ(result.arena.size(), depth);
}

TEST(Pickle, DecodesScalarsAndContainers) {
  // {'i': -300, 'big': 2**40, 'f': 0.5, 't': (True, None), 'l': [1, 2]}
  PickleWriter writer;
  writer.op('}');
  writer.op('(');
  writer.text("i");
  writer.integer(-300);
  writer.text("big");
  writer.bytes += std::string("\x8a\x06\x00\x00\x00\x00\x00\x01", 8);  // LONG1
  writer.text("f");
  writer.bytes += std::string("G\x3f\xe0\x00\x00\x00\x00\x00\x00", 9);  // BINFLOAT
  writer.text("t");
  writer.op('\x88');
  writer.op('N');
  writer.op('\x86');
  writer.text("l");
  writer.op(']');
  writer.op('(');
  writer.bytes += "K\x01K\x02";
  writer.op('e');
  writer.op('u');
  const std::string bytes = writer.finish();
  const pickle::Unpickled result =
      pickle::unpickle(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), "inline");
  EXPECT_EQ(pickle::dictGet(result.root, "i")->integer, -300);
  EXPECT_EQ(pickle::dictGet(result.root, "big")->integer, int64_t{1} << 40);
  EXPECT_EQ(pickle::dictGet(result.root, "f")->number, 0.5);
  const pickle::Value* tuple = pickle::dictGet(result.root, "t");
  ASSERT_EQ(tuple->items.size(), 2u);
  EXPECT_TRUE(tuple->items[0]->boolean);
  EXPECT_EQ(tuple->items[1]->kind, pickle::Kind::kNone);
  EXPECT_EQ(pickle::dictGet(result.root, "l")->items.size(), 2u);
}

std::string unpickleError(const std::string& bytes) {
  return messageOf([&] { pickle::unpickle(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), "inline"); });
}

// The outside probe's 16 MB pickle took 1.5 GB; these would take gigabytes from a few hundred
// kilobytes: each REDUCE copies the arguments of a 100,000-item tuple, each STACK_GLOBAL joins
// a 1 MB string with itself.
TEST(Pickle, MemoryIsBoundedWhateverTheOpcodes) {
  PickleWriter copies;
  copies.op('(');
  copies.op('N');
  for (int i = 1; i < 100000; ++i) copies.op('2');  // DUP
  copies.op('t');
  copies.bytes += std::string("q\x00", 2);  // BINPUT 0: the tuple
  copies.op('N');
  copies.bytes += "q\x01";  // BINPUT 1: a callable
  for (int i = 0; i < 2000; ++i) copies.bytes += std::string("h\x01h\x00R0", 6);  // callable(*tuple), popped
  EXPECT_NE(unpickleError(copies.finish()).find("more than 256 MB of objects"), std::string::npos)
      << unpickleError(copies.finish());

  PickleWriter globals;
  globals.text(std::string(1 << 20, 'm'));
  globals.bytes += std::string("q\x00", 2);
  for (int i = 0; i < 1000; ++i) globals.bytes += std::string("h\x00h\x00\x93" "0", 6);  // a 2 MB "module.name", popped
  EXPECT_NE(unpickleError(globals.finish()).find("more than 256 MB of objects"), std::string::npos)
      << unpickleError(globals.finish());
}

// Sixty names for one expanded view (stride 0) of a 32-byte storage: each 512-byte copy fits in
// the file, the copies together do not.
TEST(PytorchCheckpoint, NonContiguousCopiesTogetherStayWithinTheFile) {
  const auto dir = testing::makeTempDir("ffloc-checkpoint");
  PickleWriter pickle;
  pickle.op('}');
  pickle.op('(');
  for (int i = 0; i < 60; ++i) {
    pickle.text("view" + std::to_string(i));
    pickle.tensor("FloatStorage", "0", 8, 0, {16, 8}, {0, 1});
  }
  pickle.op('u');
  const auto path = dir / "views.pth";
  writeFile(path, makeZip(plainMembers(pickle.finish()), false));
  const std::string message = messageOf([&] { openPytorchCheckpoint(path); });
  EXPECT_NE(message.find("with the copies before it, is larger than the file"), std::string::npos) << message;
}

}  // namespace
}  // namespace ffloc
