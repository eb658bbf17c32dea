#include <CLI/CLI.hpp>
#include <iostream>
#include <string>

#include "command_options.h"
#include "commands.h"
#include "ffloc/core/allocator.h"
#include "ffloc/core/crash_report.h"
#include "ffloc/core/error.h"
#include "ffloc/core/utf8.h"

namespace {

// Exit code 2 for bad input, its message on one "error:" line; bytes that are not UTF-8 (a file's
// name) written as \xhh, as the message would not be valid text otherwise.
int badInput(const std::string& message) {
  std::cerr << "error: " << ffloc::escapeInvalidUtf8(message) << "\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  ffloc::installCrashReport("ffloc");
  CLI::App app{"ffloc: visual localization against posed images (classical and FastForward) in C++.\n"
               "Run 'ffloc <command> --help' for the options of each command."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "ffloc 0.1.0");
  // CLI11's own errors ("Could not convert: --max-features = 99999999999") lacked the "error: "
  // that starts every other.
  app.failure_message([](const CLI::App* command, const CLI::Error& error) {
    return "error: " + ffloc::escapeInvalidUtf8(CLI::FailureMessage::simple(command, error));
  });
  ffloc::cli::CommandRun run;
  ffloc::cli::registerEvalCommand(app, run);
  ffloc::cli::registerSynthCommand(app, run);
  ffloc::cli::registerConvertCommand(app, run);
  ffloc::cli::registerConvertDatasetCommand(app, run);
#ifdef FFLOC_WITH_TORCH
  ffloc::cli::registerBenchCommand(app, run);
  ffloc::cli::registerMapCommand(app, run);
  ffloc::cli::registerLocalizeCommand(app, run);
  ffloc::cli::registerRetrievalCommand(app, run);
  ffloc::cli::registerTrainCommand(app, run);
#endif
#ifdef FFLOC_WITH_SERVER
  ffloc::cli::registerServeCommand(app, run);
#endif
  // The arguments after a command's name, where one is named first.
  const bool command_named = argc > 1 && argv[1][0] != '-';
  const std::vector<std::string> command_arguments =
      command_named ? std::vector<std::string>(argv + 2, argv + argc) : std::vector<std::string>();
  // CLI11 said only "A subcommand is required" for a mistyped command.
  if (command_named) {
    std::string commands;
    bool known = false;
    for (const CLI::App* command : app.get_subcommands({})) {
      known = known || command->get_name() == argv[1];
      commands += (commands.empty() ? "" : ", ") + command->get_name();
    }
    if (!known) return badInput("unknown command '" + std::string(argv[1]) + "' (commands: " + commands + ")");
    // CLI11 split "--data ," into no values and went on to take the next flags as paths
    // ("/tmp/--methods: dataset folder not found", or "--out is required" with --out given).
    for (size_t i = 0; i < command_arguments.size(); ++i) {
      const std::string& argument = command_arguments[i];
      if (argument.rfind("--", 0) != 0) continue;
      const size_t equals = argument.find('=');
      const std::string flag = argument.substr(0, equals);
      const std::string value = equals != std::string::npos ? argument.substr(equals + 1)
                                : i + 1 < command_arguments.size() ? command_arguments[i + 1]
                                                                    : std::string();
      if (!value.empty() && value.find_first_not_of(',') == std::string::npos)
        return badInput(flag + ": '" + value + "' holds no value");
      const CLI::Option* option = app.get_subcommand(argv[1])->get_option_no_throw(flag);
      if (option != nullptr && option->get_delimiter() == ',') {
        if (const std::string problem = ffloc::cli::emptyListEntryProblem(value); !problem.empty())
          return badInput(flag + ": " + problem);
      }
    }
    const std::string one_dash = ffloc::cli::oneDashOptionMessage(*app.get_subcommand(argv[1]), command_arguments);
    if (!one_dash.empty()) return badInput(one_dash);
  }
  // Before the command, only --help and --version: CLI11 said "A subcommand is required", or the
  // command's own complaint, for "ffloc --typo eval".
  if (argc > 1 && !command_named) {
    const std::string first = argv[1];
    if (first != "--help" && first != "-h" && first != "--version")
      return badInput(first + ": not an option of 'ffloc'; options go after the command ('ffloc <command> --help' "
                              "lists them)");
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11's own codes (105, 106, ...) would contradict the documented 2 for bad input; --help
    // and --version end here too, with 0.
    if (e.get_exit_code() != 0 && command_named) {
      const std::string unknown = ffloc::cli::unknownOptionMessage(*app.get_subcommand(argv[1]), command_arguments);
      if (!unknown.empty()) return badInput(unknown);
    }
    return app.exit(e) == 0 ? 0 : 2;
  }
  ffloc::configureAllocator();
  try {
    const int code = run ? run() : 0;
    // A result printed to a full disk is lost: say so, not exit 0.
    if (!std::cout.flush()) {
      std::cerr << "error: standard output: write failed; the results printed there are lost\n";
      return 2;
    }
    return code;
  } catch (const ffloc::InputError& e) {
    return badInput(ffloc::cli::withFlagName(e.what()));
  } catch (const std::exception& e) {
    std::cerr << "internal error: " << ffloc::escapeInvalidUtf8(e.what()) << "\n";
    return 3;
  }
}
