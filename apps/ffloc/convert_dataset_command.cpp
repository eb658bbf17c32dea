#include <iostream>
#include <memory>

#include "command_options.h"
#include "commands.h"
#include "ffloc/core/error.h"
#include "ffloc/data/dataset.h"
#include "ffloc/data/dataset_writers.h"

namespace ffloc::cli {
namespace {

struct ConvertDatasetArguments {
  std::string dataset;
  std::string input_format = "auto";
  std::string format;
  std::string out;
};

std::string joined(const std::vector<std::string>& names) {
  std::string text;
  for (const auto& name : names) text += (text.empty() ? "" : ", ") + name;
  return text;
}

void runConvertDataset(const ConvertDatasetArguments& args) {
  checkOutputFolder("--out", args.out);
  const Scene scene = loadDataset(args.dataset, args.input_format);
  writeDataset(scene, args.format, args.out);
  std::cout << "wrote " << args.out << ": " << scene.frames.size() << " frames of " << scene.name << " ("
            << scene.format << ") as " << args.format << " (" << scene.mappingIndices().size() << " mapping, "
            << scene.queryIndices().size() << " query)\n";
  // Documented, but said nowhere else: the copy's arbitrary units were then scored as metres, and
  // its map refused the original's queries as another scene (an outside probe).
  if (!scene.metric && args.format != "manifest") {
    std::cerr << "warning: " << scene.name << " is not metric (arbitrary units), and " << args.format
              << " has no field to say so: it reads back as metric, so its errors print as metres and a map of it "
                 "refuses the original's queries (--format manifest keeps the units)\n";
  }
}

}  // namespace

void registerConvertDatasetCommand(CLI::App& app, CommandRun& run) {
  auto args = std::make_shared<ConvertDatasetArguments>();
  CLI::App* cmd = app.add_subcommand(
      "convert-dataset",
      "Write any dataset ffloc reads in another format (images and depth copied, poses and intrinsics converted "
      "to that format's conventions), so data moves between ffloc and each benchmark's tools. docs/datasets.md "
      "describes every format.");
  cmd->add_option("--dataset", args->dataset, "Dataset folder to read")->required();
  cmd->add_option("--input-format", args->input_format, "Its format: auto, " + joined(datasetFormats()))
      ->capture_default_str();
  cmd->add_option("--format", args->format, "Format to write: " + joined(datasetWriterFormats()))->required();
  cmd->add_option("--out", args->out, "New (or empty) folder to write into")->required()->check(nonEmptyPath());
  cmd->get_option("--dataset")->check(nonEmptyPath());
  cmd->callback([args, &run] {
    run = [args] {
      runConvertDataset(*args);
      return 0;
    };
  });
}

}  // namespace ffloc::cli
