// The CLI's refusals as a user meets them: `ffloc` itself is run, and each bad input must end
// with exit status 2 and a message naming the file or the field, before any long computation.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <string>
#include <tuple>
#include <vector>

#include <torch/cuda.h>

#include "ffloc/core/error.h"
#include "ffloc/core/number_text.h"
#include "ffloc/core/stop_signals.h"
#include "ffloc/core/testing/child_process.h"
#include "ffloc/core/testing/shared_data.h"
#include "ffloc/io/testing/exif_jpeg.h"
#include "ffloc/train/training_config.h"

namespace ffloc {
namespace {

namespace fs = std::filesystem;

struct CliRun {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

CliRun runCli(const std::vector<std::string>& arguments) {
  std::vector<std::string> all = {FFLOC_CLI_PATH};
  all.insert(all.end(), arguments.begin(), arguments.end());
  std::vector<char*> argv;
  for (std::string& argument : all) argv.push_back(argument.data());
  argv.push_back(nullptr);
  const testing::ChildOutput child = testing::runInChild([&argv] {
    execv(argv[0], argv.data());
    _exit(127);
  });
  if (child.status == -1) return {};
  return {WIFEXITED(child.status) ? WEXITSTATUS(child.status) : 128 + WTERMSIG(child.status), child.output};
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

void writeText(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

void writeImage(const fs::path& path, int width = 64, int height = 48) {
  fs::create_directories(path.parent_path());
  cv::imwrite(path.string(), cv::Mat(height, width, CV_8UC3, cv::Scalar(40, 80, 120)));
}

// A native manifest of one mapping frame (a.png) and one query frame, images written.
fs::path manifestDataset(const fs::path& dir, const std::string& query_image) {
  const std::string pose = R"("camera_to_world": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]])";
  writeText(dir / "manifest.json",
            R"({"format": "ffloc-manifest", "version": 1,
                "cameras": {"0": {"width": 64, "height": 48, "fx": 50, "fy": 50, "cx": 31.5, "cy": 23.5}},
                "frames": [{"image": "a.png", "camera": "0", "split": "mapping", )" + pose + R"(},
                           {"image": ")" + query_image + R"(", "camera": "0", "split": "query", )" + pose + "}]}");
  writeImage(dir / "a.png");
  writeImage(dir / query_image);
  return dir;
}

class Cli : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = testing::makeTempDir("ffloc_cli"); }
  void TearDown() override { fs::remove_all(dir_); }

  // A synthetic indoor scene (256 x 192, one query) and its map, built by `method`.
  struct MappedScene {
    fs::path scene, map;
  };
  MappedScene mappedSyntheticScene(int mapping_frames, const std::string& method) {
    const fs::path scenes = dir_ / "synth";
    const CliRun rendered = runCli({"synth", "--out", scenes.string(), "--seed", "3", "--mapping-frames",
                                    std::to_string(mapping_frames), "--query-frames", "1", "--quiet"});
    EXPECT_EQ(rendered.exit_code, 0) << rendered.output;
    const MappedScene mapped{scenes / "scene_000_indoor", dir_ / "m.ffmap"};
    const CliRun run =
        runCli({"map", "--dataset", mapped.scene.string(), "--method", method, "-o", mapped.map.string(), "--quiet"});
    EXPECT_EQ(run.exit_code, 0) << run.output;
    return mapped;
  }

  fs::path dir_;
};

// CLI11's own exit codes before: 105 for a missing required option, 106 for an extra argument.
TEST_F(Cli, CommandLineErrorsExitWithTheBadInputCode) {
  const CliRun missing = runCli({"convert", "--output", (dir_ / "out.safetensors").string()});
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  // With the "error: " every other error starts with.
  EXPECT_TRUE(contains(missing.output, "error: --input is required")) << missing.output;
  const CliRun empty_out = runCli({"synth", "--out", ""});  // an internal error of the file system before
  EXPECT_EQ(empty_out.exit_code, 2) << empty_out.output;
  EXPECT_TRUE(contains(empty_out.output, "error: --out: ")) << empty_out.output;
  const CliRun extra = runCli({"convert", "in.pth", "out.safetensors"});
  EXPECT_EQ(extra.exit_code, 2) << extra.output;
  const CliRun unknown = runCli({"localise"});
  EXPECT_EQ(unknown.exit_code, 2) << unknown.output;
  // It said "A subcommand is required", as if none had been typed.
  EXPECT_TRUE(contains(unknown.output, "error: unknown command 'localise' (commands: eval, synth,")) << unknown.output;
  // CLI11 said "The following arguments were not expected: classical --methds", or for a
  // mistyped required option only that the required one was missing.
  for (const auto& [arguments, expected] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"eval", "--dataset", "d", "--methds", "classical"}, "error: --methds: not an option of 'ffloc eval'; did you mean --methods?"},
           {{"eval", "--dataset", "d", "--method=classical"}, "error: --method: not an option of 'ffloc eval'; did you mean --methods?"},
           {{"localize", "--mapp", "m.ffmap", "--image", "q.jpg"}, "error: --mapp: not an option of 'ffloc localize'; did you mean --map?"},
           {{"serve", "--map", "m.ffmap", "--prot", "9"}, "error: --prot: not an option of 'ffloc serve'; did you mean --port?"},
           {{"bench", "model", "--thread", "2"}, "error: --thread: not an option of 'ffloc bench model'; did you mean --threads?"},
           {{"eval", "--dataset", "d", "--max", "3"},
            "error: --max: not an option of 'ffloc eval'; did you mean one of --map, --max-correspondences, --max-queries?"},
           {{"--dataset", "d", "eval"}, "error: --dataset: not an option of 'ffloc'; options go after the command"},
           // A value that looks like an option is the option's value: the error is the seed's.
           {{"synth", "--out", "--dir", "--seed", "-1"}, "--seed: expected an integer in [0, 9223372036854775807], got '-1'"},
           {{"eval", "--dataset", "d", "--zzzzzz"}, "error: --zzzzzz: not an option of 'ffloc eval' (ffloc eval --help lists them)"},
           // One dash: CLI11 said "--dataset is required", or for "-output" (-o with "utput")
           // that "m.ffmap" was not expected.
           {{"map", "-dataset", "d", "--output", "m.ffmap"}, "error: -dataset: options take two dashes; did you mean --dataset?"},
           {{"map", "--dataset", "d", "-output", "m.ffmap"}, "error: -output: options take two dashes; did you mean --output?"},
           {{"eval", "-methds", "classical", "--dataset", "d"},
            "error: -methds: not an option of 'ffloc eval' (options take two dashes); did you mean --methods?"},
           // A line CLI11 parses: it wrote the map to ./utput. The value of -o is a value.
           {{"map", "--dataset", "d", "-output", "--quiet"}, "error: -output: options take two dashes; did you mean --output?"},
           {{"map", "-o", "-quiet", "--zzzzzz"}, "error: --zzzzzz: not an option of 'ffloc map'"}}) {
    const CliRun run = runCli(arguments);
    EXPECT_EQ(run.exit_code, 2) << run.output;
    EXPECT_TRUE(contains(run.output, expected)) << run.output;
  }
  const CliRun help = runCli({"convert", "--help"});
  EXPECT_EQ(help.exit_code, 0) << help.output;
  EXPECT_TRUE(contains(help.output, "--input")) << help.output;
}

// "--data ," gave no values and CLI11 went on to read the next flags as dataset paths.
TEST_F(Cli, AListOfCommasAloneOrWithAnEmptyEntryIsRefusedNamingItsFlag) {
  for (const auto& [arguments, expected] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"eval", "--dataset", ",", "--methods", "classical"}, "error: --dataset: ',' holds no value"},
           {{"eval", "--dataset=,", "--methods", "classical"}, "error: --dataset: ',' holds no value"},
           {{"train", "--out", (dir_ / "run").string(), "--data", ",,", "--steps", "1"}, "error: --data: ',,' holds no value"},
           // An empty entry was dropped without a word.
           {{"eval", "--dataset", "a", "--methods", "oracle-depth,,classical"},
            "error: --methods: 'oracle-depth,,classical' has an empty entry"},
           {{"eval", "--dataset=a,", "--methods", "classical"}, "error: --dataset: 'a,' has an empty entry"}}) {
    const CliRun run = runCli(arguments);
    EXPECT_EQ(run.exit_code, 2) << run.output;
    EXPECT_TRUE(contains(run.output, expected)) << run.output;
  }
}

// A bad random:<preset> given to convert was blamed on --model, a flag convert does not have.
TEST_F(Cli, ConvertNamesItsInputFlag) {
  for (const auto& [input, expected] : std::vector<std::pair<std::string, std::string>>{
           {"random:bogus", "error: --input: 'random:bogus': unknown preset 'bogus'"},
           {"random:tiny:x", "error: --input: 'random:tiny:x': seed must be a whole number in [0, 18446744073709551615]"}}) {
    const CliRun run = runCli({"convert", "--input", input, "--output", (dir_ / "x.safetensors").string()});
    EXPECT_EQ(run.exit_code, 2) << run.output;
    EXPECT_TRUE(contains(run.output, expected)) << run.output;
  }
  EXPECT_FALSE(fs::exists(dir_ / "x.safetensors"));
  const CliRun empty = runCli({"convert", "--input", "random:tiny", "--output", ""});
  EXPECT_EQ(empty.exit_code, 2) << empty.output;
  EXPECT_TRUE(contains(empty.output, "--output: the path is empty")) << empty.output;
}

