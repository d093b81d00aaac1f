#pragma once
// The host's reading of a board.json (docs/boards.md): the sections only the PC uses, which
// the firmware (firmware/board) passes over. The reconstruction's bounding cylinder lives
// here rather than in common/config because only the host reconstructs: the ARM build has
// no use for it, and common/ cannot name the host's types.
#include <filesystem>

#include "host/reconstruction/bounding_cylinder.h"

namespace mirrorscan::host_board {

// From board.json's optional "reconstruction": {"bounding_cylinder": {"radius_mm",
// "core_radius_mm", "bottom_mm", "top_mm", "center_mm"}}; defaults for missing keys.
// ConfigError naming the file and key on a bad value.
reconstruction::BoundingCylinder BoundingCylinderFromBoard(const std::filesystem::path& board_json);

}  // namespace mirrorscan::host_board
