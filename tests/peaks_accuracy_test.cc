// The on-device peak extractor against the virtual cabinet's ground truth: every
// estimator on rendered frames of the mannequin sweep, under the default sensor model,
// read noise σ 5 DN, saturated stripes and a noise-free sensor; then the default
// extractor and a plain thresholded centre of mass on wide stripes (camera blur up to a
// stripe σ of 2.5 px, defocus varying with distance, skin's light spread).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "boards/virtual/renderer.h"
#include "common/config/json_reader.h"
#include "common/peaks/peaks.h"

namespace mirrorscan {
namespace {

using virtual_cabinet::GrayImage;
using virtual_cabinet::Renderer;
using virtual_cabinet::Scene;
using virtual_cabinet::TruthPeak;

struct Condition {
  std::string name;
  double read_noise_dn;
  double laser_dn;
  bool noise;
  int threshold_dn;  // the board sets the threshold for its sensor's noise
};

struct Figures {
  double rms = 0, bias = 0, recall = 0, false_per_frame = 0;
  double unlit_false_per_frame = 0;  // false peaks with no laser light at all at the pixel
  int accuracy_peaks = 0, recall_peaks = 0, frames = 0;
  // Over the clean peaks at least kInteriorColumns from where their stripe's truth ends.
  double interior_rms = 0;
  int interior_peaks = 0;
  // Against the noise-free image's own light centre (centroid of the laser light within
  // ±5 rows of the truth), and that centre against the truth.
  double light_centre_rms = 0, light_centre_truth_rms = 0;
  // Wide conditions only: over the clean peaks whose rendered stripe is >= kBrightDn.
  double bright_rms = 0, bright_recall = 0;
  int bright_peaks = 0;
  // Wide conditions only: the Cramér–Rao bound of one column's row (RowBound), as an RMS
  // over the same peaks, all and bright.
  double bound_rms = 0, bright_bound_rms = 0;
};

// The Cramér–Rao bound (a standard deviation, px) of the row of the stripe crossing column u
// near row v, from that column's samples alone: 1 / sqrt(sum over rows of (d mu / d v)^2 /
// var), mu the noise-free image (lasers on, RenderRadiance: no speckle) clipped at 255, the
// stripe taken to move rigidly (d mu / d v = -d(lit - dark) / d row, a 5-point derivative,
// 0 where mu clips), var = read^2 + mu / electrons_per_dn + 1/12 (the sensor's read and
// shot noise and the 8-bit rounding; speckle, which scales a column's stripe as a whole,
// left out). No estimator reading the column alone does better on average; the
// along-stripe fit over 2m + 1 columns, each with its own noise, can reach this times
// sqrt(sum of its weights squared) (0.456 at m = 5) where the stripe is a quadratic.
double RowBound(const virtual_cabinet::FloatImage& lit, const virtual_cabinet::FloatImage& dark,
                const virtual_cabinet::Sensor& sensor, int u, double v) {
  const int centre = static_cast<int>(std::lround(v));
  auto light = [&](int r) {
    r = std::clamp(r, 0, lit.height - 1);
    return static_cast<double>(lit.at(u, r) - dark.at(u, r));
  };
  double information = 0;
  for (int r = std::max(0, centre - 14); r <= std::min(lit.height - 1, centre + 14); ++r) {
    const double mu = lit.at(u, r);
    if (mu >= 255) continue;
    const double derivative =
        (light(r - 2) - 8 * light(r - 1) + 8 * light(r + 1) - light(r + 2)) / 12.0;
    const double variance = sensor.read_noise_dn * sensor.read_noise_dn +
                            std::max(0.0, mu) / sensor.electrons_per_dn + 1.0 / 12.0;
    information += derivative * derivative / variance;
  }
  return information > 0 ? 1.0 / std::sqrt(information) : INFINITY;
}

// Wide conditions: a stripe's amplitude is what the image holds, the noise-free rendered
// peak above the ambient (a blur that widens a stripe lowers it; the truth's peak_dn is
// before blur). Clean peaks need >= 26 DN (the default set's 40 DN before blur at the
// default blur), recall counts those >= 2 x threshold, and the bright subset is >= 60 DN:
// the position noise of a stripe grows as sqrt(width) / amplitude, so at sigma 2.5 px and
// 26 DN even the Cramér–Rao bound per column is ~0.14 px.
constexpr double kWideCleanDn = 26, kBrightDn = 60;

// Issue 17's decision: the noise-free figure is taken on peaks at least 3 columns from a
// stripe end (nearer, the image's own light centre is off the plane's trace).
constexpr int kInteriorColumns = 3;

// Columns the truth curve of p's stripe goes on beside it, on its shorter side (up to
// `limit`): followed column by column within 2 px.
int ColumnsFromEnd(const TruthPeak& p,
                   const std::map<std::tuple<int, int, int>, std::vector<double>>& by_stripe_column,
                   int limit) {
  int shortest = limit;
  for (int side : {-1, 1}) {
    double v = p.v;
    int k = 0;
    while (k < shortest) {
      const auto it =
          by_stripe_column.find({p.laser, static_cast<int>(p.view), p.u + side * (k + 1)});
      if (it == by_stripe_column.end()) break;
      double best = 1e9;
      for (double w : it->second) best = std::abs(w - v) < std::abs(best - v) ? w : best;
      if (std::abs(best - v) > 2.0) break;
      v = best;
      ++k;
    }
    shortest = std::min(shortest, k);
  }
  return shortest;
}

// Centroid of the laser light (lasers on minus off, noise-free float image) in column u
// within ±5 rows of row v.
double LightCentre(const virtual_cabinet::FloatImage& lit, const virtual_cabinet::FloatImage& dark,
                   int u, double v, int radius = 5) {
  double sum = 0, moment = 0;
  const int centre = static_cast<int>(std::lround(v));
  for (int r = std::max(0, centre - radius); r <= std::min(lit.height - 1, centre + radius); ++r) {
    const double light = std::max(0.0f, lit.at(u, r) - dark.at(u, r));
    sum += light;
    moment += light * r;
  }
  return sum > 0 ? moment / sum : v;
}

// Truth peaks whose column centroid is a fair target: isolated in their column, with
// neighbours on both sides (not a stripe end or an occlusion edge) and a gentle slope
// (on a steep stripe the line bends within one pixel column, a geometric effect), bright
// enough to be measured.
bool Clean(const TruthPeak& p,
           const std::map<std::tuple<int, int, int>, std::vector<double>>& by_stripe_column,
           const std::map<int, std::vector<double>>& by_column, int height,
           double min_peak_dn = 40.0) {
  if (p.v < 4 || p.v > height - 5) return false;  // the extractor needs rows on both sides
  for (double v : by_column.at(p.u)) {
    if (v != p.v && std::abs(v - p.v) < 8.0) return false;
  }
  const auto left = by_stripe_column.find({p.laser, static_cast<int>(p.view), p.u - 1});
  const auto right = by_stripe_column.find({p.laser, static_cast<int>(p.view), p.u + 1});
  if (left == by_stripe_column.end() || right == by_stripe_column.end()) return false;
  auto nearest = [&](const std::vector<double>& rows) {
    double best = 1e9;
    for (double v : rows) best = std::abs(v - p.v) < std::abs(best - p.v) ? v : best;
    return best;
  };
  const double slope = (nearest(right->second) - nearest(left->second)) / 2.0;
  return std::abs(slope) < 0.5 && p.peak_dn >= min_peak_dn;
}

// Clean peaks binned by the first extractor's width column (FWHM, px) or as saturated
// (its top pixel clipped): per bin and extractor, the peaks it found and their squared error.
struct ByWidth {
  static constexpr const char* kBins[] = {"< 3", "3-4", "4-5", "5-6", ">= 6", "saturated"};
  static int Bin(const Peak& p, const GrayImage& image) {
    const int row = std::clamp(static_cast<int>(std::lround(p.v)), 0, image.height - 1);
    if (image.at(p.u, row) >= 255) return 5;
    return std::clamp(static_cast<int>(std::floor(p.width)) - 2, 0, 4);
  }
  std::map<int, std::map<size_t, std::pair<int, double>>> bins;  // bin -> extractor -> (n, e²)
};

// Figures for each of `params` on the same rendered frames, then (plain_threshold > 0) for
// the plain thresholded centre of mass at that threshold.
std::vector<Figures> Evaluate(const Renderer& renderer, const std::vector<PeakParams>& params,
                              const std::vector<double>& times, int plain_threshold = 0,
                              ByWidth* by_width = nullptr, bool wide = false) {
  struct Sums {
    double sum = 0, sum2 = 0, interior2 = 0, light2 = 0, light_truth2 = 0, bright2 = 0;
    double bound2 = 0, bright_bound2 = 0;
    int found = 0, wanted = 0, false_peaks = 0, unlit_false_peaks = 0;
    int bright_found = 0, bright_wanted = 0;
  };
  const size_t extractors = params.size() + (plain_threshold > 0 ? 1 : 0);
  std::vector<Figures> figures(extractors);
  std::vector<Sums> sums(extractors);
  PeakExtractor extractor;
  PlainCentreOfMass plain;
  std::vector<Peak> peaks;
  for (int camera = 0; camera < static_cast<int>(renderer.scene().cameras.size()); ++camera) {
    for (double t : times) {
      const GrayImage image = renderer.RenderFrame(camera, t, static_cast<uint64_t>(t * 1000));
      const auto truth = renderer.Truth(camera, t);
      // The laser's own light, noise-free: tells a false peak on real light (a stripe's
      // tip or end, where the truth curve does not cross the column) from one on none.
      const virtual_cabinet::FloatImage lit = renderer.RenderRadiance(camera, t, true);
      const virtual_cabinet::FloatImage dark = renderer.RenderRadiance(camera, t, false);
      std::map<int, std::vector<double>> by_column;
      std::map<std::tuple<int, int, int>, std::vector<double>> by_stripe_column;
      for (const auto& p : truth) {
        by_column[p.u].push_back(p.v);
        by_stripe_column[{p.laser, static_cast<int>(p.view), p.u}].push_back(p.v);
      }
      std::vector<int> bin_of(truth.size(), -1);   // by the first extractor's match
      std::vector<double> rendered(truth.size());  // noise-free stripe peak in the image
      for (size_t ti = 0; ti < truth.size(); ++ti) {
        const int row = static_cast<int>(std::lround(truth[ti].v));
        for (int r = std::max(0, row - 2); r <= std::min(image.height - 1, row + 2); ++r) {
          rendered[ti] =
              std::max<double>(rendered[ti], lit.at(truth[ti].u, r) - dark.at(truth[ti].u, r));
        }
      }
      for (size_t k = 0; k < extractors; ++k) {
        Figures& f = figures[k];
        Sums& s = sums[k];
        const ImageView view{image.pixels.data(), image.width, image.height, image.width};
        const PeakParams& param = params[k < params.size() ? k : 0];  // plain: the same truth set
        if (k < params.size()) {
          ExtractPeaks(view, param, &extractor, &peaks);
        } else {
          plain.Extract(view, plain_threshold, &peaks);
        }
        std::map<int, std::vector<const Peak*>> found_by_column;
        for (const auto& p : peaks) found_by_column[p.u].push_back(&p);
        for (size_t ti = 0; ti < truth.size(); ++ti) {
          const TruthPeak& p = truth[ti];
          const bool clean = wide ? Clean(p, by_stripe_column, by_column, image.height, 0) &&
                                        rendered[ti] >= kWideCleanDn
                                  : Clean(p, by_stripe_column, by_column, image.height);
          const double amplitude = wide ? rendered[ti] : p.peak_dn;
          const Peak* best = nullptr;
          for (const Peak* q : found_by_column[p.u]) {
            if (std::abs(q->v - p.v) < 1.5 &&
                (!best || std::abs(q->v - p.v) < std::abs(best->v - p.v)))
              best = q;
          }
          if (amplitude >= 2.0 * param.threshold_dn && clean) {
            ++s.wanted;
            if (best) ++s.found;
          }
          const bool bright = wide && clean && amplitude >= kBrightDn;
          if (bright) {
            ++s.bright_wanted;
            if (best) ++s.bright_found;
          }
          if (clean && best) {
            const double error = best->v - p.v;
            s.sum += error;
            s.sum2 += error * error;
            ++f.accuracy_peaks;
            if (ColumnsFromEnd(p, by_stripe_column, kInteriorColumns) >= kInteriorColumns) {
              s.interior2 += error * error;
              ++f.interior_peaks;
            }
            const double bound =
                wide ? RowBound(lit, dark, renderer.scene().sensor, p.u, p.v) : 0.0;
            s.bound2 += bound * bound;
            if (bright) {
              s.bright2 += error * error;
              s.bright_bound2 += bound * bound;
              ++f.bright_peaks;
            }
            const double centre = LightCentre(lit, dark, p.u, p.v, wide ? 10 : 5);
            s.light2 += (best->v - centre) * (best->v - centre);
            s.light_truth2 += (centre - p.v) * (centre - p.v);
            if (by_width) {
              if (k == 0) bin_of[ti] = ByWidth::Bin(*best, image);
              if (bin_of[ti] >= 0) {
                auto& [n, e2] = by_width->bins[bin_of[ti]][k];
                ++n;
                e2 += error * error;
              }
            }
          }
        }
        // A detection is false when no laser light is there: no truth within 2 px in its
        // column or the next ones. (Where an occluding edge cuts a stripe, the visible part
        // is real light though its centre, and so the truth, lies behind the edge.)
        for (const auto& p : peaks) {
          bool explained = false;
          for (int u = p.u - 1; u <= p.u + 1; ++u) {
            const auto it = by_column.find(u);
            if (it == by_column.end()) continue;
            for (double v : it->second) explained = explained || std::abs(v - p.v) < 2.0;
          }
          if (!explained) {
            ++s.false_peaks;
            const int row = std::clamp(static_cast<int>(std::lround(p.v)), 0, image.height - 1);
            if (lit.at(p.u, row) - dark.at(p.u, row) < 0.5 * param.threshold_dn) {
              ++s.unlit_false_peaks;
            }
          }
        }
        ++f.frames;
      }
    }
  }
  for (size_t k = 0; k < extractors; ++k) {
    Figures& f = figures[k];
    const Sums& s = sums[k];
    f.rms = std::sqrt(s.sum2 / std::max(1, f.accuracy_peaks));
    f.interior_rms = std::sqrt(s.interior2 / std::max(1, f.interior_peaks));
    f.light_centre_rms = std::sqrt(s.light2 / std::max(1, f.accuracy_peaks));
    f.light_centre_truth_rms = std::sqrt(s.light_truth2 / std::max(1, f.accuracy_peaks));
    f.bias = s.sum / std::max(1, f.accuracy_peaks);
    f.bright_rms = std::sqrt(s.bright2 / std::max(1, f.bright_peaks));
    f.bound_rms = std::sqrt(s.bound2 / std::max(1, f.accuracy_peaks));
    f.bright_bound_rms = std::sqrt(s.bright_bound2 / std::max(1, f.bright_peaks));
    f.bright_recall = s.bright_wanted ? static_cast<double>(s.bright_found) / s.bright_wanted : 0;
    f.recall = s.wanted ? static_cast<double>(s.found) / s.wanted : 0.0;
    f.recall_peaks = s.wanted;
    f.false_per_frame = static_cast<double>(s.false_peaks) / std::max(1, f.frames);
    f.unlit_false_per_frame = static_cast<double>(s.unlit_false_peaks) / std::max(1, f.frames);
  }
  return figures;
}

std::string ScenePath(const std::string& name) {
  return std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/virtual/scenes/" + name + ".json";
}

const std::vector<Condition>& Conditions() {
  static const std::vector<Condition> conditions = {
      {"default (read σ 2 DN, shot, speckle 0.2)", 2.0, 400.0, true, 18},
      {"read noise σ 5 DN", 5.0, 400.0, true, 30},
      {"saturated stripes (laser ×4)", 2.0, 1600.0, true, 18},
      {"noise-free", 0.0, 400.0, false, 18},
  };
  return conditions;
}

// Row name of the table: estimator, along-stripe half width m and the stripe filters
// (isolated peaks and faded ends dropped, or kept).
std::string Name(const PeakParams& p) {
  const bool filters = p.drop_isolated_peaks || p.stripe_end_min_ratio > 0;
  return std::string(ToString(p.estimator)) + " m=" + std::to_string(p.along_stripe_half_width) +
         (filters ? "" : " keep-ends");
}

std::string Default() { return Name(PeakParams()); }

// The cabinet these figures were set for (docs/peak-extraction.md), not the cabinet for
// people (docs/boards.md): one emitter, whose laser_dn the condition states, and the
// cameras 2150 and 1350 mm high at f 1400 px. There the upper camera looks down at the
// mannequin less steeply and the 1 mm sheet is σ ≈ 0.8 px wide, against ≈ 0.64 px and rings
// curved more in the image now; the estimator's figures in the new cabinet are still to
// be measured.
Scene LoadInTheFiguresCabinet(const std::string& name) {
  nlohmann::json json = JsonReader::ParseFile(ScenePath(name));
  json.merge_patch(
      {{"lasers", {{"emitter_mm", {0, -900}}, {"power", 1.0}}},
       {"mirrors",
        {{"width_mm", 620}, {"height_mm", 1700}, {"bottom_mm", 100}, {"corner_y_mm", 600}}},
       {"cameras",
        {{{"name", "upper"},
          {"position_mm", {0, -1800, 2150}},
          {"look_at_mm", {0, 300, 1350}},
          {"f_px", 1400}},
         {{"name", "lower"},
          {"position_mm", {0, -1800, 1350}},
          {"look_at_mm", {0, 300, 450}},
          {"f_px", 1400}}}}});
  return Scene::Parse(json, name + ".json",
                      std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/virtual/scenes");
}

// Every estimator with the defaults and without the cross-column stage (m = 0, no stripe
// filters), and the default estimator at every half width and without the filters.
std::map<std::string, std::map<std::string, Figures>> RunAll() {
  std::map<std::string, std::map<std::string, Figures>> table;
  const std::vector<double> times = {1.5, 3.0, 4.5, 6.0, 7.5, 9.0};
  const PeakParams defaults;
  auto without_filters = [](PeakParams p) {
    p.drop_isolated_peaks = false;
    p.stripe_end_min_ratio = 0;
    return p;
  };
  std::vector<PeakParams> variants;
  for (PeakEstimator e : AllPeakEstimators()) {
    PeakParams p = defaults;
    p.estimator = e;
    variants.push_back(p);
    p.along_stripe_half_width = 0;
    variants.push_back(without_filters(p));
  }
  for (int m = 0; m <= kMaxAlongStripeHalfWidth; ++m) {
    if (m == 1 || m == defaults.along_stripe_half_width) continue;
    PeakParams p = defaults;
    p.along_stripe_half_width = m;
    variants.push_back(p);
  }
  variants.push_back(without_filters(defaults));
  for (const auto& c : Conditions()) {
    Scene scene = LoadInTheFiguresCabinet("mannequin");
    scene.sensor.read_noise_dn = c.read_noise_dn;
    scene.sensor.laser_dn = c.laser_dn;
    scene.sensor.noise = c.noise;
    const Renderer renderer(scene);
    std::vector<PeakParams> params = variants;
    for (PeakParams& p : params) p.threshold_dn = c.threshold_dn;
    const std::vector<Figures> figures = Evaluate(renderer, params, times);
    for (size_t k = 0; k < variants.size(); ++k) table[c.name][Name(variants[k])] = figures[k];
  }
  return table;
}

const std::map<std::string, std::map<std::string, Figures>>& Table() {
  static const auto table = [] {
    auto t = RunAll();
    std::printf(
        "| condition | estimator, half width | RMS px | bias px | recall | false/frame | of which "
        "unlit | peaks | RMS >= 3 columns from an end (peaks) | RMS against the light centre |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& [condition, row] : t) {
      for (const auto& [estimator, f] : row) {
        std::printf("| %s | %s | %.4f | %+.4f | %.2f %% | %.2f | %.2f | %d | %.4f (%d) | %.4f |\n",
                    condition.c_str(), estimator.c_str(), f.rms, f.bias, 100 * f.recall,
                    f.false_per_frame, f.unlit_false_per_frame, f.accuracy_peaks, f.interior_rms,
                    f.interior_peaks, f.light_centre_rms);
      }
    }
    const Figures& n = t.at(Conditions()[3].name).at(Default());
    std::printf("noise-free light centre against the truth: %.4f px RMS\n",
                n.light_centre_truth_rms);
    return t;
  }();
  return table;
}

// The targets, against truth, with the default parameters: default sensor RMS
// <= 0.03 px, |bias| <= 0.005 px, recall >= 99.5 %, <= 1 false peak per frame; read
// noise sigma 5 DN <= 0.06 px; saturated <= 0.05 px; noise-free <= 0.01 px on the peaks at
// least 3 columns from a stripe end (issue 17's decision: nearer, the noise-free image's own
// light centre is off the plane's trace, docs/peak-extraction.md). Over all clean peaks the
// noise-free figure (0.0140 px) keeps a guard just above it.
TEST(PeaksAccuracyTest, DefaultEstimatorOnRenderedFrames) {
  const std::string best = Default();
  const Figures& f = Table().at(Conditions()[0].name).at(best);
  EXPECT_GT(f.accuracy_peaks, 5000);
  EXPECT_LE(f.rms, 0.03);
  EXPECT_LE(std::abs(f.bias), 0.005);
  EXPECT_GE(f.recall, 0.995);
  EXPECT_LE(f.false_per_frame, 1.0);
}

TEST(PeaksAccuracyTest, HarderConditions) {
  const std::string best = Default();
  const Figures& sigma5 = Table().at(Conditions()[1].name).at(best);
  EXPECT_LE(sigma5.rms, 0.06);
  EXPECT_LE(sigma5.false_per_frame, 1.0);  // 146 before the both-sides rise test, then 1.42
  const Figures& saturated = Table().at(Conditions()[2].name).at(best);
  EXPECT_LE(saturated.rms, 0.05);
  EXPECT_LE(saturated.false_per_frame, 2.0);  // 5.67 before the stripe-end filter
  const Figures& noise_free = Table().at(Conditions()[3].name).at(best);
  EXPECT_LE(noise_free.interior_rms, 0.01);
  EXPECT_GT(noise_free.interior_peaks, 0.9 * noise_free.accuracy_peaks);
  EXPECT_LE(noise_free.rms, 0.015);
  for (const auto& c : Conditions()) {
    // Measured 99.75 / 98.56 / 99.91 / 99.85 %: a regression that loses one clean peak in
    // 200 (about 55 of the 11,000) fails, the seed's noise does not.
    const double recall_bound = c.read_noise_dn > 4 ? 0.98 : 0.995;
    EXPECT_GE(Table().at(c.name).at(best).recall, recall_bound) << c.name;
    EXPECT_LE(std::abs(Table().at(c.name).at(best).bias), 0.005) << c.name;
    // Whatever the geometry, hardly a false peak where there is no laser light at all.
    EXPECT_LE(Table().at(c.name).at(best).unlit_false_per_frame, 0.25) << c.name;
  }
}

// The cross-column stage must pay: along-stripe smoothing lowers the RMS in noise, the
// stripe filters lower the false peaks.
TEST(PeaksAccuracyTest, AlongStripeStageBeatsColumnsAlone) {
  PeakParams columns_only;
  columns_only.along_stripe_half_width = 0;
  columns_only.drop_isolated_peaks = false;
  columns_only.stripe_end_min_ratio = 0;
  for (const auto& c : Conditions()) {
    const Figures& with = Table().at(c.name).at(Default());
    const Figures& without = Table().at(c.name).at(Name(columns_only));
    if (c.noise) {
      EXPECT_LT(with.rms, 0.8 * without.rms) << c.name;
    }
    EXPECT_LE(with.rms, without.rms) << c.name;
    EXPECT_LT(with.false_per_frame, without.false_per_frame) << c.name;
    EXPECT_GE(with.recall, without.recall - 0.001) << c.name;
  }
}

// The paper's thresholded centre of mass is the baseline every estimator must beat.
TEST(PeaksAccuracyTest, DefaultBeatsThePapersCentreOfMass) {
  const std::string best = Default();
  for (const auto& c : Conditions()) {
    const double paper = Table().at(c.name).at("thresholded_com m=0 keep-ends").rms;
    // Saturated peaks use a centre of mass in every estimator, so there the gap is small.
    EXPECT_LT(Table().at(c.name).at(best).rms, (c.laser_dn > 1000 ? 0.9 : 0.6) * paper) << c.name;
  }
}

// Stripes as real cameras see them. Each condition renders the mannequin sweep (both
// cameras, 3 times) with the default sensor noise and one change: the camera blur (stripe
// sigma in the centre view ~ sqrt(blur² + 0.6²) px), defocus varying with distance
// (scenes/mannequin_defocus.json), skin's light spread symmetric (truth = the plane's
// trace) and with its one-sided tail (scenes/mannequin_skin.json: the light's centre is off
// the trace, a bias of the surface that no estimator reading the image removes).
struct WideCondition {
  std::string name;
  std::string scene;
  double blur_px;  // < 0: the scene's
  double laser_dn;
  bool tail;  // keep the skin scene's tail
};

const std::vector<WideCondition>& WideConditions() {
  static const std::vector<WideCondition> conditions = {
      {"blur 1.0 px", "mannequin", 1.0, 400, false},
      {"blur 1.5 px", "mannequin", 1.5, 400, false},
      {"blur 2.0 px", "mannequin", 2.0, 400, false},
      {"blur 2.4 px (stripe σ ≈ 2.5 px)", "mannequin", 2.4, 400, false},
      {"blur 2.4 px, saturated (laser ×4)", "mannequin", 2.4, 1600, false},
      {"defocus (focus 1.9 m, 9 px/dioptre)", "mannequin_defocus", -1, 400, false},
      {"skin, symmetric (σ 2 mm)", "mannequin_skin", -1, 400, false},
      {"skin with tail (σ 2 mm, tail 1 mm)", "mannequin_skin", -1, 400, true},
  };
  return conditions;
}

struct WideTable {
  // condition -> [default, gaussian3 m=5, plain CoM]
  std::map<std::string, std::vector<Figures>> figures;
  ByWidth by_width;  // all conditions but the skin with its tail (no truth for its centre)
};
// sqrt(sum of the squared weights) of the along-stripe quadratic fit at m = 5: its noise gain.
// The table's "floor" is hypot(the noise-free light centre against the truth, this x the
// bound): what an estimator that reads the light's centre, smoothing over 11 columns, is left
// with (the light centre is off the plane's trace where the blur along u bends a curved
// stripe's light, at ends and tips; the image holds nothing that puts it back).
constexpr double kAlongStripeGain = 0.4555;
// The default, gaussian3 in its place, the default without the along-stripe fit (its
// per-column figure, to set against one column's Cramér–Rao bound) and the plain CoM.
constexpr const char* kWideColumns[] = {"default (adaptive m=5)", "gaussian3 m=5", "adaptive m=0",
                                        "plain CoM (50 DN)"};
constexpr size_t kWidePlain = 3;

const WideTable& Wide() {
  static const WideTable table = [] {
    WideTable t;
    const std::vector<double> times = {2.0, 5.0, 8.0};
    PeakParams gaussian3;
    gaussian3.estimator = PeakEstimator::kGaussian3;
    PeakParams per_column;
    per_column.along_stripe_half_width = 0;
    for (const WideCondition& c : WideConditions()) {
      Scene scene = LoadInTheFiguresCabinet(c.scene);
      if (c.blur_px >= 0) scene.sensor.blur_px = c.blur_px;
      scene.sensor.laser_dn = c.laser_dn;
      if (!c.tail) scene.subject_light_spread.tail_mm = 0;
      const Renderer renderer(scene);
      t.figures[c.name] = Evaluate(renderer, {PeakParams(), gaussian3, per_column}, times, 50,
                                   c.tail ? nullptr : &t.by_width, /*wide=*/true);
    }
    std::printf(
        "\n| condition | extractor | RMS px | bias px | recall | false/frame (unlit) | "
        "peaks | RMS against the light centre (light centre against the truth) | >= 60 DN: RMS "
        "px, recall, peaks | Cramér–Rao bound, one column / x 0.456 (11 columns): all, >= 60 "
        "DN | floor px |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const WideCondition& c : WideConditions()) {
      const auto& row = t.figures.at(c.name);
      for (size_t k = 0; k < row.size(); ++k) {
        const Figures& f = row[k];
        std::printf(
            "| %s | %s | %.4f | %+.4f | %.2f %% | %.2f (%.2f) | %d | %.4f (%.4f) | %.4f, %.2f %%, "
            "%d | %.4f / %.4f, %.4f / %.4f | %.4f |\n",
            c.name.c_str(), kWideColumns[k], f.rms, f.bias, 100 * f.recall, f.false_per_frame,
            f.unlit_false_per_frame, f.accuracy_peaks, f.light_centre_rms, f.light_centre_truth_rms,
            f.bright_rms, 100 * f.bright_recall, f.bright_peaks, f.bound_rms,
            kAlongStripeGain * f.bound_rms, f.bright_bound_rms,
            kAlongStripeGain * f.bright_bound_rms,
            std::hypot(f.light_centre_truth_rms, kAlongStripeGain * f.bound_rms));
      }
    }
    std::printf(
        "\n| width (px) | peaks | default RMS px | gaussian3 RMS px | adaptive m=0 RMS px | plain "
        "CoM RMS px (peaks) |\n"
        "|---|---|---|---|---|---|\n");
    for (const auto& [bin, by_extractor] : t.by_width.bins) {
      auto rms = [&](size_t k) {
        const auto it = by_extractor.find(k);
        return it == by_extractor.end() ? NAN : std::sqrt(it->second.second / it->second.first);
      };
      const auto plain = by_extractor.find(kWidePlain);
      std::printf("| %s | %d | %.4f | %.4f | %.4f | %.4f (%d) |\n", ByWidth::kBins[bin],
                  by_extractor.at(0).first, rms(0), rms(1), rms(2), rms(kWidePlain),
                  plain == by_extractor.end() ? 0 : plain->second.first);
    }
    return t;
  }();
  return table;
}

// Issue 18's targets at every width from the sharp default to stripe sigma 2.5 px and on
// skin: RMS <= 0.03 px against the truth where the truth is defined, recall >= 99.5 %,
// <= 1 false peak per frame. Recall is met (>= 99.91 %). False peaks are met but on the
// saturated wide stripes (2.83 per frame, the plain CoM 11.3; 30.5 before wide stripes' ends
// were peeled, peaks.cc kWideEndPeel): all of them on real laser light past the truth's ends
// (none unlit), where clipping hides how much dimmer the column is. The RMS
// is not: 0.035 ... 0.080 px over all clean peaks (>= 26 DN), 0.019 ... 0.039 px on those
// >= 60 DN; the floor of the table (the noise-free light centre's own offset from the trace
// and the Cramér–Rao bound after an 11-column fit) is above 0.03 px from blur 1.5 px up and on
// skin (docs/peak-extraction.md). These bounds are guards just above the measured
// figures, and the default must beat gaussian3 and the plain CoM in every condition. With skin's
// tail the truth (the plane's trace) is not the light's centre (the default is 0.43 px off it, as
// every estimator): there the figures are against the noise-free light centre.
TEST(PeaksAccuracyTest, WideStripesOnRenderedFrames) {
  for (const WideCondition& c : WideConditions()) {
    const std::vector<Figures>& row = Wide().figures.at(c.name);
    const Figures& f = row[0];
    SCOPED_TRACE(c.name);
    const bool saturated = c.laser_dn > 1000;
    EXPECT_GT(f.accuracy_peaks, 3000);
    EXPECT_GE(f.recall, 0.995);
    EXPECT_GE(f.bright_recall, 0.995);
    EXPECT_LE(f.false_per_frame, saturated ? 4.0 : 1.0);
    EXPECT_LE(f.unlit_false_per_frame, 0.25);
    for (size_t k = 1; k < row.size(); ++k) {
      EXPECT_LT(c.tail ? f.light_centre_rms : f.rms, c.tail ? row[k].light_centre_rms : row[k].rms)
          << kWideColumns[k];
    }
    if (c.tail) {
      EXPECT_LE(f.light_centre_rms, 0.05);
      continue;
    }
    EXPECT_LE(f.rms, 0.09);
    EXPECT_LE(f.bright_rms, saturated ? 0.07 : 0.04);
    EXPECT_LE(std::abs(f.bias), saturated ? 0.02 : 0.01);
  }
}

// At no width is the plain thresholded centre of mass better than the default extractor
// (binned by the extractor's own width column, saturated apart).
TEST(PeaksAccuracyTest, NoWidthWherePlainCentreOfMassIsBetter) {
  for (const auto& [bin, by_extractor] : Wide().by_width.bins) {
    SCOPED_TRACE(ByWidth::kBins[bin]);
    const auto plain = by_extractor.find(kWidePlain);
    if (plain == by_extractor.end() || plain->second.first < 100) continue;
    const auto& mine = by_extractor.at(0);
    EXPECT_LT(std::sqrt(mine.second / mine.first),
              std::sqrt(plain->second.second / plain->second.first));
  }
}

}  // namespace
}  // namespace mirrorscan