// A libtorch stack trace from deep inside the run, exit 3, before.
TEST_F(Cli, CudaOnACpuOnlyBuildIsRefusedNamingTheFlag) {
  if (torch::cuda::is_available()) GTEST_SKIP() << "this libtorch has CUDA and sees a GPU";
  fs::create_directories(dir_ / "data");
  const CliRun run = runCli({"train", "--device", "cuda", "--data", (dir_ / "data").string(), "--out",
                             (dir_ / "run").string()});
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_TRUE(contains(run.output, "--device: cuda, but this libtorch was built without CUDA"))
      << run.output;
  EXPECT_FALSE(contains(run.output, "Exception raised from")) << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "run"));

  // A config written for a GPU machine: refused naming its field, and runs elsewhere with
  // --device cpu (the file alone was refused before the flag could override it).
  writeText(dir_ / "gpu.json", R"({"device": "cuda", "steps": 1, "warmup_steps": 0})");
  const CliRun from_file = runCli({"train", "--config", (dir_ / "gpu.json").string(), "--data",
                                   (dir_ / "data").string(), "--out", (dir_ / "run").string()});
  EXPECT_EQ(from_file.exit_code, 2) << from_file.output;
  EXPECT_TRUE(contains(from_file.output, "gpu.json with the command line: field 'device': cuda, but"))
      << from_file.output;
  const CliRun overridden = runCli({"train", "--config", (dir_ / "gpu.json").string(), "--device", "cpu", "--data",
                                    (dir_ / "data").string(), "--out", (dir_ / "run").string()});
  EXPECT_EQ(overridden.exit_code, 2) << overridden.output;
  EXPECT_FALSE(contains(overridden.output, "device")) << overridden.output;
  EXPECT_TRUE(contains(overridden.output, "data: unknown dataset format")) << overridden.output;
}

// long_side 100000 grew to 24 GB before the kernel killed the run: refused at the config check,
// before any data is read. The other bounds through the same check, without a process each.
TEST_F(Cli, AbsurdTrainingSizesAreRefusedAtTheConfigCheck) {
  fs::create_directories(dir_ / "data");
  writeText(dir_ / "cfg.json", R"({"long_side": 100000})");
  const CliRun run = runCli({"train", "--config", (dir_ / "cfg.json").string(), "--data", (dir_ / "data").string(),
                             "--out", (dir_ / "run").string()});
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_TRUE(contains(run.output, "cfg.json: field 'long_side': must be in [16, 2048] pixels, got 100000"))
      << run.output;
  for (const auto& [field, value] : std::vector<std::pair<std::string, int>>{
           {"batch_size", 1000000}, {"mapping_frames", 100000}, {"max_map_tokens", 1000000000},
           {"loader_threads", 100000}, {"prefetch_samples", 100000000}}) {
    try {
      trainingConfigFromJson({{field, value}}, "cfg.json");
      ADD_FAILURE() << field << " = " << value << " accepted";
    } catch (const InputError& e) {
      EXPECT_TRUE(contains(e.what(), "cfg.json: field '" + field + "'")) << e.what();
    }
  }
}

// --data a,a pooled one dataset twice, weighing its frames double without a word.
TEST_F(Cli, OneDatasetGivenTwiceIsRefused) {
  const std::string data = (dir_ / "data").string();
  fs::create_directories(data);
  // One dataset's two splits are distinct frames and pass; the same folder spelled twice does not.
  const CliRun train = runCli({"train", "--data", data + "@mapping," + data + "@query", "--val-data",
                               data + "," + data + "/", "--out", (dir_ / "run").string()});
  EXPECT_EQ(train.exit_code, 2) << train.output;
  EXPECT_TRUE(contains(train.output, "--val-data: '" + data + "' and '" + data + "/' are the same frames"))
      << train.output;
  EXPECT_FALSE(contains(train.output, "--data: ")) << train.output;
  const CliRun eval = runCli({"eval", "--dataset", data + "," + data + "/../data"});
  EXPECT_EQ(eval.exit_code, 2) << eval.output;
  EXPECT_TRUE(contains(eval.output, "--dataset: '" + data + "/../data' is given twice")) << eval.output;
}

// Names were written unescaped: a space made the name two fields, a newline two lines.
TEST_F(Cli, PoseListsRefuseNamesTheirReadersWouldSplitBeforeEvaluating) {
  const fs::path data = manifestDataset(dir_ / "data", "with space.png");
  const CliRun eval = runCli({"eval", "--dataset", data.string(), "--poses", (dir_ / "poses.txt").string()});
  EXPECT_EQ(eval.exit_code, 2) << eval.output;
  EXPECT_TRUE(contains(eval.output, "--poses: frame 'with space.png': the name holds whitespace")) << eval.output;
  EXPECT_FALSE(contains(eval.output, "median")) << "evaluated first: " << eval.output;
  EXPECT_FALSE(fs::exists(dir_ / "poses.txt"));

  const CliRun localize = runCli({"localize", "--map", (dir_ / "no.ffmap").string(), "--image",
                                  (data / "with space.png").string(), "--intrinsics", "50,50,31.5,23.5", "--poses",
                                  (dir_ / "poses.txt").string()});
  EXPECT_EQ(localize.exit_code, 2) << localize.output;
  EXPECT_TRUE(contains(localize.output, "the name holds whitespace")) << localize.output;
}

// The manifest's images were never looked at, and oracle-depth, which never reads a query
// image, scored a missing one 100 %.
TEST_F(Cli, EvalRefusesAManifestWhoseQueryImageIsMissingOrNotAnImage) {
  const fs::path data = manifestDataset(dir_ / "data", "q.png");
  fs::remove(data / "q.png");
  const CliRun missing = runCli({"eval", "--dataset", data.string(), "--methods", "oracle-depth"});
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  EXPECT_TRUE(contains(missing.output, "manifest.json: field 'frames[1].image'")) << missing.output;
  EXPECT_TRUE(contains(missing.output, "q.png")) << missing.output;
  // Not an image, or of the wrong size: Manifest.MissingBrokenOrMissizedImagesAreRefusedNamingTheFrame.

  // A query image outside the dataset's folder, given as an output: replaced by the CSV, exit 0.
  const fs::path outside = manifestDataset(dir_ / "outside", "../shared/q.png");
  const std::string image = (dir_ / "shared" / "q.png").string();
  const auto size = fs::file_size(image);
  const CliRun over = runCli({"eval", "--dataset", outside.string(), "--methods", "oracle-depth", "--csv", image});
  EXPECT_EQ(over.exit_code, 2) << over.output;
  EXPECT_TRUE(contains(over.output, "--csv: '" + image + "' is a file of the dataset")) << over.output;
  EXPECT_EQ(fs::file_size(image), size);
  // The CSV --json puts beside itself, where a folder stands: found after the run before.
  fs::create_directories(dir_ / "out" / "r.frames.csv");
  const CliRun beside = runCli({"eval", "--dataset", outside.string(), "--methods", "oracle-depth", "--json",
                                (dir_ / "out" / "r.json").string()});
  EXPECT_EQ(beside.exit_code, 2) << beside.output;
  EXPECT_TRUE(contains(beside.output, "--json (its CSV): '")) << beside.output;
  EXPECT_FALSE(fs::exists(dir_ / "out" / "r.json"));
}

// Found after the whole computation before: an internal error, or a replacement character.
TEST_F(Cli, LocalizeJsonRefusesANameThatIsNotUtf8BeforeLoadingTheMap) {
  const fs::path image = dir_ / "caf\xE9.png";
  writeImage(image);
  const CliRun run = runCli({"localize", "--map", (dir_ / "no.ffmap").string(), "--image", image.string(),
                             "--intrinsics", "50,50,31.5,23.5", "--json"});
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_TRUE(contains(run.output, "--json: the query name is not UTF-8")) << run.output;
}

// The library names its own option as the remedy; the CLI names the command and flag that set it.
TEST_F(Cli, VladRetrievalOnAMapWithoutItNamesTheFlagThatBuildsIt) {
  const auto [scene, map] = mappedSyntheticScene(8, "fastforward");
  ASSERT_FALSE(HasFailure());
  const CliRun run = runCli({"localize", "--map", map.string(), "--image", (scene / "images" / "query_0000_near.png").string(),
                             "--intrinsics", "200,200,128,96", "--retrieval", "vlad"});
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_TRUE(contains(run.output, "--retrieval: the map has no VLAD descriptors (build it with 'ffloc map --vlad')"))
      << run.output;
  // An append cannot add them: refused before any image is encoded, not blamed on the first one.
  const CliRun append = runCli({"map", "--dataset", scene.string(), "--method", "fastforward", "-o", map.string(),
                                "--append", "--vlad", "--quiet"});
  EXPECT_EQ(append.exit_code, 2) << append.output;
  EXPECT_TRUE(contains(append.output, "map: was built without VLAD descriptors, which an append cannot add to the "
                                      "images already in it; rebuild it with 'ffloc map --vlad'"))
      << append.output;
  // retrieval --json given the map's path, or a file of the dataset, replaced it, exit 0.
  const auto map_size = fs::file_size(map);
  for (const fs::path& output : {map, scene / "manifest.json"}) {
    const CliRun over = runCli({"retrieval", "--map", map.string(), "--dataset", scene.string(), "--json", output.string()});
    EXPECT_EQ(over.exit_code, 2) << over.output;
    EXPECT_TRUE(contains(over.output, "--json: '" + output.string() + "' is")) << over.output;
  }
  EXPECT_EQ(fs::file_size(map), map_size);
  // A folder no file can be made in was found only after every query had run.
  const CliRun proc = runCli({"retrieval", "--map", map.string(), "--dataset", scene.string(), "--json", "/proc/r.json"});
  EXPECT_EQ(proc.exit_code, 2) << proc.output;
  EXPECT_TRUE(contains(proc.output, "--json: '/proc/r.json': folder '/proc' is not writable")) << proc.output;
  EXPECT_FALSE(contains(proc.output, "recall")) << proc.output;
}

