#pragma once

#include <functional>

#include <CLI/CLI.hpp>

namespace ffloc::cli {

// A command's work, chosen while the arguments are parsed and run by main afterwards; it returns
// the process exit code (0 success, 1 a query not localized, 2 bad input).
using CommandRun = std::function<int()>;

// Each subcommand lives in its own <name>_command.cpp and registers itself here; its callback
// stores its work in `run`.
void registerEvalCommand(CLI::App& app, CommandRun& run);
void registerSynthCommand(CLI::App& app, CommandRun& run);
void registerConvertCommand(CLI::App& app, CommandRun& run);
void registerConvertDatasetCommand(CLI::App& app, CommandRun& run);
#ifdef FFLOC_WITH_TORCH  // these need the network module
void registerBenchCommand(CLI::App& app, CommandRun& run);
void registerMapCommand(CLI::App& app, CommandRun& run);
void registerLocalizeCommand(CLI::App& app, CommandRun& run);
void registerRetrievalCommand(CLI::App& app, CommandRun& run);
void registerTrainCommand(CLI::App& app, CommandRun& run);
#endif
#ifdef FFLOC_WITH_SERVER  // the network and cpp-httplib
void registerServeCommand(CLI::App& app, CommandRun& run);
#endif

}  // namespace ffloc::cli
