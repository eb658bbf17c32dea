#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

#include "ffloc/core/threads.h"

#include "ffloc/localization/localizer.h"

namespace ffloc::cli {

// The query options every localizing command shares (--preset, --top-k, --features, --seed,
// --selection, --retrieval, --solver, --no-verify, --no-pose-guided), declared once and turned into the
// library's LocalizeOptions, whose check() names the library field.
struct QueryArguments {
  std::string preset = "indoor";
  int64_t top_k = 0;     // the preset's unless given
  int64_t features = 0;  // the preset's unless given
  const CLI::Option* top_k_option = nullptr;
  const CLI::Option* features_option = nullptr;
  uint64_t seed = 0;
  std::string selection = "retrieval";
  std::string retrieval = "token-vlad";
  std::string solver = "lo-ransac";
  bool no_verify = false;
  bool no_pose_guided = false;
};
void addQueryOptions(CLI::App& command, QueryArguments& args);
LocalizeOptions localizeOptions(const QueryArguments& args);

// The flags of settings one localization method alone uses (methodUsesSetting), with the
// setting each sets: a flag of a method that does not run was ignored without a word (a model
// path that does not exist, on a classical map).
const std::map<std::string, std::string>& methodSettingOfFlag();
// The flags among the keys of `flags` given on `command`'s line; one the command lacks (a build
// without libtorch has no --model) is not given.
std::vector<std::string> flagsGiven(const CLI::App& command, const std::map<std::string, std::string>& flags);

// Every --threads flag: 0 (all hardware threads) to kMaxThreads (core/threads.h), checked while
// the command line is parsed.
CLI::Validator threadCountRange();

// For a flag that names a file or folder: an empty value reached the file system as "", whose
// error named nothing ("error: : Invalid argument").
CLI::Validator nonEmptyPath();

// For a file the run writes at its end (`flag` names it in the error): its folder must exist and
// be writable, and the path must not be a folder, checked before the run, which found either only after every
// query had run. Empty: not asked for, nothing to check.
void checkOutputPath(const std::string& flag, const std::string& path);

// For a folder the run fills (synth, convert-dataset): it must be new or empty, checked before the
// run (requireEmptyOutputFolder), and the error names `flag`.
void checkOutputFolder(const std::string& flag, const std::string& path);

// For a flag read into an unsigned integer (seeds, counts): decimal digits only, at most 2^63 - 1
// (the server's bound on the same fields). CLI11 alone reads "-1" as 2^64 - 1, saturates a longer
// number without a word, takes "" as 0 and "0x10" as 16.
CLI::Validator wholeNumber();
// "'a,,b' has an empty entry" when a comma-separated `value` has one (CLI11 dropped it without a
// word: "oracle-depth,,classical" ran two methods), else "".
std::string emptyListEntryProblem(const std::string& value);

// The first argument of `arguments` (what follows the command's name) that looks like a long option
// `command` does not have, named with the command's option it most likely meant: "--methds: not
// an option of 'ffloc eval'; did you mean --methods?". Empty when every one is known. CLI11 said
// "The following arguments were not expected: classical --methds", or, for a mistyped required
// option, only that the required one is missing. A one-dash word near a long option is named the
// same way ("-methds"), unless it begins with a short option's letter ("-ofile.ffmap").
std::string unknownOptionMessage(const CLI::App& command, const std::vector<std::string>& arguments);

// The first argument that is one of `command`'s long options typed with one dash ("-output"),
// not an option's value: "-output: options take two dashes; did you mean --output?". Checked
// before parsing, as CLI11 reads "-output" as "-o utput" and writes the map to ./utput.
std::string oneDashOptionMessage(const CLI::App& command, const std::vector<std::string>& arguments);

// For an integer count: "must be at least 1, got 0", where CLI11's PositiveNumber said "Value 0
// not in range 0.000000 to 1797...", the largest double in full.
CLI::Validator atLeast(int64_t minimum);

// For a duration in seconds: finite and in [least, most] (`most` infinite: no upper bound).
// CLI11's Range and NonNegativeNumber take "nan", whose comparisons all fail: a NaN time budget
// never ran out.
CLI::Validator secondsIn(double least, double most);

// An error message that starts with a library option field ("top_k: ...") with the field
// replaced by its flag ("--top-k: ..."): main() says every InputError this way.
std::string withFlagName(const std::string& message);

// The folder `path` names, however it is spelled ("d", "d/", "x/../d", a link to d), for telling
// whether two flags name the same dataset.
std::filesystem::path sameFolderKey(const std::string& path);

// InputError when the output `path` of `flag` is one of the command's `inputs` (what it is, its
// path), lies inside one of its `datasets`, whose files it could replace, or is another ffloc
// map: a report given the map's path replaced the map, exit 0.
void refuseOutputOverInputs(const std::string& flag, const std::string& path,
                            const std::vector<std::pair<std::string, std::string>>& inputs,
                            const std::vector<std::string>& datasets = {});

}  // namespace ffloc::cli