// The server and Python took a query's lens distortion, localize did not: a distorted camera's
// queries were answered 50 times less accurately, without a word (an outside probe).
TEST_F(Cli, LocalizeTakesTheQueryCamerasDistortion) {
  // A real camera's size, where the query localizes (at 256 x 192 with few mapping frames it fails).
  const fs::path scene = dir_ / "synth" / "scene_000_indoor", map = dir_ / "m.ffmap";
  ASSERT_EQ(runCli({"synth", "--out", (dir_ / "synth").string(), "--seed", "5000", "--kind", "indoor", "--size",
                    "640x480", "--mapping-frames", "12", "--query-frames", "1", "--quiet"}).exit_code, 0);
  ASSERT_EQ(runCli({"map", "--dataset", scene.string(), "-o", map.string(), "--quiet"}).exit_code, 0);
  std::ifstream in(scene / "manifest.json");
  const nlohmann::json manifest = nlohmann::json::parse(in);
  nlohmann::json query;
  for (const nlohmann::json& frame : manifest["frames"])
    if (frame["split"] == "query") query = frame;
  ASSERT_FALSE(query.is_null());
  const nlohmann::json& camera = manifest["cameras"][query["camera"].get<std::string>()];
  const std::string intrinsics = nlohmann::json(camera["fx"]).dump() + "," + nlohmann::json(camera["fy"]).dump() + "," +
                                 nlohmann::json(camera["cx"]).dump() + "," + nlohmann::json(camera["cy"]).dump();
  const auto localize = [&](const std::vector<std::string>& extra) {
    std::vector<std::string> arguments = {"localize", "--map", map.string(), "--image",
                                          (scene / query["image"].get<std::string>()).string(), "--intrinsics",
                                          intrinsics, "--json"};
    arguments.insert(arguments.end(), extra.begin(), extra.end());
    return runCli(arguments);
  };
  const auto pose = [](const CliRun& run) {
    const size_t start = run.output.find('{');
    return start == std::string::npos ? nlohmann::json() : nlohmann::json::parse(run.output.substr(start))["camera_to_world"];
  };
  const CliRun plain = localize({});
  const CliRun none = localize({"--distortion", "0,0,0,0"});
  const CliRun barrel = localize({"--distortion", "-0.2,0.05,0,0"});
  ASSERT_FALSE(pose(plain).is_null()) << plain.output;
  EXPECT_EQ(pose(none), pose(plain)) << none.output;
  ASSERT_FALSE(pose(barrel).is_null()) << barrel.output;
  EXPECT_NE(pose(barrel), pose(plain)) << "the distortion is applied";
  const CliRun absurd = localize({"--distortion", "1e10,0,0,0"});
  EXPECT_EQ(absurd.exit_code, 2) << absurd.output;
  EXPECT_TRUE(contains(absurd.output, "--distortion: k1 1e+10: moves the image corner")) << absurd.output;
  const CliRun two = localize({"--distortion", "0.1,0.1"});
  EXPECT_EQ(two.exit_code, 2) << two.output;
  EXPECT_TRUE(contains(two.output, "error: --distortion: expected 4, 5 or 8 comma-separated coefficients")) << two.output;
}

// A non-metric scene written to a format that reads back as metric came back metric without a
// word (documented only): its units were scored as metres (an outside probe).
TEST_F(Cli, ConvertingANonMetricSceneToAMetricFormatWarns) {
  const fs::path scenes = dir_ / "synth";
  ASSERT_EQ(runCli({"synth", "--out", scenes.string(), "--mapping-frames", "3", "--query-frames", "1", "--size",
                    "160x120", "--quiet"}).exit_code, 0);
  const fs::path scene = scenes / "scene_000_indoor";
  std::ifstream in(scene / "manifest.json");
  nlohmann::json manifest = nlohmann::json::parse(in);
  in.close();
  manifest["metric"] = false;
  writeText(scene / "manifest.json", manifest.dump());
  const CliRun kapture = runCli({"convert-dataset", "--dataset", scene.string(), "--format", "kapture", "--out",
                                 (dir_ / "k").string()});
  ASSERT_EQ(kapture.exit_code, 0) << kapture.output;
  EXPECT_TRUE(contains(kapture.output, "warning: scene_000_indoor is not metric (arbitrary units), and kapture has no "
                                       "field to say so: it reads back as metric"))
      << kapture.output;
  const CliRun kept = runCli({"convert-dataset", "--dataset", scene.string(), "--format", "manifest", "--out",
                              (dir_ / "m").string()});
  ASSERT_EQ(kept.exit_code, 0) << kept.output;
  EXPECT_FALSE(contains(kept.output, "warning")) << kept.output;
}

// `ffloc retrieval` refused the map `ffloc map` writes by default (classical), after loading a
// network it does not use (found by an outside probe following the README).
TEST_F(Cli, RetrievalMeasuresAClassicalMapAsItLocalizes) {
  const auto [scene, map] = mappedSyntheticScene(6, "classical");
  ASSERT_FALSE(HasFailure());
  const fs::path json = dir_ / "retrieval.json";
  const CliRun run = runCli({"retrieval", "--map", map.string(), "--dataset", scene.string(), "--quiet", "--top-k",
                             "1,60", "--json", json.string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  std::ifstream in(json);
  const nlohmann::json recall = nlohmann::json::parse(in);
  EXPECT_EQ(recall["retrieval"], "vlad");
  EXPECT_EQ(recall["recall"][1]["retrieval"], 1.0);  // every mapping image within K = 60
  EXPECT_TRUE(contains(run.output, "--top-k 60 is at least the map's 6 images")) << run.output;
  EXPECT_FALSE(contains(run.output, "--top-k 1 is")) << run.output;
  EXPECT_GT(recall["recall"][0]["retrieval"].get<double>(), 0.5) << recall.dump();
  const CliRun twice = runCli({"retrieval", "--map", map.string(), "--dataset", scene.string(), "--top-k", "5,1,5"});
  EXPECT_EQ(twice.exit_code, 2) << twice.output;
  EXPECT_TRUE(contains(twice.output, "--top-k: 5 given twice")) << twice.output;
  const CliRun encoder = runCli({"retrieval", "--map", map.string(), "--dataset", scene.string(), "--retrieval", "encoder"});
  EXPECT_EQ(encoder.exit_code, 2) << encoder.output;
  EXPECT_TRUE(contains(encoder.output, "--retrieval: applies to FastForward maps")) << encoder.output;

  // A map grown by --append from a second session was refused as "built from another dataset"
  // (found by an outside probe): the second session here is the scene's images under other names.
  const fs::path session = dir_ / "session";
  fs::copy(scene, session, fs::copy_options::recursive);
  std::ifstream manifest_in(session / "manifest.json");
  std::string manifest{std::istreambuf_iterator<char>(manifest_in), {}};
  for (size_t at; (at = manifest.find("images/mapping_")) != std::string::npos;) manifest.replace(at, 15, "images/second_");
  writeText(session / "manifest.json", manifest);
  for (const fs::directory_entry& entry : fs::directory_iterator(session / "images")) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("mapping_", 0) == 0) fs::rename(entry.path(), session / "images" / ("second_" + name.substr(8)));
  }
  const CliRun append = runCli({"map", "--dataset", session.string(), "-o", map.string(), "--append", "--quiet"});
  ASSERT_EQ(append.exit_code, 0) << append.output;
  const CliRun grown = runCli({"retrieval", "--map", map.string(), "--dataset", scene.string(), "--quiet"});
  EXPECT_EQ(grown.exit_code, 0) << grown.output;
  // A map of none of the dataset's frames is still refused.
  const fs::path other = dir_ / "other.ffmap";
  ASSERT_EQ(runCli({"map", "--dataset", session.string(), "-o", other.string(), "--quiet"}).exit_code, 0);
  const CliRun unrelated = runCli({"retrieval", "--map", other.string(), "--dataset", scene.string(), "--quiet"});
  EXPECT_EQ(unrelated.exit_code, 2) << unrelated.output;
  EXPECT_TRUE(contains(unrelated.output, other.string() + ": none of its 6 images is a frame of dataset")) << unrelated.output;
}

// `--poses` given the map's path replaced the map with a pose list, exit 0; a model path that
// does not exist was ignored on a classical map; a pose printed to a full disk exited 0.
TEST_F(Cli, LocalizeKeepsItsInputsRefusesTheOtherMethodsFlagsAndReportsLostOutput) {
  const auto [scene, map] = mappedSyntheticScene(6, "classical");
  ASSERT_FALSE(HasFailure());
  const std::string image = (scene / "images" / "query_0000_near.png").string();
  const auto map_size = fs::file_size(map);
  // Another map: a pose list written over it replaced it (found by an outside probe).
  const fs::path other_map = dir_ / "other.ffmap";
  fs::copy_file(map, other_map);
  const std::vector<std::string> query = {"localize", "--map", map.string(), "--image", image, "--intrinsics",
                                          "200,200,127.5,95.5"};
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--poses", map.string()}, "--poses: '" + map.string() + "' is the map (--map)"},
      {{"--poses", other_map.string()}, "--poses: '" + other_map.string() + "' is an ffloc map, which this output would replace; write it elsewhere"},
      {{"--ply", image}, "--ply: '" + image + "' is a query image"},
      {{"--poses", (dir_ / "o.txt").string(), "--ply", (dir_ / "o.txt").string()}, "is also the output of --poses"},
      {{"--model", (dir_ / "missing.pth").string()}, "--model: the map is a classical map, which does not use it"},
      {{"--no-verify"}, "--no-verify: the map is a classical map"}};
  for (const auto& [flags, expected] : cases) {
    std::vector<std::string> arguments = query;
    arguments.insert(arguments.end(), flags.begin(), flags.end());
    const CliRun run = runCli(arguments);
    EXPECT_EQ(run.exit_code, 2) << flags[0] << ": " << run.output;
    EXPECT_TRUE(contains(run.output, expected)) << run.output;
  }
  EXPECT_EQ(fs::file_size(map), map_size);
  const CliRun eval = runCli({"eval", "--dataset", scene.string(), "--csv", other_map.string(), "--quiet"});
  EXPECT_EQ(eval.exit_code, 2) << eval.output;
  EXPECT_TRUE(contains(eval.output, "--csv: '" + other_map.string() + "' is an ffloc map")) << eval.output;
  EXPECT_EQ(fs::file_size(other_map), map_size);
  EXPECT_TRUE(fs::exists(image));

  if (!fs::exists("/dev/full")) return;
  std::string command = "'" + std::string(FFLOC_CLI_PATH) + "'";
  for (const std::string& argument : query) command += " '" + argument + "'";
  const fs::path errors = dir_ / "full.err";
  const int status = std::system((command + " --json > /dev/full 2> '" + errors.string() + "'").c_str());
  EXPECT_EQ(WEXITSTATUS(status), 2);
  std::ifstream err(errors);
  const std::string text((std::istreambuf_iterator<char>(err)), {});
  EXPECT_TRUE(contains(text, "error: standard output: write failed")) << text;
}

