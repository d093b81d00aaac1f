#include <cstdio>
#include <exception>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "host/cli/calibrate_command.h"
#include "host/cli/calibrate_intrinsics_command.h"
#include "host/cli/calibrate_lasers_command.h"
#include "host/cli/device_command.h"
#include "host/cli/exit_status.h"
#include "host/cli/measure_command.h"
#include "host/cli/mesh_command.h"
#include "host/cli/peaks_command.h"
#include "host/cli/pose_command.h"
#include "host/cli/process_command.h"
#include "host/cli/reconstruct_command.h"
#include "host/cli/sim_command.h"

namespace {

// CLI11 answers --help before it notices an unknown subcommand, so `mirrorscan nosuch
// --help` would print the main help and succeed. Walks the leading command words and
// names the first that is not a command of the one before it.
std::optional<std::string> UnknownCommand(CLI::App& app, int argc, char** argv) {
  CLI::App* current = &app;
  std::string path = "mirrorscan";
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (word.empty() || word[0] == '-') return std::nullopt;  // options: CLI11's to parse
    CLI::App* next = nullptr;
    // (Option groups are nameless subcommands: not commands.)
    const auto commands =
        current->get_subcommands([](CLI::App* a) { return !a->get_name().empty(); });
    if (commands.empty()) return std::nullopt;  // the command's own arguments
    for (CLI::App* command : commands) {
      if (command->check_name(word)) next = command;
    }
    if (next == nullptr) {
      return "unknown command \"" + word + "\" (see " + path + " --help)";
    }
    current = next;
    path += " " + word;
  }
  return std::nullopt;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"mirrorscan: host tools for the mirrorscan body scanner"};
  app.require_subcommand(1);
  mirrorscan::cli::AddSimCommands(app);
  mirrorscan::cli::AddPeaksCommand(app);
  mirrorscan::cli::AddCalibrateCommand(app);
  mirrorscan::cli::AddCalibrateIntrinsicsCommand(app);
  mirrorscan::cli::AddCalibrateLasersCommand(app);
  mirrorscan::cli::AddReconstructCommand(app);
  mirrorscan::cli::AddDeviceCommands(app);
  mirrorscan::cli::AddMeasureCommand(app);
  mirrorscan::cli::AddMeshCommand(app);
  mirrorscan::cli::AddProcessCommand(app);
  mirrorscan::cli::AddPoseCommand(app);
  if (const auto unknown = UnknownCommand(app, argc, argv)) {
    std::fprintf(stderr, "mirrorscan: %s\n", unknown->c_str());
    return mirrorscan::cli::kExitUsage;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help is a success; every other command-line error is a usage error.
    return app.exit(e) == 0 ? 0 : mirrorscan::cli::kExitUsage;
  } catch (const mirrorscan::cli::CommandExit& e) {
    std::fprintf(stderr, "mirrorscan: %s\n", e.what());
    return e.status();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mirrorscan: %s\n", e.what());
    return 1;
  }
  return 0;
}
