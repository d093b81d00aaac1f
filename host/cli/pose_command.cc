#include "host/cli/pose_command.h"

#include <cstdio>
#include <memory>
#include <string>

#include "common/config/calibration.h"
#include "common/config/json_reader.h"
#include "common/mesh/cloud_io.h"
#include "host/board/board_json.h"
#include "host/cli/exit_status.h"
#include "host/pose/pose_check.h"

namespace mirrorscan::cli {
namespace {

struct PoseCommandOptions {
  std::string cloud, calibration, board;
  bool json = false;
};

std::string Figure(const nlohmann::json& value, const char* unit) {
  if (!value.is_number()) return "not measured";
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f %s", value.get<double>(), unit);
  return text;
}

// The cabinet's reach from the calibration and the board, either optional.
pose::CabinetReach Reach(const PoseCommandOptions& o) {
  host_board::BoardReach board;
  if (!o.board.empty()) board = host_board::ReachFromBoard(o.board);
  if (o.calibration.empty()) {
    pose::CabinetReach reach;
    reach.mirror_top_mm = board.mirror_top_mm;
    return reach;
  }
  return pose::ReachOf(Calibration::Load(o.calibration), board.sweep_end_mm, board.mirror_top_mm);
}

void Run(const PoseCommandOptions& o) {
  PointCloud cloud;
  pose::PoseOptions options;
  try {
    cloud = ReadPointCloud(o.cloud);
    options.reach = Reach(o);
  } catch (const MeshIoError& e) {
    throw CommandExit(kExitUsage, e.what());
  } catch (const ConfigError& e) {
    throw CommandExit(kExitUsage, e.what());
  }
  const nlohmann::json json = pose::ToJson(pose::CheckPose(cloud, options), options);
  if (o.json) {
    std::printf("%s\n", json.dump(2).c_str());
    return;
  }
  for (const std::string& line : PoseLines(json)) std::printf("%s\n", line.c_str());
}

}  // namespace

std::vector<std::string> PoseLines(const nlohmann::json& pose) {
  std::vector<std::string> lines;
  if (pose.value("checked", false)) {
    const nlohmann::json& arms = pose["arm_abduction_deg"];
    lines.push_back("feet " + Figure(pose["feet_spread_mm"], "mm") + " apart (legs " +
                    Figure(pose["hip_spread_mm"], "mm") + " apart at the hips); arms " +
                    Figure(arms["left"], "deg") + " left, " + Figure(arms["right"], "deg") +
                    " right; yaw " + Figure(pose["yaw_deg"], "deg") + "; lean " +
                    Figure(pose["lean_deg"], "deg") + "; head turn " +
                    Figure(pose["head_turn_deg"], "deg") + "; top of the head " +
                    Figure(pose["head_top_mm"], "mm") + " (cabinet reach " +
                    Figure(pose["reach_mm"], "mm") + ")");
  } else {
    lines.push_back("not checked: " + pose.value("reason", std::string()));
  }
  if (pose.value("within_protocol", false)) {
    lines.push_back("within the standard scanning posture");
  } else {
    for (const auto& advice : pose["advice"]) lines.push_back("say: " + advice.get<std::string>());
  }
  return lines;
}

void AddPoseCommand(CLI::App& app) {
  auto options = std::make_shared<PoseCommandOptions>();
  auto* cmd = app.add_subcommand(
      "pose",
      "How the person stood, from a scan's cloud, against the standard scanning posture, and "
      "what to say for a rescan (as summary.json's \"pose\")");
  cmd->add_option("cloud", options->cloud, "points.ply (world frame, mm)")->required();
  cmd->add_option("--calibration", options->calibration,
                  "calibration.json (the mirrors' top, the lasers) for the cabinet's reach");
  cmd->add_option("--board", options->board, "board.json (the sweep's end) for the reach");
  cmd->add_flag("--json", options->json, "print the pose as JSON");
  cmd->callback([options] { Run(*options); });
}

}  // namespace mirrorscan::cli