// A query stored sideways with an EXIF orientation is decoded upright; localize says so, sizes and
// all, since intrinsics of the stored image no longer fit. Stored upright (EXIF orientation 1),
// it says nothing.
TEST_F(Cli, LocalizeSaysWhenAQueryWasTurnedByItsExifOrientation) {
  const auto [scene, map] = mappedSyntheticScene(6, "classical");
  ASSERT_FALSE(HasFailure());
  const cv::Mat upright = cv::imread((scene / "images" / "query_0000_near.png").string());
  ASSERT_FALSE(upright.empty());
  cv::Mat sideways;
  cv::rotate(upright, sideways, cv::ROTATE_90_COUNTERCLOCKWISE);  // orientation 6 turns it back clockwise
  const fs::path turned = dir_ / "sideways.jpg", plain = dir_ / "upright.jpg";
  std::ofstream(turned, std::ios::binary) << testing::jpegWithExifOrientation(sideways, 6);
  std::ofstream(plain, std::ios::binary) << testing::jpegWithExifOrientation(upright, 1);
  const std::string note = "note: " + turned.string() + ": turned upright by its EXIF orientation, from " +
                           std::to_string(upright.rows) + "x" + std::to_string(upright.cols) + " to " +
                           std::to_string(upright.cols) + "x" + std::to_string(upright.rows);
  const CliRun run = runCli({"localize", "--map", map.string(), "--image", turned.string(), "--intrinsics",
                             "200,200,127.5,95.5", "--json"});
  EXPECT_TRUE(contains(run.output, note)) << run.output;
  const CliRun stored_upright = runCli({"localize", "--map", map.string(), "--image", plain.string(), "--intrinsics",
                                        "200,200,127.5,95.5", "--json"});
  EXPECT_FALSE(contains(stored_upright.output, "note:")) << stored_upright.output;
  EXPECT_TRUE(contains(stored_upright.output, "\"status\"")) << stored_upright.output;
}

// eval --map of another scene's map scored its poses against this scene's truth without a word.
TEST_F(Cli, EvalWarnsWhenTheMapIsOfAnotherCapture) {
  const auto [scene, map] = mappedSyntheticScene(6, "classical");
  ASSERT_FALSE(HasFailure());
  const CliRun own = runCli({"eval", "--dataset", scene.string(), "--map", map.string(), "--quiet"});
  EXPECT_EQ(own.exit_code, 0) << own.output;
  EXPECT_FALSE(contains(own.output, "warning")) << own.output;
  // The map's use of depth was fixed by 'ffloc map': the refusal blamed a --methods never given.
  const CliRun no_depth = runCli({"eval", "--dataset", scene.string(), "--map", map.string(), "--no-depth"});
  EXPECT_EQ(no_depth.exit_code, 2) << no_depth.output;
  EXPECT_TRUE(contains(no_depth.output, "error: --no-depth: the map's was set when 'ffloc map' built it; only classical "
                                        "built in memory (--methods classical) uses it here"))
      << no_depth.output;
  // PnP's study settings changed the map's row, which 'ffloc localize' could then not reproduce
  // (an outside review).
  const CliRun threshold =
      runCli({"eval", "--dataset", scene.string(), "--map", map.string(), "--inlier-threshold", "2"});
  EXPECT_EQ(threshold.exit_code, 2) << threshold.output;
  EXPECT_TRUE(contains(threshold.output, "error: --inlier-threshold: 'ffloc localize' does not take it, so the map's "
                                         "row would not be what it answers"))
      << threshold.output;
  // Seed 4: the same frame names, other poses.
  const fs::path other = dir_ / "other";
  ASSERT_EQ(runCli({"synth", "--out", other.string(), "--seed", "4", "--mapping-frames", "6", "--query-frames", "1",
                    "--kind", "indoor", "--quiet"}).exit_code, 0);
  const CliRun elsewhere =
      runCli({"eval", "--dataset", (other / "scene_000_indoor").string(), "--map", map.string(), "--quiet"});
  EXPECT_EQ(elsewhere.exit_code, 0) << elsewhere.output;
  EXPECT_TRUE(contains(elsewhere.output, "warning: --map '" + map.string() +
                                             "': the map holds none of the 6 mapping frames of scene_000_indoor"))
      << elsewhere.output;
}

// The summary said "depth where the frames have it, triangulated elsewhere" for --no-depth and for
// a dataset without depth alike (found by an outside probe): the counts now.
TEST_F(Cli, MapSaysHowManyPointsCameFromDepth) {
  const auto [scene, map] = mappedSyntheticScene(6, "classical");
  ASSERT_FALSE(HasFailure());
  for (const bool depth : {true, false}) {
    std::vector<std::string> arguments = {"map", "--dataset", scene.string(), "-o", (dir_ / "d.ffmap").string()};
    if (!depth) arguments.push_back("--no-depth");
    const CliRun run = runCli(arguments);
    ASSERT_EQ(run.exit_code, 0) << run.output;
    const std::regex summary(depth ? R"(\n([0-9]+) points \(\1 lifted from depth, 0 triangulated\), [0-9]+ links\n)"
                                   : R"(\n[1-9][0-9]* points \(0 lifted from depth, [1-9][0-9]* triangulated: --no-depth\), )");
    EXPECT_TRUE(std::regex_search(run.output, summary)) << run.output;
  }
}

// A dataset without any split (a COLMAP model, a SLAM export) could not be mapped at all: "split
// 'mapping' is empty", with no flag to choose frames (an outside review). It is mapped whole; a
// split file, even an empty one, still decides.
TEST_F(Cli, MapTakesEveryFrameOfADatasetWithoutASplit) {
  const auto [scene, map] = mappedSyntheticScene(6, "classical");
  ASSERT_FALSE(HasFailure());
  nlohmann::json manifest = nlohmann::json::parse(std::ifstream(scene / "manifest.json"));
  for (nlohmann::json& frame : manifest["frames"]) frame.erase("split");
  std::ofstream(scene / "manifest.json") << manifest.dump();
  const fs::path whole = dir_ / "whole.ffmap";
  const CliRun run = runCli({"map", "--dataset", scene.string(), "-o", whole.string(), "--quiet"});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(contains(run.output, "note: " + scene.string() + " has no split, so every frame was mapped")) << run.output;
  EXPECT_TRUE(contains(run.output, "mapped 7 images")) << run.output;  // the 6 mapping frames and the query
  // The intrinsics the images were given, for queries of the same camera (an outside review).
  const nlohmann::json& camera = manifest["cameras"].begin().value();
  EXPECT_TRUE(contains(run.output, "intrinsics of the mapping images: " + formatNumber(camera["fx"].get<double>()) + "," +
                                       formatNumber(camera["fy"].get<double>()) + "," +
                                       formatNumber(camera["cx"].get<double>()) + "," +
                                       formatNumber(camera["cy"].get<double>()) + " at 256x192\n"))
      << run.output;
  // An append's counts are of the images it added, and say so.
  const CliRun again = runCli({"map", "--dataset", scene.string(), "-o", whole.string(), "--append"});
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_TRUE(contains(again.output, "\nin the 0 images added: 0 points (0 lifted from depth, 0 triangulated), 0 links\n"))
      << again.output;
  EXPECT_FALSE(contains(run.output, "images added")) << run.output;
  // The mapping camera's lens distortion is printed too, as --distortion takes it: fox's queries
  // given the four numbers alone were 40 times farther off (an outside probe).
  manifest["cameras"].begin().value()["distortion"] = {0.0125, -0.004, 0, 0};
  std::ofstream(scene / "manifest.json") << manifest.dump();
  const CliRun distorted = runCli({"map", "--dataset", scene.string(), "-o", (dir_ / "distorted.ffmap").string()});
  ASSERT_EQ(distorted.exit_code, 0) << distorted.output;
  EXPECT_TRUE(contains(distorted.output, " at 256x192, distortion 0.0125,-0.004,0,0\n")) << distorted.output;
  std::ofstream(scene / "split_mapping.txt").flush();
  const CliRun listed_none = runCli({"map", "--dataset", scene.string(), "-o", (dir_ / "none.ffmap").string()});
  EXPECT_EQ(listed_none.exit_code, 2) << listed_none.output;
  EXPECT_TRUE(contains(listed_none.output, "split 'mapping' is empty (split_mapping.txt lists 0 frame(s)"))
      << listed_none.output;
}

