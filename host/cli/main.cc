#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>

#include "host/cli/calibrate_command.h"
#include "host/cli/calibrate_intrinsics_command.h"
#include "host/cli/calibrate_lasers_command.h"
#include "host/cli/device_command.h"
#include "host/cli/peaks_command.h"
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
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mirrorscan: %s\n", e.what());
    return 1;
  }
  return 0;
}
