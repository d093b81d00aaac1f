#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

namespace mirrorscan::measurement {

// The top of a head from the seen surface of its cap, where a scan leaves the top itself
// unseen (docs/measurement.md, When a value is withheld). The cap is taken as an
// ellipsoid with a vertical axis, turned about it, whose front and back halves have
// their own depth (a head is longer behind its crown than in front of it): semi-axes a
// (left-right), b_front, b_back, c (up). Its highest point is then above the centre, and
// where it lies follows from the front half's profile alone: a cabinet whose mirrors end
// below the top of the head still gives it. The fit is Ceres' least squares over each
// point's distance from the surface along the ray from the centre.
struct HeadCapFit {
  Eigen::Vector3d top = Eigen::Vector3d::Zero();  // the fitted surface's highest point
  double rms_mm = 0.0;                            // of the points' distances from it
};

// `points` on the cap (world, mm, z up); `lateral` the body's left-right direction in x-y
// (the yaw the fit starts from; the front is -y turned by it). Nullopt when there are too
// few points or the solver finds no usable solution.
std::optional<HeadCapFit> FitHeadCap(const std::vector<Eigen::Vector3d>& points,
                                     const Eigen::Vector2d& lateral);

}  // namespace mirrorscan::measurement