// The .md of an --protocol run held the table alone, where the terminal also printed the protocol;
// a dataset that is not 7-Scenes lost most of its mapping frames to its thinning, said without why
// (found by an outside probe).
TEST_F(Cli, EvalUnderAProtocolWritesItBesideTheTable) {
  const fs::path scenes = dir_ / "synth";
  ASSERT_EQ(runCli({"synth", "--out", scenes.string(), "--mapping-frames", "20", "--query-frames", "2", "--size",
                    "160x120", "--quiet"}).exit_code, 0);
  const fs::path json = dir_ / "r.json";
  const CliRun run = runCli({"eval", "--dataset", (scenes / "scene_000_indoor").string(), "--methods", "oracle-depth",
                             "--protocol", "7scenes", "--quiet", "--json", json.string(), "--html",
                             (dir_ / "r.html").string()});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(contains(run.output, "protocol 7scenes keeps 2 of its 20 mapping frames (every 15th by capture number"))
      << run.output;
  std::ifstream markdown(dir_ / "r.md");
  const std::string written{std::istreambuf_iterator<char>(markdown), {}};
  EXPECT_TRUE(contains(written, "| oracle-depth |")) << written;
  EXPECT_TRUE(contains(written, "\nprotocol 7scenes (indoor): top-K ")) << written;
  std::ifstream html(dir_ / "r.html");
  const std::string page{std::istreambuf_iterator<char>(html), {}};
  EXPECT_TRUE(contains(page, "<p class=\"note\">protocol 7scenes (indoor): top-K ")) << page.substr(0, 3000);
}

// A resume refused at its first draw rewrote the run's config.json with settings that never ran
// (its --steps became the run's), and a run that finished all its steps within --max-seconds said
// its budget was spent and --resume would continue it (found by an outside probe).
TEST_F(Cli, TrainSaysAndKeepsOnlyWhatHappened) {
  const fs::path scenes = dir_ / "synth";
  ASSERT_EQ(runCli({"synth", "--out", scenes.string(), "--seed", "3", "--size", "160x120", "--quiet"}).exit_code, 0);
  const std::string data = (scenes / "scene_000_indoor").string();
  writeText(dir_ / "c.json", R"({"model": "random:tiny", "steps": 1, "warmup_steps": 0, "long_side": 128,
                                 "min_map_tokens": 20, "max_map_tokens": 40})");
  const fs::path run = dir_ / "run";
  const CliRun first = runCli({"train", "--config", (dir_ / "c.json").string(), "--data", data, "--out", run.string(),
                               "--quiet", "--threads", "1", "--max-seconds", "0.001"});
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_FALSE(contains(first.output, "time budget")) << first.output;
  std::ifstream before_in(run / "config.json");
  const std::string before{std::istreambuf_iterator<char>(before_in), {}};
  // The query split alone, 15 frames over the scene: no frame has 5 others that overlap it.
  const CliRun refused = runCli({"train", "--data", data + "@query", "--out", run.string(), "--resume", "--steps", "3",
                                 "--quiet", "--threads", "1"});
  ASSERT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_TRUE(contains(refused.output, "no frame has 5 mapping frames of overlap")) << refused.output;
  std::ifstream after_in(run / "config.json");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(after_in), {}), before);
}

// The pose list held every pose PnP found, an `uncertain` one (a query from another scene, 1-7 m
// off) as any other (an outside probe): it holds the localized queries' alone.
TEST_F(Cli, LocalizesPoseListHoldsTheLocalizedQueriesAlone) {
  const auto [scene, map] = mappedSyntheticScene(20, "classical");
  ASSERT_FALSE(HasFailure());
  std::ifstream manifest_in(scene / "manifest.json");
  const nlohmann::json camera = nlohmann::json::parse(manifest_in)["cameras"]["0"];
  const std::string intrinsics = formatSignificant(camera["fx"].get<double>(), 17) + " " +
                                 formatSignificant(camera["fy"].get<double>(), 17) + " " +
                                 formatSignificant(camera["cx"].get<double>(), 17) + " " +
                                 formatSignificant(camera["cy"].get<double>(), 17);
  writeImage(scene / "flat.png", camera["width"].get<int>(), camera["height"].get<int>());
  // The same image given a focal length 1.31 times its own: a pose, `uncertain` for its focal fit.
  const std::string wrong_focal = "230 230 " + formatSignificant(camera["cx"].get<double>(), 17) + " " +
                                  formatSignificant(camera["cy"].get<double>(), 17);
  writeText(scene / "list.txt", "images/mapping_0002.png " + intrinsics + "\nimages/mapping_0002.png " + wrong_focal +
                                    "\nflat.png " + intrinsics + "\n");
  const fs::path poses = dir_ / "poses.txt";
  const CliRun run = runCli({"localize", "--map", map.string(), "--images", (scene / "list.txt").string(), "--json",
                             "--quiet", "--poses", poses.string()});
  EXPECT_EQ(run.exit_code, 1) << run.output;
  const nlohmann::json answers = nlohmann::json::parse(
      run.output.substr(run.output.find('['), run.output.rfind(']') + 1 - run.output.find('[')));
  ASSERT_EQ(answers.size(), 3u) << run.output;
  EXPECT_EQ(answers[0]["status"], "localized") << run.output;
  EXPECT_EQ(answers[1]["status"], "uncertain") << run.output;
  EXPECT_FALSE(answers[1]["camera_to_world"].is_null()) << run.output;
  EXPECT_EQ(answers[2]["status"], "failed") << run.output;
  std::ifstream poses_in(poses);
  const std::string list{std::istreambuf_iterator<char>(poses_in), {}};
  EXPECT_EQ(list.rfind("images/mapping_0002.png ", 0), 0u) << list;
  EXPECT_EQ(std::count(list.begin(), list.end(), '\n'), 1) << list;
  EXPECT_TRUE(contains(run.output, "(the poses of the 1 localized of 3 queries)")) << run.output;
}

// A query of an --images list whose intrinsics the localizer refuses (a focal length out of range, a
// principal point outside the image) was reported without its line: in a long list, no telling which.
TEST_F(Cli, QueryListsTakePathsWithSpacesAndNameTheLineOfARefusedQuery) {
  const auto [scene, map] = mappedSyntheticScene(6, "classical");
  ASSERT_FALSE(HasFailure());
  writeText(scene / "one.txt", "images/query_0000_near.png -200 200 127.5 95.5\n");
  const CliRun one = runCli({"localize", "--map", map.string(), "--images", (scene / "one.txt").string()});
  EXPECT_EQ(one.exit_code, 2) << one.output;
  EXPECT_TRUE(contains(one.output, "one.txt:1: query 'images/query_0000_near.png': fx: focal length -200 px is not in [0.256, 256000]")) << one.output;
  writeText(scene / "two.txt", "# a comment\nimages/query_0000_near.png 200 200 127.5 95.5\n"
                               "images/query_0000_near.png 200 200 900 95.5\n");
  const CliRun two = runCli({"localize", "--map", map.string(), "--images", (scene / "two.txt").string()});
  EXPECT_EQ(two.exit_code, 2) << two.output;
  EXPECT_TRUE(contains(two.output, "two.txt:3: query 'images/query_0000_near.png': cx, cy: the principal point (900, 95.5)"))
      << two.output;
  // An error that names the image itself named it twice: "list:2: query 'x.png': .../x.png: ...".
  writeText(scene / "text.png", "not an image");
  writeText(scene / "bad.txt", "images/query_0000_near.png 200 200 127.5 95.5\ntext.png 200 200 127.5 95.5\n");
  const CliRun bad = runCli({"localize", "--map", map.string(), "--images", (scene / "bad.txt").string(), "--json"});
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_TRUE(contains(bad.output, "bad.txt:2: " + (scene / "text.png").string() + ": ")) << bad.output;
  EXPECT_FALSE(contains(bad.output, "query 'text.png'")) << bad.output;
  EXPECT_TRUE(contains(bad.output, "\"status\": \"error\"")) << bad.output;
  // A single --image query named neither itself nor its flag.
  const std::string image = (scene / "images" / "query_0000_near.png").string();
  const CliRun single = runCli({"localize", "--map", map.string(), "--image", image, "--intrinsics", "200,200,900,95.5"});
  EXPECT_EQ(single.exit_code, 2) << single.output;
  EXPECT_TRUE(contains(single.output, "error: query '" + image + "': cx, cy: the principal point (900, 95.5)"))
      << single.output;
  // A comma with no number beside it was read as a space: "200,200,127.5,95.5," passed as four.
  for (const std::string cut : {"200,200,127.5,95.5,", "200,,200,127.5,95.5", ",200,200,127.5,95.5"}) {
    const CliRun run = runCli({"localize", "--map", map.string(), "--image", image, "--intrinsics", cut});
    EXPECT_EQ(run.exit_code, 2) << cut << ": " << run.output;
    EXPECT_TRUE(contains(run.output, "--intrinsics: intrinsics must be four numbers fx,fy,cx,cy, got '" + cut + "'"))
        << run.output;
  }
  // A path with spaces (split at its first space, it was refused), after a UTF-8 byte order mark,
  // with Windows line ends and intrinsics apart by commas; and a NUL byte, which cut the path short.
  fs::copy_file(scene / "images" / "query_0000_near.png", scene / "images" / "near view.png");
  writeText(scene / "spaces.txt", "\xEF\xBB\xBFimages/near view.png 200 200 127.5 95.5\r\n"
                                  "images/near view.png 200,200,127.5,95.5\r\n");
  const CliRun spaces = runCli({"localize", "--map", map.string(), "--images", (scene / "spaces.txt").string(), "--json"});
  EXPECT_NE(spaces.exit_code, 2) << spaces.output;
  EXPECT_TRUE(contains(spaces.output, "\"name\": \"images/near view.png\"")) << spaces.output;
  EXPECT_FALSE(contains(spaces.output, "\"error\"")) << spaces.output;
  // With --json nothing showed until the last query was answered (an outside probe): a progress
  // line; without it each answer shows as it comes.
  EXPECT_TRUE(contains(spaces.output, "queries [==============================] 2/2")) << spaces.output;
  const CliRun quiet = runCli({"localize", "--map", map.string(), "--images", (scene / "spaces.txt").string(), "--json",
                               "--quiet"});
  EXPECT_FALSE(contains(quiet.output, "queries [")) << quiet.output;
  EXPECT_FALSE(contains(two.output, "queries [")) << two.output;
  writeText(scene / "three.txt", "images/near view.png 200 200 127.5\n");
  const CliRun three = runCli({"localize", "--map", map.string(), "--images", (scene / "three.txt").string()});
  EXPECT_EQ(three.exit_code, 2) << three.output;
  EXPECT_TRUE(contains(three.output, "three.txt:1: query 'images/near view.png': intrinsics must be four numbers"))
      << three.output;
  // In a list, such a line is its query's error and the others run (it stopped the whole list
  // before any query: an outside probe); so is a line without intrinsics.
  writeText(scene / "mixed.txt", "images/near view.png 200 200 127.5 95.5\nimages/near view.png 200 200 127.5\n"
                                 "images/near view.png\n");
  const CliRun mixed = runCli({"localize", "--map", map.string(), "--images", (scene / "mixed.txt").string(), "--json",
                               "--quiet"});
  EXPECT_EQ(mixed.exit_code, 2) << mixed.output;
  const size_t array_at = mixed.output.find('[');
  ASSERT_NE(array_at, std::string::npos) << mixed.output;
  const nlohmann::json answers = nlohmann::json::parse(mixed.output.substr(array_at));
  ASSERT_EQ(answers.size(), 3u) << mixed.output;
  EXPECT_NE(answers[0]["status"], "error") << mixed.output;
  EXPECT_EQ(answers[1]["status"], "error") << mixed.output;
  EXPECT_TRUE(contains(answers[1]["error"].get<std::string>(),
                       "mixed.txt:2: query 'images/near view.png': intrinsics must be four numbers fx,fy,cx,cy, got "
                       "'200 200 127.5'"))
      << mixed.output;
  EXPECT_EQ(answers[2]["status"], "error") << mixed.output;
  EXPECT_TRUE(contains(answers[2]["error"].get<std::string>(), "mixed.txt:3: query 'images/near view.png': no intrinsics"))
      << mixed.output;
  writeText(scene / "nul.txt", std::string("images/query_0000_near.png\0.jpg 200 200 127.5 95.5\n", 51));
  const CliRun nul = runCli({"localize", "--map", map.string(), "--images", (scene / "nul.txt").string()});
  EXPECT_EQ(nul.exit_code, 2) << nul.output;
  EXPECT_TRUE(contains(nul.output, "nul.txt:1: query list: the line holds a NUL byte")) << nul.output;
  // A FIFO waited for a writer for ever; /dev/zero, one endless line, filled the memory.
  const fs::path fifo = scene / "list.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const fs::path& list : {fifo, fs::path("/dev/zero")}) {
    const CliRun endless = runCli({"localize", "--map", map.string(), "--images", list.string()});
    EXPECT_EQ(endless.exit_code, 2) << endless.output;
    EXPECT_TRUE(contains(endless.output, list.string() + ": query list expected, found something that is not a regular file"))
        << endless.output;
  }
}

