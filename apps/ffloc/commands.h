#pragma once

#include <CLI/CLI.hpp>

namespace ffloc::cli {

// Each subcommand lives in its own <name>_command.cpp and registers itself here; the callback
// it installs runs the command and sets the process exit code through exitCode().
void registerEvalCommand(CLI::App& app);
void registerSynthCommand(CLI::App& app);
void registerConvertCommand(CLI::App& app);
#ifdef FFLOC_WITH_TORCH
void registerBenchCommand(CLI::App& app);  // needs the network module
#endif

int& exitCode();

}  // namespace ffloc::cli
