#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>

#include "host/cli/calibrate_command.h"
#include "host/cli/calibrate_intrinsics_command.h"
#include "host/cli/calibrate_lasers_command.h"
#include "host/cli/device_command.h"
#include "host/cli/measure_command.h"
#include "host/cli/exit_status.h"
#include "host/cli/mesh_command.h"
#include "host/cli/peaks_command.h"
#include "host/cli/process_command.h"
#include "host/cli/reconstruct_command.h"
#include "host/cli/sim_command.h"

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