TEST_F(Cli, MapRefusesImageNamesThatAreNotUtf8BeforeMapping) {
  for (const std::string stem : {"caf\xE9", "plain"}) {
    const fs::path root = dir_ / "data" / "train";
    writeImage(root / "rgb" / (stem + ".color.png"));
    writeText(root / "poses" / (stem + ".pose.txt"), "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
    writeText(root / "calibration" / (stem + ".calibration.txt"), "50\n");
  }
  const CliRun run = runCli({"map", "--dataset", (dir_ / "data").string(), "-o", (dir_ / "out.ffmap").string()});
  EXPECT_EQ(run.exit_code, 2) << run.output;
  // The bytes that are not UTF-8 are escaped: the error line was itself not valid text.
  EXPECT_TRUE(contains(run.output, "caf\\xe9.color.png: image name 'train/rgb/caf\\xe9.color.png' is not UTF-8"))
      << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "out.ffmap"));
  // CLI11's own messages too: an unknown option was printed with its raw bytes.
  const CliRun option = runCli({"eval", "--dataset", "x", "--no\xffpe"});
  EXPECT_EQ(option.exit_code, 2) << option.output;
  EXPECT_TRUE(contains(option.output, "no\\xffpe")) << option.output;
  EXPECT_FALSE(contains(option.output, "no\xffpe")) << option.output;
}

// Unbounded before: 65537 crashed inside TBB (OpenCV's pool), 1000 made a one-image map 25 times
// slower, and -1 passed without a word. Refused while parsing, before any map or model loads.
TEST_F(Cli, ThreadCountsOutsideTheirRangeAreRefusedNamingTheFlag) {
  const std::string map = (dir_ / "no.ffmap").string();
  const std::vector<std::vector<std::string>> commands = {
      {"localize", "--map", map, "--image", "q.png", "--intrinsics", "50,50,31.5,23.5"},
      {"map", "--dataset", dir_.string(), "-o", map},
      {"eval", "--dataset", dir_.string()},
      {"serve", "--map", map},
      {"synth", "--out", (dir_ / "synth").string()},
      {"bench", "model"},
      {"train", "--data", dir_.string(), "--out", (dir_ / "run").string()}};
  for (const std::vector<std::string>& command : commands) {
    for (const std::string threads : {"65537", "257", "-1"}) {
      std::vector<std::string> arguments = command;
      arguments.insert(arguments.end(), {"--threads", threads});
      const CliRun run = runCli(arguments);
      EXPECT_EQ(run.exit_code, 2) << command[0] << " --threads " << threads << ": " << run.output;
      EXPECT_TRUE(contains(run.output, "--threads: must be 0 (all hardware threads) to 256, got " + threads))
          << command[0] << ": " << run.output;
    }
  }
  // The bound itself passes the check and reaches the next one: the missing map.
  const CliRun at_bound = runCli({"localize", "--map", map, "--image", "q.png", "--intrinsics", "50,50,31.5,23.5",
                                  "--threads", "256"});
  EXPECT_EQ(at_bound.exit_code, 2) << at_bound.output;
  EXPECT_TRUE(contains(at_bound.output, "no.ffmap")) << at_bound.output;
  EXPECT_FALSE(contains(at_bound.output, "--threads")) << at_bound.output;
}

// Unbounded before: --height 100000 took 2.5 GB and had not finished one call after 30 s.
TEST_F(Cli, BenchSizesAndCountsBeyondAnyMeasurementAreRefused) {
  for (const auto& [flags, message] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"--height", "100000"}, "--width/--height: 512x100000 is not a positive multiple of the patch size 16 of at most 4096"},
           {{"--repeats", "1000000000"}, "--repeats: must be in [1, 10000]"},
           {{"--features", "99999999"}, "--features: map token counts must be in [1, 1000000], got 99999999"},
           // Two spellings of one precision timed it twice (an outside probe).
           {{"--dtype", "f32,fp32"}, "--dtype: 'fp32' names a precision given before"}}) {
    std::vector<std::string> arguments = {"bench", "model"};
    arguments.insert(arguments.end(), flags.begin(), flags.end());
    const CliRun run = runCli(arguments);
    EXPECT_EQ(run.exit_code, 2) << flags[0] << ": " << run.output;
    EXPECT_TRUE(contains(run.output, message)) << run.output;
  }
}

// Classical mapped the empty split and blamed the features ("no mapping image has usable
// features"), fastforward the depth; a dataset without queries was mapped in full first.
TEST_F(Cli, EvalOfADatasetWithAnEmptySplitSaysWhichAndNamesTheDataset) {
  const fs::path data = manifestDataset(dir_ / "data", "q.png");
  std::ifstream read(data / "manifest.json");
  const std::string manifest((std::istreambuf_iterator<char>(read)), {});
  for (const auto& [from, to, empty] : {std::tuple<std::string, std::string, std::string>{"mapping", "query", "mapping"},
                                        {"query", "mapping", "query"}}) {
    std::string edited = manifest;
    for (size_t at; (at = edited.find("\"split\": \"" + from + "\"")) != std::string::npos;)
      edited.replace(at, from.size() + 11, "\"split\": \"" + to + "\"");
    writeText(data / "manifest.json", edited);
    for (const std::string methods : {"classical", "fastforward", "oracle-depth"}) {
      const CliRun run = runCli({"eval", "--dataset", data.string(), "--methods", methods});
      EXPECT_EQ(run.exit_code, 2) << methods << ": " << run.output;
      EXPECT_TRUE(contains(run.output, "error: " + data.string() + ": split '" + empty + "' is empty"))
          << methods << ": " << run.output;
      EXPECT_FALSE(contains(run.output, "features [")) << methods << " mapped first: " << run.output;
    }
  }
}

