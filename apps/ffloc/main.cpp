#include <CLI/CLI.hpp>
#include <iostream>

#include "commands.h"
#include "ffloc/core/error.h"

namespace ffloc::cli {

int& exitCode() {
  static int code = 0;
  return code;
}

}  // namespace ffloc::cli

int main(int argc, char** argv) {
  CLI::App app{"ffloc: feed-forward visual localization (FastForward) in C++.\n"
               "Run 'ffloc <command> --help' for the options of each command."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "ffloc 0.1.0");
  ffloc::cli::registerEvalCommand(app);
  ffloc::cli::registerSynthCommand(app);
  ffloc::cli::registerConvertCommand(app);
  ffloc::cli::registerConvertDatasetCommand(app);
#ifdef FFLOC_WITH_TORCH
  ffloc::cli::registerBenchCommand(app);
  ffloc::cli::registerMapCommand(app);
  ffloc::cli::registerLocalizeCommand(app);
  ffloc::cli::registerRetrievalCommand(app);
  ffloc::cli::registerTrainCommand(app);
#endif
#ifdef FFLOC_WITH_SERVER
  ffloc::cli::registerServeCommand(app);
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const ffloc::InputError& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "internal error: " << e.what() << "\n";
    return 3;
  }
  return ffloc::cli::exitCode();
}
