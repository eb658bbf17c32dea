#pragma once

#include <CLI/CLI.hpp>

namespace ffloc::cli {

// Each subcommand lives in its own <name>_command.cpp and registers itself here; the callback
// it installs runs the command and sets the process exit code through exitCode().
void registerEvalCommand(CLI::App& app);
void registerSynthCommand(CLI::App& app);
void registerConvertCommand(CLI::App& app);
void registerConvertDatasetCommand(CLI::App& app);
#ifdef FFLOC_WITH_TORCH  // these need the network module
void registerBenchCommand(CLI::App& app);
void registerMapCommand(CLI::App& app);
void registerLocalizeCommand(CLI::App& app);
void registerRetrievalCommand(CLI::App& app);
void registerTrainCommand(CLI::App& app);
#endif
#ifdef FFLOC_WITH_SERVER  // the network and cpp-httplib
void registerServeCommand(CLI::App& app);
#endif

int& exitCode();

}  // namespace ffloc::cli