// Flags the run would ignore were taken without a word: --model on a classical map (the docs'
// retrieval example built a classical map that way), --max-features with --append (the map keeps
// its own SIFT settings).
TEST_F(Cli, MapRefusesFlagsItWouldIgnore) {
  const std::string data = manifestDataset(dir_ / "data", "q.png").string();
  const std::string map = (dir_ / "ignored.ffmap").string();
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--model", "default"}, "--model: the classical method uses no network"},
      {{"--dtype", "bf16"}, "--dtype: the classical method uses no network"},
      {{"--vlad"}, "--vlad: a classical map always holds its VLAD descriptors"},
      {{"--method", "fastforward", "--max-features", "100"}, "--max-features: applies to the classical method only"},
      {{"--method", "fastforward", "--no-depth"}, "--no-depth: applies to the classical method only"},
      {{"--append", "--max-image-size", "640"}, "--max-image-size: a map appended to keeps the SIFT settings"}};
  for (const auto& [flags, expected] : cases) {
    std::vector<std::string> arguments = {"map", "--dataset", data, "-o", map, "--quiet"};
    arguments.insert(arguments.end(), flags.begin(), flags.end());
    const CliRun run = runCli(arguments);
    EXPECT_EQ(run.exit_code, 2) << flags[0] << ": " << run.output;
    EXPECT_TRUE(contains(run.output, expected)) << run.output;
  }
  EXPECT_FALSE(fs::exists(map));
}

// "error: : Invalid argument" before, naming neither the flag nor what was wrong; --stride 0 gave
// "Value 0 not in range 0.000000 to 1797...", the largest double in full.
TEST_F(Cli, EmptyPathsAndCountsBelowTheirMinimumNameTheFlagAndTheBound) {
  const std::string data = manifestDataset(dir_ / "data", "q.png").string();
  const std::string map = (dir_ / "m.ffmap").string();
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"map", "--dataset", "", "-o", map}, "--dataset"},
      {{"map", "--dataset", data, "-o", ""}, "--output"},
      {{"eval", "--dataset", ""}, "--dataset"},
      {{"eval", "--dataset", data, "--map", ""}, "--map"},
      {{"eval", "--dataset", data, "--json", ""}, "--json"},
      {{"localize", "--map", "", "--image", "q.png", "--intrinsics", "50,50,31.5,23.5"}, "--map"},
      {{"serve", "--map", ""}, "--map"},
      {{"retrieval", "--map", map, "--dataset", ""}, "--dataset"},
      {{"convert-dataset", "--dataset", data, "--format", "kapture", "--out", ""}, "--out"}};
  for (const auto& [arguments, flag] : cases) {
    const CliRun run = runCli(arguments);
    EXPECT_EQ(run.exit_code, 2) << arguments[0] << " " << flag << ": " << run.output;
    EXPECT_TRUE(contains(run.output, flag + ": the path is empty")) << arguments[0] << ": " << run.output;
    EXPECT_FALSE(contains(run.output, "features [")) << arguments[0] << " mapped first: " << run.output;
  }
  EXPECT_FALSE(fs::exists(map));
  for (const std::string stride : {"0", "-3"}) {
    const CliRun run = runCli({"eval", "--dataset", data, "--methods", "oracle-depth", "--stride", stride});
    EXPECT_EQ(run.exit_code, 2) << run.output;
    EXPECT_TRUE(contains(run.output, "--stride: must be an integer of at least 1, got " + stride)) << run.output;
  }
  // CLI11 read "-1" into an unsigned seed or K as 2^64 - 1, without a word.
  for (const auto& [arguments, flag] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"localize", "--map", map, "--image", "q.png", "--intrinsics", "50,50,31.5,23.5", "--seed", "-1"}, "--seed"},
           {{"eval", "--dataset", data, "--seed", "-1"}, "--seed"},
           {{"eval", "--dataset", data, "--max-queries", "-1"}, "--max-queries"},
           {{"eval", "--dataset", data, "--max-correspondences", "-1"}, "--max-correspondences"},
           {{"eval", "--dataset", data, "--min-correspondences", "-1"}, "--min-correspondences"},
           {{"synth", "--out", (dir_ / "s").string(), "--seed", "-1"}, "--seed"},
           {{"retrieval", "--map", map, "--dataset", data, "--top-k", "5,-1"}, "--top-k"}}) {
    const CliRun run = runCli(arguments);
    EXPECT_EQ(run.exit_code, 2) << arguments[0] << ": " << run.output;
    EXPECT_TRUE(contains(run.output, flag + ": expected an integer in [0, 9223372036854775807], got '-1'"))
        << arguments[0] << ": " << run.output;
  }
  // CLI11 alone saturated a seed past 2^64 without a word, read "" as 0 and "0x10" as 16; the
  // server refuses seeds past 2^63 - 1.
  for (const std::string seed : {"99999999999999999999999", "18446744073709551616", "9223372036854775808", "", "0x10"}) {
    const CliRun run = runCli({"localize", "--map", map, "--image", "q.png", "--intrinsics", "50,50,31.5,23.5", "--seed", seed});
    EXPECT_EQ(run.exit_code, 2) << seed << ": " << run.output;
    EXPECT_TRUE(contains(run.output, "--seed: expected an integer in [0, 9223372036854775807], got '" + seed + "'"))
        << seed << ": " << run.output;
  }
  // A FIFO given as the reference timings blocked the bench until someone wrote to it.
  const fs::path fifo = dir_ / "timings.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const CliRun bench = runCli({"bench", "model", "--reference", fifo.string()});
  EXPECT_EQ(bench.exit_code, 2) << bench.output;
  EXPECT_TRUE(contains(bench.output, fifo.string() + ": reference timing file expected, found something that is not"))
      << bench.output;
}

// Accepted before: an empty method list ran classical, a method named twice ran twice, NaN
// outliers and negative noise passed, and an output in a missing folder or onto a folder was
// found only after every query had run.
TEST_F(Cli, EvalRefusesOptionsItWouldIgnoreOrMisuseBeforeEvaluating) {
  const std::string data = manifestDataset(dir_ / "data", "q.png").string();
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--methods", ""}, "--methods: names no method"},
      {{"--methods", ","}, "--methods: ',' holds no value"},
      {{"--methods", "oracle-depth,classical,oracle-depth"}, "--methods: 'oracle-depth' is given twice"},
      {{"--methods", "oracle-depth", "--outliers", "nan"}, "--outliers: must be in [0, 1]"},
      {{"--methods", "oracle-depth", "--noise-px", "-1"}, "--noise-px: must be a finite number of pixels, 0 or more"},
      {{"--methods", "oracle-depth", "--noise-px", "inf"}, "--noise-px: must be a finite number of pixels, 0 or more"},
      {{"--methods", "oracle-depth", "--point-noise", "nan"}, "--point-noise: must be a finite distance, 0 or more"},
      {{"--methods", "oracle-depth", "--json", (dir_ / "missing" / "r.json").string()},
       "--json: '" + (dir_ / "missing" / "r.json").string() + "': folder '" + (dir_ / "missing").string() +
           "' does not exist"},
      {{"--methods", "oracle-depth", "--poses", dir_.string()}, "--poses: '" + dir_.string() + "' is a folder"},
      // A flag of a method that does not run changed nothing, without a word.
      {{"--methods", "classical,oracle-depth", "--features", "500"},
       "--features: none of the methods evaluated (classical, oracle-depth) uses it"},
      {{"--methods", "fastforward", "--no-pose-guided"}, "--no-pose-guided: none of the methods evaluated (fastforward) uses it"},
      {{"--methods", "oracle-depth,sift-baseline", "--top-k", "3"},
       "--top-k: none of the methods evaluated (oracle-depth, sift-baseline) uses it"},
      {{"--methods", "oracle-depth", "--preset", "outdoor"}, "--preset: none of the methods evaluated (oracle-depth) uses it"},
      {{"--methods", "classical", "--stride", "2"}, "--stride: only oracle-depth uses it, and --methods does not run it"},
      {{"--methods", "oracle-depth", "--no-depth"}, "--no-depth: only classical uses it, and --methods does not run it"},
      // Root passes every permission test in /proc, where no file can be made: the JSON failed after
      // every query had run.
      {{"--methods", "oracle-depth", "--json", "/proc/ffloc-r.json"}, "--json: '/proc/ffloc-r.json': folder '/proc' is not writable"},
      // A name the file system cannot look up was an uncaught filesystem_error: "internal error", exit 3.
      {{"--methods", "oracle-depth", "--csv", (dir_ / std::string(300, 'a') / "r.csv").string()},
       "' cannot be reached: File name too long"},
      // An HTML report over the query image replaced it, exit 0; two outputs of one path kept the last.
      {{"--methods", "oracle-depth", "--html", data + "/q.png"},
       "--html: '" + data + "/q.png' is inside the dataset '" + data + "', whose files it could replace"},
      {{"--methods", "oracle-depth", "--json", (dir_ / "r.json").string(), "--markdown", (dir_ / "r.json").string()},
       "--markdown: '" + (dir_ / "r.json").string() + "' is also the output of --json"},
      {{"--methods", "oracle-depth", "--json", (dir_ / "r.json").string(), "--html", (dir_ / "r.md").string()},
       "--json (its table): '" + (dir_ / "r.md").string() + "' is also the output of --html"}};
  for (const auto& [options, message] : cases) {
    std::vector<std::string> arguments = {"eval", "--dataset", data};
    arguments.insert(arguments.end(), options.begin(), options.end());
    const CliRun run = runCli(arguments);
    EXPECT_EQ(run.exit_code, 2) << message << ": " << run.output;
    EXPECT_TRUE(contains(run.output, message)) << run.output;
    EXPECT_FALSE(contains(run.output, "median")) << "evaluated first: " << run.output;
  }
  const CliRun localize = runCli({"localize", "--map", (dir_ / "no.ffmap").string(), "--image", data + "/q.png",
                                  "--intrinsics", "50,50,31.5,23.5", "--ply", (dir_ / "missing" / "p.ply").string()});
  EXPECT_EQ(localize.exit_code, 2) << localize.output;
  EXPECT_TRUE(contains(localize.output, "--ply: '" + (dir_ / "missing" / "p.ply").string() + "': folder"))
      << localize.output;
}

