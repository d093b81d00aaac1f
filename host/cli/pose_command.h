#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

namespace mirrorscan::cli {

// `mirrorscan pose points.ply [--calibration C.json] [--board board.json] [--json]`: the
// pose check of a cloud (host/pose, docs/pose-check.md), as `process` puts it in
// summary.json's "pose".
void AddPoseCommand(CLI::App& app);

// summary.json's "pose" in lines for a person: the figures, then what to say (or that the
// stance is within the protocol).
std::vector<std::string> PoseLines(const nlohmann::json& pose);

}  // namespace mirrorscan::cli
