#include "host/board/board_json.h"

#include <algorithm>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/config/json_reader.h"

namespace mirrorscan::host_board {

reconstruction::BoundingCylinder BoundingCylinderFromBoard(
    const std::filesystem::path& board_json) {
  const nlohmann::json json = JsonReader::ParseFile(board_json);
  const JsonReader root(json, board_json.string());
  reconstruction::BoundingCylinder c;
  if (!root.Has("reconstruction")) return c;
  const JsonReader r = root.Object("reconstruction");
  r.AllowOnly({"bounding_cylinder"});
  if (!r.Has("bounding_cylinder")) return c;
  const JsonReader b = r.Object("bounding_cylinder");
  b.AllowOnly({"radius_mm", "core_radius_mm", "bottom_mm", "top_mm", "center_mm"});
  c.radius_mm = b.Number("radius_mm", c.radius_mm, 1.0, 1e5);
  c.core_radius_mm = b.Number("core_radius_mm", std::min(c.core_radius_mm, c.radius_mm), 1.0, 1e5);
  if (c.core_radius_mm > c.radius_mm) b.Fail("core_radius_mm", "must not exceed radius_mm");
  c.bottom_mm = b.Number("bottom_mm", c.bottom_mm, -1e5, 1e5);
  c.top_mm = b.Number("top_mm", c.top_mm, -1e5, 1e5);
  if (c.top_mm <= c.bottom_mm) b.Fail("top_mm", "must be above bottom_mm");
  const std::vector<double> center = b.Numbers("center_mm", 2, std::vector<double>{0.0, 0.0});
  c.center_mm = {center[0], center[1]};
  return c;
}

}  // namespace mirrorscan::host_board