// Outputs were compared with the frames' images and depth maps only: --json onto the target of a
// linked manifest.json replaced the dataset's ground truth (found by an outside probe).
TEST_F(Cli, EvalNeverWritesOverAFileTheDatasetReadsThroughALink) {
  const fs::path data = manifestDataset(dir_ / "data", "q.png");
  const fs::path outside = dir_ / "outside" / "manifest.json";
  fs::create_directories(outside.parent_path());
  fs::rename(data / "manifest.json", outside);
  fs::create_symlink(outside, data / "manifest.json");
  std::ifstream before_file(outside);
  const std::string before((std::istreambuf_iterator<char>(before_file)), {});
  const CliRun run =
      runCli({"eval", "--dataset", data.string(), "--methods", "oracle-depth", "--json", outside.string()});
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_TRUE(contains(run.output, "--json: '" + outside.string() + "' is a file of the dataset " + data.string() +
                                       " (as " + (data / "manifest.json").string() + "); write it elsewhere"))
      << run.output;
  std::ifstream after_file(outside);
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(after_file)), {}), before);
}

// Every seed of `ffloc synth` names its first scene scene_000_indoor: two of them evaluated together
// gave rows nothing told apart (found by an outside probe). Such datasets are named by their folder.
TEST_F(Cli, EvalNamesDatasetsOfOneNameByTheirFolders) {
  std::vector<std::string> folders;
  for (const std::string seed : {"1", "2"}) {
    const fs::path scenes = dir_ / ("seed" + seed);
    const CliRun rendered = runCli({"synth", "--out", scenes.string(), "--seed", seed, "--mapping-frames", "3",
                                    "--query-frames", "1", "--size", "64x48", "--quiet"});
    ASSERT_EQ(rendered.exit_code, 0) << rendered.output;
    folders.push_back((scenes / "scene_000_indoor").string());
  }
  const fs::path report = dir_ / "r.json";
  const CliRun run = runCli({"eval", "--dataset", folders[0] + "," + folders[1], "--methods", "oracle-depth",
                             "--json", report.string(), "--quiet"});
  ASSERT_EQ(run.exit_code, 0) << run.output;
  std::ifstream in(report);
  const nlohmann::json summary = nlohmann::json::parse(in);
  std::vector<std::string> datasets;
  for (const auto& row : summary.at("results")) datasets.push_back(row.at("dataset").get<std::string>());
  EXPECT_EQ(datasets, (std::vector<std::string>{folders[0], folders[1], "all 2 datasets"}));

  // Folders whose names are not UTF-8: the JSON writer failed after the evaluation (exit 3), and
  // every output was lost. Named with \xhh escapes.
  const fs::path odd = dir_ / "no\xffpe";
  fs::create_directories(odd);
  fs::create_directory_symlink(folders[0], odd / "scene");
  fs::create_directories(dir_ / "second" / "no\xffpe");
  fs::create_directory_symlink(folders[1], dir_ / "second" / "no\xffpe" / "scene");
  const CliRun odd_run = runCli({"eval", "--dataset", (odd / "scene").string() + "," + (dir_ / "second" / "no\xffpe" / "scene").string(),
                                 "--methods", "oracle-depth", "--json", report.string(), "--quiet"});
  ASSERT_EQ(odd_run.exit_code, 0) << odd_run.output;
  std::ifstream odd_in(report);
  const nlohmann::json odd_summary = nlohmann::json::parse(odd_in);
  EXPECT_EQ(odd_summary.at("results")[0].at("dataset"), (dir_ / "no\\xffpe" / "scene").string());
}

// synth wrote over a dataset, mixing its stale frames with new ones, and ran --scenes 2e9 (or
// scenes the disk cannot hold) until the disk filled; convert-dataset onto a loop of links was an
// internal error (exit 3); --max-waiting had no bound.
TEST_F(Cli, OutputFoldersAndServerCountsAreRefusedNamingTheFlag) {
  writeText(dir_ / "earlier" / "manifest.json", "{}");
  const fs::path loop = dir_ / "selfloop";
  fs::create_directory_symlink(loop, loop);
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"synth", "--out", (dir_ / "earlier").string(), "--quiet"}, "--out: " + (dir_ / "earlier").string() + ": output folder is not empty"},
      {{"synth", "--out", (dir_ / "many").string(), "--scenes", "2000000000"}, "--scenes: must be in [1, 10000], got 2000000000"},
      // 37 749 GB of depth maps.
      {{"synth", "--out", (dir_ / "new" / "big").string(), "--scenes", "10000", "--size", "4096x3072"},
       "--out: the scenes need at least 37748.7 GB (their depth maps alone) and " + dir_.string() + " has "},
      {{"convert-dataset", "--dataset", dir_.string(), "--format", "kapture", "--out", loop.string()},
       "--out: " + loop.string() + ": cannot examine the output folder: Too many levels of symbolic links"},
      {{"serve", "--map", "m.ffmap", "--max-waiting", "100000"}, "--max-waiting: Value 100000 not in range 0 to 256"},
      // It bound the IPv6 loopback while saying that any machine on the network could reach it.
      {{"serve", "--map", "m.ffmap", "--host", ""}, "--host: empty: name an address"},
      // CLI11's Range took "nan" (every comparison with it fails).
      {{"serve", "--map", "m.ffmap", "--header-timeout", "nan"},
       "--header-timeout: must be a finite number of seconds in [0.1, 3600], got nan"},
      {{"train", "--data", dir_.string(), "--out", (dir_ / "run").string(), "--rendezvous-timeout", "nan"},
       "--rendezvous-timeout: must be a finite number of seconds in [1, 86400], got nan"}};
  for (const auto& [arguments, message] : cases) {
    const CliRun run = runCli(arguments);
    EXPECT_EQ(run.exit_code, 2) << arguments[0] << ": " << run.output;
    EXPECT_TRUE(contains(run.output, message)) << run.output;
  }
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_ / "earlier"), fs::directory_iterator()), 1);
  EXPECT_FALSE(fs::exists(dir_ / "many"));
  EXPECT_FALSE(fs::exists(dir_ / "new"));
}

// With --port 0 the start said "every client that reaches 127.0.0.1:0", not the port it took.
// A closed terminal (SIGHUP) ended the server without an orderly stop.
TEST_F(Cli, ServeOnAnyPortNamesThePortItTookAndStopsOnSigtermOrSighup) {
  const fs::path scenes = dir_ / "synth";
  ASSERT_EQ(runCli({"synth", "--out", scenes.string(), "--mapping-frames", "4", "--query-frames", "0", "--size",
                    "160x120", "--quiet"}).exit_code, 0);
  const fs::path map = dir_ / "m.ffmap";
  ASSERT_EQ(runCli({"map", "--dataset", (scenes / "scene_000_indoor").string(), "-o", map.string(), "--quiet"}).exit_code, 0);
  // Defaults the API would refuse or ignore are refused at start (an outside probe: --top-k 1000
  // was advertised and the same value in a request refused; --features on classical maps ignored).
  const CliRun top_k = runCli({"serve", "--map", map.string(), "--port", "0", "--top-k", "1000"});
  EXPECT_EQ(top_k.exit_code, 2) << top_k.output;
  EXPECT_TRUE(contains(top_k.output, "error: --top-k: 1000 is more than a request may ask for (100)")) << top_k.output;
  for (const std::vector<std::string> flag : {std::vector<std::string>{"--features", "500"}, {"--selection", "uniform"}}) {
    const CliRun run = runCli({"serve", "--map", map.string(), "--port", "0", flag[0], flag[1]});
    EXPECT_EQ(run.exit_code, 2) << run.output;
    EXPECT_TRUE(contains(run.output, "error: " + flag[0] + ": every map served is a classical map, which does not use it"))
        << run.output;
  }
  for (const int signal_number : {SIGTERM, SIGHUP}) {
    SCOPED_TRACE(signalName(signal_number));
    std::vector<std::string> arguments = {FFLOC_CLI_PATH, "serve", "--map", map.string(), "--port", "0"};
    std::vector<char*> argv;
    for (std::string& argument : arguments) argv.push_back(argument.data());
    argv.push_back(nullptr);
    int pipe_fds[2];
    ASSERT_EQ(pipe(pipe_fds), 0);
    const pid_t pid = fork();
    if (pid == 0) {
      dup2(pipe_fds[1], 2);
      close(pipe_fds[0]);
      execv(argv[0], argv.data());
      _exit(127);
    }
    close(pipe_fds[1]);
    std::string output;
    char buffer[4096];
    for (ssize_t got; !contains(output, "map viewer") && (got = read(pipe_fds[0], buffer, sizeof(buffer))) > 0;)
      output.append(buffer, got);
    kill(pid, signal_number);
    for (ssize_t got; (got = read(pipe_fds[0], buffer, sizeof(buffer))) > 0;) output.append(buffer, got);
    close(pipe_fds[0]);
    int status = 0;
    waitpid(pid, &status, 0);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << output;
    EXPECT_TRUE(contains(output, signalName(signal_number) + ": stopping once the query being localized is answered"))
        << output;
    const size_t at = output.find("listening on http://127.0.0.1:");
    ASSERT_NE(at, std::string::npos) << output;
    const std::string port = output.substr(at + 30, output.find(' ', at + 30) - at - 30);
    EXPECT_NE(port, "0") << output;
    EXPECT_TRUE(contains(output, "every client that reaches 127.0.0.1:" + port + " may use every map")) << output;
  }
}

}  // namespace
}  // namespace ffloc
