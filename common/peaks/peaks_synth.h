#pragma once

// Synthetic laser frames with known truth, for peaks_test and peaks_benchmark only.
// Stripe model: a Gaussian profile A exp(-(y - v)^2 / (2 sigma^2)) integrated over each
// pixel's rows [r - 0.5, r + 0.5], times a multiplicative speckle factor per column, on an
// ambient plane with a gradient, plus Gaussian noise, clipped to [0, 255] and rounded.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "common/peaks/peaks.h"

namespace mirrorscan::synth {

struct Stripe {
  double v0 = 100;                 // Centre row at column 0.
  double slope = 0.0;              // Rows per column (sweeps the sub-pixel phase).
  double curvature = 0.0;          // Rows per column^2.
  double amplitude = 100;          // Peak of the continuous profile at column 0, DN.
  double amplitude_end = -1;       // At the last column (linear ramp); < 0: constant.
  double sigma = 1.0;              // Profile sigma, px.
  int gap_begin = 0, gap_end = 0;  // Columns [gap_begin, gap_end) have no stripe.
  double Centre(int u) const { return v0 + slope * u + curvature * u * u; }
  bool Present(int u) const { return u < gap_begin || u >= gap_end; }
};

struct Glint {
  int u, v;
  int value;  // Added DN.
};

struct Scene {
  int width = 1024, height = 768;
  double ambient = 30, ambient_du = 0.02, ambient_dv = 0.05;  // DN, DN per px.
  double noise_sigma = 0;
  double speckle = 0;  // Relative std of the per-column multiplicative speckle.
  std::vector<Stripe> stripes;
  std::vector<Glint> glints;
};

struct Truth {
  int u;
  double v;
  double amplitude;  // After speckle.
};

struct Frame {
  int width = 0, height = 0;
  std::vector<uint8_t> pixels;
  std::vector<Truth> truth;
  ImageView view() const { return {pixels.data(), width, height, width}; }
};

inline double PixelIntegral(double r, double v, double sigma) {
  const double k = 1.0 / (sigma * std::sqrt(2.0));
  // integral of exp(-(y - v)^2 / (2 sigma^2)) over [r - 0.5, r + 0.5]
  return sigma * std::sqrt(M_PI / 2.0) *
         (std::erf((r + 0.5 - v) * k) - std::erf((r - 0.5 - v) * k));
}

inline Frame Render(const Scene& scene, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Frame f;
  f.width = scene.width;
  f.height = scene.height;
  std::vector<double> img(static_cast<size_t>(scene.width) * scene.height);
  for (int y = 0; y < scene.height; ++y) {
    for (int x = 0; x < scene.width; ++x) {
      img[static_cast<size_t>(y) * scene.width + x] =
          scene.ambient + scene.ambient_du * x + scene.ambient_dv * y;
    }
  }
  for (const Stripe& s : scene.stripes) {
    for (int u = 0; u < scene.width; ++u) {
      if (!s.Present(u)) continue;
      const double v = s.Centre(u);
      const double speckle =
          scene.speckle > 0 ? std::clamp(1.0 + scene.speckle * gauss(rng), 0.5, 1.5) : 1.0;
      const double ramp = s.amplitude_end < 0 ? s.amplitude
                                              : s.amplitude + (s.amplitude_end - s.amplitude) * u /
                                                                  std::max(1, scene.width - 1);
      const double a = ramp * speckle;
      const int reach = static_cast<int>(std::ceil(6 * s.sigma)) + 1;
      for (int r = static_cast<int>(std::floor(v)) - reach; r <= static_cast<int>(v) + reach; ++r) {
        if (r < 0 || r >= scene.height) continue;
        img[static_cast<size_t>(r) * scene.width + u] += a * PixelIntegral(r, v, s.sigma);
      }
      if (v >= 0 && v <= scene.height - 1) f.truth.push_back({u, v, a});
    }
  }
  for (const Glint& g : scene.glints) {
    img[static_cast<size_t>(g.v) * scene.width + g.u] += g.value;
  }
  f.pixels.resize(img.size());
  for (size_t i = 0; i < img.size(); ++i) {
    const double x = img[i] + (scene.noise_sigma > 0 ? scene.noise_sigma * gauss(rng) : 0.0);
    f.pixels[i] = static_cast<uint8_t>(std::clamp(std::lround(x), 0L, 255L));
  }
  return f;
}

// `count` stripes spread over the frame height, random amplitude/sigma/slope.
inline std::vector<Stripe> RandomStripes(int count, int height, double amp_min, double amp_max,
                                         std::mt19937* rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Stripe> out;
  const double spacing = static_cast<double>(height) / (count + 1);
  for (int i = 0; i < count; ++i) {
    Stripe s;
    s.slope = (unit(*rng) - 0.5) * 0.08;
    s.curvature = (unit(*rng) - 0.5) * 4e-5;
    s.v0 = spacing * (i + 1) - 0.5 * (s.slope * 1024 + s.curvature * 1024 * 1024) +
           (unit(*rng) - 0.5) * 8;
    s.amplitude = amp_min + (amp_max - amp_min) * unit(*rng);
    s.amplitude_end = amp_min + (amp_max - amp_min) * unit(*rng);
    s.sigma = 0.6 + 0.9 * unit(*rng);
    out.push_back(s);
  }
  return out;
}

}  // namespace mirrorscan::synth
