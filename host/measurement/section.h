#pragma once

#include <vector>

#include <Eigen/Core>

#include "common/mesh/triangle_mesh.h"

namespace mirrorscan::measurement {

// The mesh with vertices at the same position merged (a triangle soup stores every
// triangle's corners apart), so that sections can follow edges from triangle to triangle.
TriangleMesh WeldVertices(const TriangleMesh& mesh);

// One chain of a plane section, in the plane's coordinates. A closed loop went all the
// way round; an open chain ended at a border of the mesh: a hole crosses the section.
struct SectionLoop {
  std::vector<Eigen::Vector2d> points;
  bool closed = false;
};

// A body part's section: loops that overlap or contain one another (one surface's
// loop, or the overlapping solids of one limb and what it is buried in), and any open
// chain lying among them.
struct SectionPart {
  std::vector<int> loops;             // indices into Section::loops
  std::vector<Eigen::Vector2d> hull;  // convex hull, counter-clockwise
  double tape_mm = 0.0;               // perimeter of the hull: what a tape measures
  double contour_mm = 0.0;            // the followed outline, into the hollows
  double area_mm2 = 0.0;              // of the hull
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();  // of the hull
  bool has_hole = false;                               // an open chain belongs to it
  // A holed part whose open chains could be joined end to end into one outline by smooth
  // bridges (cubic curves leaving and entering each chain along its own direction): the
  // hull, tape, contour and area then include them. bridged_mm is their summed length,
  // largest_bridge_mm the longest; 0 when nothing was bridged.
  bool bridged = false;
  double bridged_mm = 0.0, largest_bridge_mm = 0.0;

  bool Contains(const Eigen::Vector2d& p) const;      // inside the hull
  double DistanceTo(const SectionPart& other) const;  // between hulls, 0 when they meet
};

// A plane section of a mesh: point p of the plane is origin + x e1 + y e2.
struct Section {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitX(), e2 = Eigen::Vector3d::UnitY();
  std::vector<SectionLoop> loops;
  std::vector<SectionPart> parts;  // largest area first

  Eigen::Vector3d ToWorld(const Eigen::Vector2d& p) const {
    return origin + p.x() * e1 + p.y() * e2;
  }
};

// Sections of one mesh; horizontal ones use a height index of the triangles.
class Slicer {
 public:
  explicit Slicer(TriangleMesh mesh);

  const TriangleMesh& mesh() const { return mesh_; }
  // The section by the horizontal plane at z, in world x and y. A vertex exactly on the
  // plane counts as above it, so the section is that of the plane an instant lower.
  // Without `join_holes` open chains are neither joined nor bridged (SectionPart): an open
  // chain is one part with what lies within 20 mm of it, as where a hole hides whether two
  // limbs meet (the crotch), a bridge must not decide it.
  Section AtHeight(double z, bool join_holes = true) const;
  // The section by the plane through `origin` with normal `normal`.
  Section ByPlane(const Eigen::Vector3d& origin, const Eigen::Vector3d& normal) const;

 private:
  Section Cut(const std::vector<int>& triangles, const Eigen::Vector3d& origin,
              const Eigen::Vector3d& normal, const Eigen::Vector3d& e1, const Eigen::Vector3d& e2,
              bool join_holes) const;

  TriangleMesh mesh_;
  double z_min_ = 0.0, bucket_mm_ = 10.0;
  std::vector<std::vector<int>> buckets_;  // triangles spanning each z bucket
};

// Parameters t along origin + t direction where the line crosses the mesh, with +1 where
// it leaves a triangle's outside (along its normal) and -1 where it enters, sorted by t.
struct LineCrossing {
  double t;
  int sign;
};
std::vector<LineCrossing> CrossLine(const TriangleMesh& mesh, const Eigen::Vector3d& origin,
                                    const Eigen::Vector3d& direction);

}  // namespace mirrorscan::measurement
