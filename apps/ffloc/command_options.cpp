#include "command_options.h"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include "ffloc/core/error.h"
#include "ffloc/core/file_paths.h"
#include "ffloc/core/text_file_writer.h"
#include "ffloc/io/input_file.h"
#include "ffloc/io/map_file.h"
#include "ffloc/data/format_io.h"

namespace ffloc::cli {
std::string withFlagName(const std::string& message) {
  static const std::map<std::string, std::string> flags = {
      {"top_k", "--top-k"},
      {"num_features", "--features"},
      {"preset", "--preset"},
      {"selection", "--selection"},
      {"retrieval", "--retrieval"},
      {"method", "--method"},
      {"methods", "--methods"},
      {"pnp.inlier_threshold_px", "--inlier-threshold"},
      {"pnp.confidence_threshold", "--confidence-threshold"},
      {"pnp.max_correspondences", "--max-correspondences"},
      {"pnp.solver", "--solver"},
      {"max_image_size", "--max-image-size"},
      {"max_features", "--max-features"},
      {"use_depth", "--no-depth"},
      {"vlad", "--vlad"},
      {"model", "--model"},
      {"dtype", "--dtype"},
      {"kind", "--kind"},
      {"width, height", "--size"},
      {"mapping_frames", "--mapping-frames"},
      {"query_frames", "--query-frames"},
      {"min_fov_deg, max_fov_deg", "--min-fov, --max-fov"},
      {"image_noise", "--image-noise"},
      {"depth_noise", "--depth-noise"},
      {"format", "--format"},
      {"protocol", "--protocol"},
      {"distortion", "--distortion"}};
  // Library options a message points to as the remedy, and the command that sets them.
  static const std::map<std::string, std::string> remedies = {{"MappingOptions::vlad", "'ffloc map --vlad'"}};
  std::string translated = message;
  for (const auto& [option, command] : remedies)
    if (const size_t at = translated.find(option); at != std::string::npos) translated.replace(at, option.size(), command);
  const size_t colon = translated.find(':');
  if (colon == std::string::npos) return translated;
  const auto flag = flags.find(translated.substr(0, colon));
  return flag == flags.end() ? translated : flag->second + translated.substr(colon);
}

const std::map<std::string, std::string>& methodSettingOfFlag() {
  static const std::map<std::string, std::string> setting_of_flag = {
      {"--model", "model"},         {"--dtype", "dtype"},         {"--features", "features"},
      {"--selection", "selection"}, {"--retrieval", "retrieval"}, {"--no-verify", "verify"},
      {"--no-pose-guided", "pose_guided"}, {"--top-k", "top_k"},    {"--preset", "preset"}};
  return setting_of_flag;
}

std::string emptyListEntryProblem(const std::string& value) {
  if (value.empty() || (value.front() != ',' && value.back() != ',' && value.find(",,") == std::string::npos)) return "";
  return "'" + value + "' has an empty entry";
}

std::vector<std::string> flagsGiven(const CLI::App& command, const std::map<std::string, std::string>& flags) {
  std::vector<std::string> given;
  for (const auto& [flag, meaning] : flags)
    if (const CLI::Option* option = command.get_option_no_throw(flag); option != nullptr && option->count() > 0)
      given.push_back(flag);
  return given;
}

CLI::Validator threadCountRange() {
  return CLI::Validator(
      [](const std::string& input) -> std::string {
        int64_t threads = 0;
        if (!CLI::detail::lexical_cast(input, threads)) return "expected an integer, got " + input;
        return threadCountProblem(threads);
      },
      "0 to " + std::to_string(kMaxThreads));
}

CLI::Validator nonEmptyPath() {
  return CLI::Validator([](const std::string& input) { return input.empty() ? "the path is empty" : ""; }, "PATH");
}

CLI::Validator wholeNumber() {
  constexpr uint64_t kLargest = static_cast<uint64_t>(std::numeric_limits<int64_t>::max());
  return CLI::Validator(
      [](const std::string& input) {
        uint64_t value = 0;
        const char* end = input.data() + input.size();
        const auto [stop, error] = std::from_chars(input.data(), end, value);
        if (input.empty() || stop != end || error != std::errc() || value > kLargest)
          return "expected an integer in [0, " + std::to_string(kLargest) + "], got '" + input + "'";
        return std::string();
      },
      "0 to " + std::to_string(kLargest));
}

namespace {

// Insertions, deletions, substitutions and swaps of neighbours ("--prot" is one from "--port").
size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i)
    for (size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// The options of a command and of the subcommands named after it ("ffloc bench model"), and
// which of the arguments are options rather than their values.
struct CommandOptions {
  std::string full_name;                  // "bench model"
  std::map<std::string, bool> long_names;  // each long option: whether its next argument is its value
  std::map<char, bool> short_names;       // the same for each one-letter option

  CommandOptions(const CLI::App& command, const std::vector<std::string>& arguments) : full_name(command.get_name()) {
    size_t next_argument = 0;
    for (const CLI::App* current = &command; current != nullptr;) {
      for (const CLI::Option* option : current->get_options()) {
        const bool takes_value = option->get_expected_min() > 0;
        for (const std::string& name : option->get_lnames()) long_names.emplace(name, takes_value);
        for (const std::string& name : option->get_snames()) short_names.emplace(name[0], takes_value);
      }
      const CLI::App* named = nullptr;
      for (; next_argument < arguments.size() && named == nullptr; ++next_argument)
        for (const CLI::App* subcommand : current->get_subcommands({}))
          if (subcommand->get_name() == arguments[next_argument]) named = subcommand;
      if (named != nullptr) full_name += " " + named->get_name();
      current = named;
    }
  }

  // The arguments before "--" that are not the value of the option before them ("--out --dir"
  // writes to "--dir", "-o -quiet" to "-quiet").
  std::vector<std::string> optionsAndOperands(const std::vector<std::string>& arguments) const {
    std::vector<std::string> kept;
    bool is_value = false;
    for (const std::string& argument : arguments) {
      if (argument == "--") break;  // what follows is not options
      const bool was_value = is_value;
      is_value = false;
      if (was_value) continue;
      kept.push_back(argument);
      if (argument.rfind("--", 0) == 0) {
        const auto known = long_names.find(argument.substr(2));  // "--name=value" carries its value
        is_value = known != long_names.end() && known->second;
      } else if (argument.size() == 2 && argument[0] == '-') {
        const auto known = short_names.find(argument[1]);  // "-ofile" carries its value
        is_value = known != short_names.end() && known->second;
      }
    }
    return kept;
  }
};

// A word of one dash and at least two letters ("-dataset", "-ofile.ffmap"), not a number ("-1").
bool isOneDashWord(const std::string& argument) {
  return argument.size() > 2 && argument[0] == '-' && std::isalpha(static_cast<unsigned char>(argument[1]));
}

// The long option name `argument` is, typed with one dash ("-dataset"); empty otherwise.
std::string oneDashLongName(const CommandOptions& options, const std::string& argument) {
  if (!isOneDashWord(argument)) return "";
  const std::string name = argument.substr(1, argument.find('=') - 1);
  // "-help" is CLI11's "-h elp": help, as typed.
  return name != "help" && options.long_names.count(name) > 0 ? name : "";
}

}  // namespace

std::string oneDashOptionMessage(const CLI::App& command, const std::vector<std::string>& arguments) {
  const CommandOptions options(command, arguments);
  for (const std::string& argument : options.optionsAndOperands(arguments))
    if (const std::string name = oneDashLongName(options, argument); !name.empty())
      return "-" + name + ": options take two dashes; did you mean --" + name + "?";
  return "";
}

std::string unknownOptionMessage(const CLI::App& command, const std::vector<std::string>& arguments) {
  const CommandOptions options(command, arguments);
  for (const std::string& argument : options.optionsAndOperands(arguments)) {
    // One dash: CLI11 reads "-methds" as short options and then says another argument was not
    // expected. "-ofile.ffmap" is a short option with its value.
    const bool one_dash = isOneDashWord(argument);
    if (argument.rfind("--", 0) != 0 && !(one_dash && options.short_names.count(argument[1]) == 0)) continue;
    const size_t dashes = one_dash ? 1 : 2;
    const std::string name = argument.substr(dashes, argument.find('=') - dashes);
    if (options.long_names.count(name) > 0) continue;  // one-dash ones are refused before parsing
    // One typing slip in a short name, two in a longer one, or a name the option's begins with
    // ("--method" for "--methods"); every option at the least distance, in alphabetical order.
    std::vector<std::string> nearest;
    size_t nearest_distance = name.size() <= 4 ? 1 : 2;
    for (const auto& [option, ignored] : options.long_names) {
      if (name.empty()) break;  // "--=x": every name begins so
      const size_t distance = option.rfind(name, 0) == 0 ? 1 : editDistance(name, option);
      if (distance > nearest_distance) continue;
      if (distance < nearest_distance) nearest.clear();
      nearest_distance = distance;
      nearest.push_back(option);
    }
    if (one_dash && nearest.empty()) continue;  // left to CLI11
    std::string message = std::string(dashes, '-') + name + ": not an option of 'ffloc " + options.full_name + "'";
    if (one_dash) message += " (options take two dashes)";
    if (nearest.empty()) return message + " (ffloc " + options.full_name + " --help lists them)";
    message += nearest.size() == 1 ? "; did you mean " : "; did you mean one of ";
    for (size_t i = 0; i < nearest.size(); ++i) message += (i == 0 ? "--" : ", --") + nearest[i];
    return message + "?";
  }
  return "";
}

CLI::Validator atLeast(int64_t minimum) {
  return CLI::Validator(
      [minimum](const std::string& input) -> std::string {
        int64_t value = 0;
        if (CLI::detail::lexical_cast(input, value) && value >= minimum) return "";
        return "must be an integer of at least " + std::to_string(minimum) + ", got " + input;
      },
      ">= " + std::to_string(minimum));
}

CLI::Validator secondsIn(double least, double most) {
  return CLI::Validator(
      [least, most](const std::string& input) -> std::string {
        double seconds = 0;
        if (CLI::detail::lexical_cast(input, seconds) && std::isfinite(seconds) && seconds >= least && seconds <= most)
          return "";
        std::ostringstream bound;
        if (std::isinf(most))
          bound << ", at least " << least;
        else
          bound << " in [" << least << ", " << most << "]";
        return "must be a finite number of seconds" + bound.str() + ", got " + input;
      },
      "SECONDS");
}

void checkOutputPath(const std::string& flag, const std::string& path) {
  if (path.empty()) return;
  const std::filesystem::path target(path);
  // /dev/null, /dev/stdout, a pipe: written through, whatever their folder allows.
  if (writesThrough(target)) {
    if (!openDescriptorNamed(target) && access(path.c_str(), W_OK) != 0)
      throw InputError(flag + ": '" + path + "' is not writable");
    return;
  }
  // The error_code overloads: a folder on the way that may not be searched, or a name too long,
  // is the user's input, not an internal error.
  std::error_code error;
  if (std::filesystem::is_directory(target, error)) throw InputError(flag + ": '" + path + "' is a folder; give a file name");
  const std::filesystem::path folder = target.has_parent_path() ? target.parent_path() : ".";
  if (!std::filesystem::is_directory(folder, error))
    throw InputError(flag + ": '" + path + "': folder '" + folder.string() + "' " +
                     (error && error != std::errc::no_such_file_or_directory ? "cannot be reached: " + error.message()
                                                                             : std::string("does not exist")));
  if (const std::string problem = folderWriteProblem(folder); !problem.empty())
    throw InputError(flag + ": '" + path + "': folder '" + folder.string() + "' " + problem);
}

void checkOutputFolder(const std::string& flag, const std::string& path) {
  try {
    requireEmptyOutputFolder(path);
  } catch (const InputError& e) {
    throw InputError(flag + ": " + e.what());
  }
}

void addQueryOptions(CLI::App& command, QueryArguments& args) {
  command.add_option("--preset", args.preset, "indoor (K=10, N=1500) or outdoor (K=20, N=3000)")->capture_default_str();
  args.top_k_option = command.add_option("--top-k", args.top_k, "Mapping images per query (overrides the preset)");
  args.features_option =
      command.add_option("--features", args.features, "fastforward: map tokens per query (overrides the preset)");
  command.add_option("--seed", args.seed, "Seed of RANSAC, the token sampling and random selection")
      ->check(wholeNumber())
      ->capture_default_str();
  command.add_option("--selection", args.selection, "fastforward: mapping image selection: retrieval, uniform or random")
      ->capture_default_str();
  command.add_option("--retrieval", args.retrieval,
                     "fastforward: what retrieval ranks the mapping images by: encoder (pooled tokens), vlad (the "
                     "classical descriptor; the map must have been built with --vlad) or token-vlad (a VLAD of the "
                     "encoder's tokens, its vocabulary learned from the map's tokens when the map was built)")
      ->capture_default_str();
  command.add_option("--solver", args.solver, "PnP-RANSAC solver: lo-ransac or opencv-usac")->capture_default_str();
  command.add_flag("--no-verify", args.no_verify,
                   "fastforward: skip the second prediction behind the verdict (then a half-sample RANSAC estimate "
                   "stands in; about half the latency)");
  command.add_flag("--no-pose-guided", args.no_pose_guided,
                   "classical: when the first pose is not localized, do not look again (at the mapping images it "
                   "sees, then at looser matches it places near their keypoints)");
}

LocalizeOptions localizeOptions(const QueryArguments& args) {
  QuerySettings settings;
  settings.preset = args.preset;
  if (args.top_k_option && args.top_k_option->count() > 0) settings.top_k = args.top_k;
  if (args.features_option && args.features_option->count() > 0) settings.features = args.features;
  settings.seed = args.seed;
  settings.selection = args.selection;
  settings.retrieval = args.retrieval;
  settings.solver = args.solver;
  settings.verify = !args.no_verify;
  settings.pose_guided = !args.no_pose_guided;
  return ffloc::localizeOptions(settings);
}

void refuseOutputOverInputs(const std::string& flag, const std::string& path,
                            const std::vector<std::pair<std::string, std::string>>& inputs,
                            const std::vector<std::string>& datasets) {
  if (path.empty()) return;
  for (const auto& [what, input] : inputs)
    if (!input.empty() && sameFolderKey(path) == sameFolderKey(input))
      throw InputError(flag + ": '" + path + "' is " + what + "; write it elsewhere");
  for (const std::string& dataset : datasets)
    if (!dataset.empty() && liesWithin(path, dataset))
      throw InputError(flag + ": '" + path + "' is inside the dataset '" + dataset +
                       "', whose files it could replace; write it elsewhere");
  // Another map than the one in use: a pose list or a CSV written over it replaced hours of
  // mapping without a word.
  std::error_code error;
  if (std::filesystem::is_regular_file(path, error) && isMapFile(path))
    throw InputError(flag + ": '" + path + "' is an ffloc map, which this output would replace; write it elsewhere");
}

std::filesystem::path sameFolderKey(const std::string& path) {
  // A pipe's path (bash's >(cat) is /dev/fd/63, a link to "pipe:[N]") has no canonical form: it
  // threw, an internal error; it is compared as given.
  std::error_code error;
  std::filesystem::path canonical = std::filesystem::weakly_canonical(path, error);
  if (error) canonical = std::filesystem::absolute(path, error).lexically_normal();
  // weakly_canonical keeps a trailing separator: "d/" would differ from "d".
  return canonical.has_filename() ? canonical : canonical.parent_path();
}

}  // namespace ffloc::cli
