#include "common/peaks/peaks.h"

#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "common/peaks/peaks_internal.h"
#include "common/peaks/peaks_synth.h"

namespace mirrorscan {
namespace {

using synth::Frame;
using synth::Scene;

struct Score {
  int truth = 0, found = 0, false_peaks = 0, frames = 0;
  double sum = 0, sum2 = 0;
  double Rms() const { return found ? std::sqrt(sum2 / found) : NAN; }
  double Bias() const { return found ? sum / found : NAN; }
  double Recall() const { return truth ? static_cast<double>(found) / truth : NAN; }
  double FalsePerFrame() const { return frames ? static_cast<double>(false_peaks) / frames : 0; }
};

// Matches each truth to the nearest peak of its column within 1.5 px.
void Evaluate(const Frame& f, const std::vector<Peak>& peaks, Score* s) {
  std::vector<std::vector<const Peak*>> by_column(f.width);
  for (const Peak& p : peaks) by_column[p.u].push_back(&p);
  std::vector<char> used(peaks.size(), 0);
  for (const synth::Truth& t : f.truth) {
    ++s->truth;
    const Peak* best = nullptr;
    for (const Peak* p : by_column[t.u]) {
      if (std::abs(p->v - t.v) < 1.5 && (!best || std::abs(p->v - t.v) < std::abs(best->v - t.v)))
        best = p;
    }
    if (!best) continue;
    used[best - peaks.data()] = 1;
    ++s->found;
    const double e = best->v - t.v;
    s->sum += e;
    s->sum2 += e * e;
  }
  for (char u : used) s->false_peaks += !u;
  ++s->frames;
}

struct Condition {
  const char* name;
  double noise;
  double amp_min, amp_max;
  double speckle;
  int threshold;
};

// Accuracy conditions. Amplitude = peak of the continuous profile before pixel integration.
const Condition kConditions[] = {
    {"noise-free", 0, 30, 250, 0, 12},
    {"sigma 2 DN", 2, 30, 250, 0.1, 12},
    {"sigma 2 DN, A>=100", 2, 100, 250, 0.1, 12},
    {"sigma 5 DN", 5, 60, 250, 0.1, 30},
    {"saturated (A 300-900), sigma 2", 2, 300, 900, 0.1, 12},
};

Frame ConditionFrame(const Condition& c, int index) {
  std::mt19937 rng(1000 + index);
  Scene scene;
  scene.noise_sigma = c.noise;
  scene.speckle = c.speckle;
  scene.stripes = synth::RandomStripes(6, scene.height, c.amp_min, c.amp_max, &rng);
  return synth::Render(scene, 77 + index);
}

constexpr int kFramesPerCondition = 4;

#ifdef MIRRORSCAN_UNDER_EMULATOR
constexpr bool kUnderEmulator = true;
#else
constexpr bool kUnderEmulator = false;
#endif

// Every estimator without (m = 0) and with the default along-stripe smoothing.
TEST(PeakAccuracy, TableOfEstimators) {
  std::vector<std::vector<Frame>> frames;
  for (const Condition& c : kConditions) {
    frames.emplace_back();
    for (int i = 0; i < kFramesPerCondition; ++i) frames.back().push_back(ConditionFrame(c, i));
  }
  std::printf("\n| estimator | m | condition | RMS px | bias px | recall %% | false/frame |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  PeakExtractor extractor;
  std::vector<Peak> peaks;
  const PeakParams defaults;
  for (PeakEstimator e : AllPeakEstimators()) {
    for (int half_width : {0, defaults.along_stripe_half_width}) {
      for (size_t ci = 0; ci < std::size(kConditions); ++ci) {
        const Condition& c = kConditions[ci];
        PeakParams params;
        params.estimator = e;
        params.along_stripe_half_width = half_width;
        params.threshold_dn = c.threshold;
        Score s;
        for (const Frame& f : frames[ci]) {
          extractor.Extract(f.view(), params, &peaks);
          Evaluate(f, peaks, &s);
        }
        std::printf("| %s | %d | %s | %.4f | %+.4f | %.2f | %.2f |\n", ToString(e), half_width,
                    c.name, s.Rms(), s.Bias(), 100 * s.Recall(), s.FalsePerFrame());
        SCOPED_TRACE(std::string(ToString(e)) + " / m " + std::to_string(half_width) + " / " +
                     c.name);
        EXPECT_GE(s.Recall(), 0.995);
        EXPECT_LE(s.FalsePerFrame(), 1.0);
        EXPECT_LE(std::abs(s.Bias()), 0.005);
        if (e == defaults.estimator && half_width == defaults.along_stripe_half_width) {
          const std::string name = c.name;
          if (name == "noise-free") {
            EXPECT_LE(s.Rms(), 0.01);
          }
          if (name == "sigma 2 DN, A>=100") {
            EXPECT_LE(s.Rms(), 0.03);
          }
          if (name.rfind("saturated", 0) == 0) {
            EXPECT_LE(s.Rms(), 0.05);
          }
        }
      }
    }
  }
}

// Stripes as wide as real cameras see them (defocus, skin): profile sigma 0.8 ... 2.5 px
// (FWHM 1.9 ... 5.9 px), 6 stripes per frame, on a flat ambient so that the plain
// thresholded centre of mass (one global threshold, PlainCentreOfMass) gets a fair
// chance. Rows: gaussian3, the adaptive estimator and windowed CoM with the defaults
// (m = 5), and the plain CoM; a table by width, noise and saturation.
TEST(PeakAccuracy, WideStripesTableByWidth) {
  struct WideCondition {
    const char* name;
    double noise, amp_min, amp_max, speckle;
  };
  const WideCondition conditions[] = {
      {"noise-free", 0, 40, 250, 0},
      {"sigma 2 DN", 2, 40, 250, 0.1},
      {"sigma 5 DN", 5, 80, 250, 0.1},
      {"saturated (A 300-900), sigma 2", 2, 300, 900, 0.1},
  };
  // Under qemu-aarch64 (the cross build) the full table took up to 156 s, rendering and
  // extracting 48 frames: there the narrowest, a middle and the widest sigma prove the same
  // assertions on the board's code (its SIMD target included), on the same frames as the
  // host's cells; the host runs every cell. (One frame per cell is too few: noise-free at
  // sigma 2.5 px the adaptive estimator and the plain CoM are then level, 0.00674 against
  // 0.00673 px.)
  const std::vector<double> sigmas = kUnderEmulator
                                         ? std::vector<double>{0.8, 1.5, 2.5}
                                         : std::vector<double>{0.8, 1.0, 1.25, 1.5, 2.0, 2.5};
  constexpr int kFramesPerCell = 2;
  constexpr double kAmbient = 30;
  PeakExtractor extractor;
  PlainCentreOfMass plain;
  std::vector<Peak> peaks;
  std::printf("\n| sigma px | condition | gaussian3 | adaptive | windowed_com | plain CoM |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (const double sigma : sigmas) {
    for (const WideCondition& c : conditions) {
      const int threshold = c.noise >= 5 ? 30 : 12;
      Score g3, adaptive, windowed, com;
      for (int i = 0; i < kFramesPerCell; ++i) {
        std::mt19937 rng(3000 + i);
        Scene scene;
        scene.ambient = kAmbient;
        scene.ambient_du = scene.ambient_dv = 0;
        scene.noise_sigma = c.noise;
        scene.speckle = c.speckle;
        scene.stripes = synth::RandomStripes(6, scene.height, c.amp_min, c.amp_max, &rng);
        for (auto& stripe : scene.stripes) stripe.sigma = sigma;
        const Frame f = synth::Render(scene, 91 + i);
        for (auto [estimator, score] : {std::pair{PeakEstimator::kGaussian3, &g3},
                                        std::pair{PeakEstimator::kAdaptive, &adaptive},
                                        std::pair{PeakEstimator::kWindowedCom, &windowed}}) {
          PeakParams params;
          params.estimator = estimator;
          params.threshold_dn = threshold;
          extractor.Extract(f.view(), params, &peaks);
          Evaluate(f, peaks, score);
        }
        plain.Extract(f.view(), static_cast<int>(kAmbient) + threshold, &peaks);
        Evaluate(f, peaks, &com);
      }
      auto cell = [](const Score& s) {
        char text[64];
        std::snprintf(text, sizeof text, "%.4f (%.1f %%, %.1f)", s.Rms(), 100 * s.Recall(),
                      s.FalsePerFrame());
        return std::string(text);
      };
      std::printf("| %.2f | %s | %s | %s | %s | %s |\n", sigma, c.name, cell(g3).c_str(),
                  cell(adaptive).c_str(), cell(windowed).c_str(), cell(com).c_str());
      SCOPED_TRACE(std::string(c.name) + " / sigma " + std::to_string(sigma));
      EXPECT_GE(adaptive.Recall(), 0.995);
      EXPECT_LE(adaptive.FalsePerFrame(), 1.0);
      EXPECT_LE(std::abs(adaptive.Bias()), 0.005);
      // No width where the plain centre of mass is better; but for narrow clipped stripes,
      // where every estimator takes the whole-peak centre of mass and the plain one is level
      // (sigma 0.8: 0.0389 against 0.0382 px).
      const bool clipped = c.amp_min > 255;
      EXPECT_LE(adaptive.Rms(), (clipped && sigma < 1 ? 1.05 : 1.0) * com.Rms());
    }
  }
}

// Many frames, every estimator, awkward ROIs: SIMD candidates == scalar candidates.
TEST(PeakSimd, SimdEqualsScalarExactly) {
  std::printf("SIMD target: %s\n", PeakExtractor::SimdTarget().c_str());
  PeakExtractor a, b;
  std::vector<Peak> pa, pb;
  int total = 0;
  for (int i = 0; i < 24; ++i) {
    std::mt19937 rng(5000 + i);
    Scene scene;
    scene.width = 1024 - 37 * (i % 3);  // Widths that are no multiple of the vector.
    scene.height = 768 - 11 * (i % 2);
    scene.noise_sigma = (i % 4) * 2.0;
    scene.speckle = 0.2;
    scene.ambient = 10 + 10 * (i % 5);
    scene.stripes = synth::RandomStripes(3 + i % 7, scene.height, 20, 600, &rng);
    for (int g = 0; g < 20; ++g) {
      scene.glints.push_back(
          {static_cast<int>(rng() % scene.width), static_cast<int>(rng() % scene.height), 120});
    }
    const Frame f = synth::Render(scene, 900 + i);
    PeakParams params;
    params.estimator = AllPeakEstimators()[i % AllPeakEstimators().size()];
    params.threshold_dn = 8 + i % 20;
    params.window = 4 + i % 9;
    params.along_stripe_half_width = i % (kMaxAlongStripeHalfWidth + 1);
    if (i % 3 == 1) params.roi = {13, 7, 701, 500};
    if (i % 3 == 2) params.roi = {0, 300, 0, 0};
    if (i % 5 == 0) params.excluded = {{100, 0, 50, 768}, {400, 200, 300, 100}};
    a.Extract(f.view(), params, &pa);
    b.ExtractScalar(f.view(), params, &pb);
    ASSERT_EQ(pa.size(), pb.size()) << "frame " << i;
    for (size_t k = 0; k < pa.size(); ++k) {
      ASSERT_EQ(pa[k].u, pb[k].u);
      ASSERT_EQ(pa[k].v, pb[k].v);
      ASSERT_EQ(pa[k].intensity, pb[k].intensity);
      ASSERT_EQ(pa[k].width, pb[k].width);
      ASSERT_EQ(pa[k].score, pb[k].score);
    }
    total += static_cast<int>(pa.size());
  }
  EXPECT_GT(total, 24 * 1000);
}

// Every Highway target this CPU supports (e.g. AVX3, AVX2, SSE4; SVE2, SVE, NEON).
TEST(PeakSimd, SimdEqualsScalarOnEveryTarget) {
  std::mt19937 rng(77);
  Scene scene;
  scene.noise_sigma = 3;
  scene.speckle = 0.2;
  scene.width = 1000;
  scene.stripes = synth::RandomStripes(7, scene.height, 20, 600, &rng);
  const Frame f = synth::Render(scene, 78);
  PeakParams params;
  params.threshold_dn = 10;
  const auto reference = ExtractPeaksScalar(f.view(), params);
  for (const int64_t target : hwy::SupportedAndGeneratedTargets()) {
    hwy::SetSupportedTargetsForTest(target);
    const auto peaks = ExtractPeaks(f.view(), params);
    std::printf("target %s: %zu peaks\n", hwy::TargetName(target), peaks.size());
    ASSERT_EQ(peaks.size(), reference.size()) << hwy::TargetName(target);
    for (size_t k = 0; k < peaks.size(); ++k) {
      ASSERT_EQ(peaks[k].u, reference[k].u) << hwy::TargetName(target);
      ASSERT_EQ(peaks[k].v, reference[k].v) << hwy::TargetName(target);
    }
  }
  hwy::SetSupportedTargetsForTest(0);
}

TEST(PeakSimd, TinyAndOddImages) {
  std::mt19937 rng(3);
  for (int w : {1, 5, 31, 33, 65, 130}) {
    for (int h : {1, 2, 3, 9, 40}) {
      std::vector<uint8_t> px(static_cast<size_t>(w + 3) * h);
      for (auto& p : px) p = static_cast<uint8_t>(rng() % 256);
      const ImageView view{px.data(), w, h, w + 3};
      PeakParams params;
      params.threshold_dn = 10;
      params.window = 4;
      const auto pa = ExtractPeaks(view, params);
      const auto pb = ExtractPeaksScalar(view, params);
      ASSERT_EQ(pa.size(), pb.size()) << w << "x" << h;
      for (size_t k = 0; k < pa.size(); ++k) {
        EXPECT_EQ(pa[k].u, pb[k].u);
        EXPECT_EQ(pa[k].v, pb[k].v);
      }
    }
  }
}

TEST(PeakRobustness, TwoLinesSixPixelsApartBothFound) {
  for (double sigma : {0.6, 1.0, 1.5}) {
    Scene scene;
    scene.noise_sigma = 2;
    synth::Stripe s1{
        .v0 = 300, .slope = 0.03, .amplitude = 80, .amplitude_end = 200, .sigma = sigma};
    synth::Stripe s2 = s1;
    s2.v0 = 306;
    s2.amplitude = 200;
    s2.amplitude_end = 80;
    scene.stripes = {s1, s2};
    const Frame f = synth::Render(scene, 11);
    PeakParams params;
    params.threshold_dn = 12;
    Score s;
    Evaluate(f, ExtractPeaks(f.view(), params), &s);
    std::printf("two lines 6 px apart, sigma %.1f: recall %.2f%%, RMS %.4f, bias %+.4f\n", sigma,
                100 * s.Recall(), s.Rms(), s.Bias());
    EXPECT_GE(s.Recall(), 0.995) << sigma;
    EXPECT_EQ(s.false_peaks, 0) << sigma;
    EXPECT_LE(s.Rms(), 0.1) << sigma;
  }
}

// A line across an edge of reflectance (dark underwear against skin): the surface's
// reflectance multiplies the ambient and the line alike, so the line is dimmed on the dark
// side and its centre moves towards the bright one. The edge wanders +-10 px about the line
// (dark above it, 6:1, skin 20 DN as in the virtual cabinet). Every peak given with a
// score above 0.1 lies within 0.25 px of the truth (without the edge rule they lie up to
// 1.5 px off); where the edge is beyond the line's reach (8 px and more below the dark
// edge), the line is found with its usual score.
TEST(PeakRobustness, LinesAcrossAReflectanceEdgeAreGivenOnlyAsDoubtful) {
  for (double amplitude : {40.0, 200.0}) {
    const synth::Stripe stripe{.v0 = 300, .slope = 0.02, .amplitude = amplitude, .sigma = 1.0};
    Frame f;
    f.width = 1024;
    f.height = 768;
    f.pixels.assign(static_cast<size_t>(f.width) * f.height, 0);
    std::mt19937 rng(5);
    std::normal_distribution<double> noise(0.0, 2.0);
    std::vector<double> edge_offset(f.width);
    for (int u = 0; u < f.width; ++u) {
      const double v = stripe.Centre(u);
      const double edge = v + 10.0 * std::sin(u / 50.0);
      edge_offset[u] = edge - v;
      f.truth.push_back({u, v, amplitude});
      for (int r = 0; r < f.height; ++r) {
        const double dark_part = std::clamp(edge - (r - 0.5), 0.0, 1.0);  // Of the pixel's rows.
        const double reflectance = 1.0 - dark_part * (1.0 - 1.0 / 6.0);
        const double light = 20.0 + amplitude * synth::PixelIntegral(r, v, stripe.sigma);
        f.pixels[static_cast<size_t>(r) * f.width + u] = static_cast<uint8_t>(
            std::clamp(std::round(light * reflectance + noise(rng)), 0.0, 255.0));
      }
    }
    PeakParams params;
    params.threshold_dn = 10;
    const std::vector<Peak> peaks = ExtractPeaks(f.view(), params);
    int beyond = 0, beyond_found = 0, doubtful = 0;
    double worst = 0;
    for (const synth::Truth& t : f.truth) {
      const Peak* found = nullptr;
      for (const Peak& p : peaks)
        if (p.u == t.u && std::abs(p.v - t.v) < 1.5) found = &p;
      if (found && found->score <= 0.1f) ++doubtful;
      if (found && found->score > 0.1f) worst = std::max(worst, std::abs(found->v - t.v));
      if (edge_offset[t.u] <= -8.0) {
        ++beyond;
        beyond_found += found != nullptr && found->score > 0.1f;
      }
    }
    std::printf(
        "reflectance edge, amplitude %.0f: %zu peaks, %d doubtful, the others' worst %.3f px; "
        "edge beyond: %d of %d\n",
        amplitude, peaks.size(), doubtful, worst, beyond_found, beyond);
    EXPECT_LE(worst, 0.25) << amplitude;
    EXPECT_GE(beyond_found, 0.99 * beyond) << amplitude;
  }
}

TEST(PeakRobustness, GlintsGapsAndAmbientGradient) {
  std::mt19937 rng(8);
  Scene scene;
  scene.noise_sigma = 2;
  scene.ambient = 20;
  scene.ambient_du = 0.1;   // 20 .. 122 DN across the frame
  scene.ambient_dv = 0.08;  // plus 61 DN down it
  scene.stripes = synth::RandomStripes(5, scene.height, 60, 200, &rng);
  scene.stripes[1].gap_begin = 200;
  scene.stripes[1].gap_end = 420;
  scene.stripes[3].gap_begin = 700;
  scene.stripes[3].gap_end = 710;
  for (int g = 0; g < 300; ++g) {  // Single-pixel glints well away from the stripes.
    const int u = static_cast<int>(rng() % 1024);
    const int v = 30 + static_cast<int>(rng() % 700);
    bool near = false;
    for (const auto& s : scene.stripes) near = near || std::abs(s.Centre(u) - v) < 12;
    if (!near) scene.glints.push_back({u, v, 60 + static_cast<int>(rng() % 150)});
  }
  const Frame f = synth::Render(scene, 12);
  PeakParams params;
  params.threshold_dn = 12;
  const auto peaks = ExtractPeaks(f.view(), params);
  Score s;
  Evaluate(f, peaks, &s);
  std::printf("glints %zu, gaps, gradient: recall %.2f%%, false %d, RMS %.4f\n",
              scene.glints.size(), 100 * s.Recall(), s.false_peaks, s.Rms());
  EXPECT_GE(s.Recall(), 0.995);
  EXPECT_LE(s.false_peaks, 1);
  for (const Peak& p : peaks) {
    const bool in_gap = p.u >= 200 && p.u < 420 && std::abs(p.v - scene.stripes[1].Centre(p.u)) < 3;
    EXPECT_FALSE(in_gap) << p.u << " " << p.v;
  }
}

// On rendered frames two thirds of the candidates are local maxima on the bright side of
// an ambient step, and the candidate rule drops those the refinement is certain to reject
// (CandidateSearch::NeverHalfHeight). Checked here against the refinement's own arithmetic
// (exact flank means, a linear background where they agree within threshold / 2, the
// half-maximum walk out to the window) on noisy frames with steps beside and under the
// lines; and the lines are still found.
TEST(PeakRobustness, StepRuleDropsOnlyWhatRefinementRejects) {
  std::mt19937 rng(21);
  Scene scene;
  scene.noise_sigma = 3;
  scene.stripes = synth::RandomStripes(8, scene.height, 40, 200, &rng);
  Frame f = synth::Render(scene, 21);
  // Each stripe gets an edge wandering from 8 px above it to 8 px below, 20 .. 50 DN up
  // for even stripes, down for odd ones (the frame stays within 0 .. 255 between them).
  for (size_t k = 0; k < scene.stripes.size(); ++k) {
    const int step = (k % 2 == 0 ? 1 : -1) * (20 + static_cast<int>(10 * k) % 31);
    for (int u = 0; u < f.width; ++u) {
      const double edge =
          scene.stripes[k].Centre(u) + 8 * std::sin(u / 40.0 + static_cast<double>(k));
      for (int v = std::max(0, static_cast<int>(std::ceil(edge))); v < f.height; ++v) {
        uint8_t& px = f.pixels[static_cast<size_t>(v) * f.width + u];
        px = static_cast<uint8_t>(std::clamp(px + step, 0, 255));
      }
    }
  }
  PeakParams params;
  params.threshold_dn = 18;
  const peaks_internal::CandidateSearch search{
      f.pixels.data(), f.width, 0, f.width, 0, f.height, params.window, params.threshold_dn};
  int candidates = 0, dropped = 0;
  for (int u = 0; u < f.width; ++u) {
    for (int r = 1; r <= f.height - 2; ++r) {
      const int c = search.At(u, r);
      if (!(search.At(u, r - 1) < c && search.At(u, r + 1) <= c)) continue;
      const int upper = search.Mean4(u, r - params.window);
      const int lower = search.Mean4(u, r + params.window - 3);
      if (c - std::min(upper, lower) < params.threshold_dn) continue;
      ++candidates;
      if (!search.NeverHalfHeight(u, r, upper, lower)) continue;
      ++dropped;
      float left = 0, right = 0;
      for (int i = 0; i < 4; ++i) {
        left += 0.25f * static_cast<float>(search.At(u, r - params.window + i));
        right += 0.25f * static_cast<float>(search.At(u, r + params.window - 3 + i));
      }
      ASSERT_GT(std::abs(left - right), 0.5f * params.threshold_dn) << u << " " << r;
      const float base = std::min(left, right);
      const float half = 0.5f * (static_cast<float>(c) - base);
      bool crossing_up = false, crossing_down = false;
      for (int i = 1; i <= params.window; ++i) {
        crossing_up = crossing_up || (r - i >= 0 && search.At(u, r - i) - base <= half);
        crossing_down = crossing_down || (r + i < f.height && search.At(u, r + i) - base <= half);
      }
      ASSERT_FALSE(crossing_up && crossing_down) << u << " " << r;
    }
  }
  Score s;
  const auto peaks = ExtractPeaks(f.view(), params);
  Evaluate(f, peaks, &s);
  std::printf("steps beside lines: %d of %d candidates dropped; recall %.2f%%, false %d\n", dropped,
              candidates, 100 * s.Recall(), s.false_peaks);
  EXPECT_GT(dropped, candidates / 4);
  EXPECT_GE(s.Recall(), 0.99);
  EXPECT_LE(s.false_peaks, 10);
  EXPECT_EQ(peaks.size(), ExtractPeaksScalar(f.view(), params).size());
}

TEST(PeakRobustness, MaxPeaksPerColumnKeepsTheStrongest) {
  Scene scene;
  for (int i = 0; i < 5; ++i) {
    synth::Stripe s{.v0 = 100.0 + 120 * i, .amplitude = 40.0 + 40 * i, .sigma = 1.0};
    scene.stripes.push_back(s);
  }
  const Frame f = synth::Render(scene, 1);
  PeakParams params;
  params.max_peaks_per_column = 2;
  const auto peaks = ExtractPeaks(f.view(), params);
  ASSERT_EQ(peaks.size(), 2u * 1024);
  for (size_t i = 0; i < peaks.size(); i += 2) {
    EXPECT_NEAR(peaks[i].v, 460, 0.05);  // Strongest two, sorted by v.
    EXPECT_NEAR(peaks[i + 1].v, 580, 0.05);
  }
}

TEST(PeakRobustness, SaturatedPlateauUsesTheWholePeak) {
  for (PeakEstimator e : AllPeakEstimators()) {
    Scene scene;
    synth::Stripe s{.v0 = 400.3, .slope = 0.011, .amplitude = 900, .sigma = 1.2};
    scene.stripes = {s};
    const Frame f = synth::Render(scene, 2);
    PeakParams params;
    params.estimator = e;
    Score sc;
    const auto peaks = ExtractPeaks(f.view(), params);
    Evaluate(f, peaks, &sc);
    EXPECT_GE(sc.Recall(), 0.999) << ToString(e);
    EXPECT_LE(sc.Rms(), 0.05) << ToString(e);
    for (const Peak& p : peaks) EXPECT_LT(p.score, 0.81f);
  }
}

// Errors of the peaks matched to the truths of `f` whose column is in [u_lo, u_hi].
Score ScoreColumns(const Frame& f, const std::vector<Peak>& peaks, int u_lo, int u_hi) {
  Frame part = f;
  part.truth.clear();
  for (const synth::Truth& t : f.truth)
    if (t.u >= u_lo && t.u <= u_hi) part.truth.push_back(t);
  Score s;
  Evaluate(part, peaks, &s);
  return s;
}

// Straight slanted and tightly curved stripes: the along-stripe fit lowers the noise and
// adds no bias. A plain mean over 11 columns would be biased by v'' * 10 / 2 = 0.05 px on
// the tight curve (v'' = 0.01 px per column^2), a binomial [1 4 6 4 1] by 0.005 px.
TEST(AlongStripe, NoBiasOnSlantedAndCurvedStripes) {
  struct Case {
    const char* name;
    synth::Stripe stripe;
    int u_lo, u_hi;  // Evaluated columns: |slope| <= 0.75 px per column.
  };
  // 512 x 400 frames: this test also runs under qemu.
  const Case cases[] = {
      {"slope +0.35", {.v0 = 100.2, .slope = 0.35, .amplitude = 70, .sigma = 1.0}, 0, 511},
      {"slope -0.55", {.v0 = 350.7, .slope = -0.55, .amplitude = 90, .sigma = 0.8}, 0, 511},
      {"curve v''=+0.0012",
       {.v0 = 120 + 6e-4 * 256 * 256,
        .slope = -2 * 6e-4 * 256,
        .curvature = 6e-4,
        .amplitude = 80,
        .sigma = 1.2},
       0,
       511},
      {"tight curve v''=-0.01",
       {.v0 = 350 - 5e-3 * 256 * 256,
        .slope = 2 * 5e-3 * 256,
        .curvature = -5e-3,
        .amplitude = 100,
        .sigma = 1.0},
       181,
       331},
  };
  const PeakParams smoothed;
  ASSERT_GE(smoothed.along_stripe_half_width, 2);
  PeakParams plain = smoothed;
  plain.along_stripe_half_width = 0;
  for (const Case& c : cases) {
    for (double noise : {0.0, 2.0}) {
      Score s0, s1;
      for (int seed = 0; seed < (noise > 0 ? 6 : 1); ++seed) {
        Scene scene;
        scene.width = 512;
        scene.height = 400;
        scene.noise_sigma = noise;
        scene.speckle = noise > 0 ? 0.1 : 0.0;
        scene.stripes = {c.stripe};
        const Frame f = synth::Render(scene, 300 + seed);
        const Score a = ScoreColumns(f, ExtractPeaks(f.view(), plain), c.u_lo, c.u_hi);
        const Score b = ScoreColumns(f, ExtractPeaks(f.view(), smoothed), c.u_lo, c.u_hi);
        for (auto [from, to] : {std::pair{&a, &s0}, std::pair{&b, &s1}}) {
          to->truth += from->truth;
          to->found += from->found;
          to->sum += from->sum;
          to->sum2 += from->sum2;
        }
      }
      std::printf("%s, noise %.0f: RMS %.4f -> %.4f, bias %+.4f -> %+.4f, recall %.2f%%\n", c.name,
                  noise, s0.Rms(), s1.Rms(), s0.Bias(), s1.Bias(), 100 * s1.Recall());
      SCOPED_TRACE(std::string(c.name) + ", noise " + std::to_string(noise));
      EXPECT_GE(s1.Recall(), 0.999);
      EXPECT_LE(std::abs(s1.Bias()), 0.005);
      EXPECT_LE(std::abs(s1.Bias() - s0.Bias()), 0.001);  // The fit adds no bias.
      if (noise > 0) {
        EXPECT_LE(s1.Rms(), 0.7 * s0.Rms());
      } else {
        EXPECT_LE(s1.Rms(), s0.Rms() + 0.001);
      }
    }
  }
}

// The fit must not reach across stripe ends, gaps or steps: noise-free, every peak next to
// them keeps (nearly) its own column's accuracy.
TEST(AlongStripe, EndsGapsAndStepsAreNotSmearedAcross) {
  Scene scene;
  scene.ambient_du = 0;
  scene.ambient_dv = 0;
  // A 1 px step at u = 500 (a small depth discontinuity: both sides link within 1.5 px).
  synth::Stripe left{
      .v0 = 150.3, .slope = 0.1, .amplitude = 80, .sigma = 1.0, .gap_begin = 500, .gap_end = 1024};
  synth::Stripe right = left;
  right.v0 += 1.0;
  right.gap_begin = 0;
  right.gap_end = 500;
  // A 4 px jump at u = 700 (no link) and a gap of 60 columns at u = 200.
  synth::Stripe before{.v0 = 400.6,
                       .slope = -0.05,
                       .amplitude = 90,
                       .sigma = 1.2,
                       .gap_begin = 700,
                       .gap_end = 1024};
  synth::Stripe after = before;
  after.v0 += 4.0;
  after.gap_begin = 0;
  after.gap_end = 700;
  synth::Stripe gapped{
      .v0 = 600.1, .slope = 0.02, .amplitude = 60, .sigma = 0.9, .gap_begin = 200, .gap_end = 260};
  scene.stripes = {left, right, before, after, gapped};
  const Frame f = synth::Render(scene, 5);
  PeakParams plain;
  plain.along_stripe_half_width = 0;
  const auto reference = ExtractPeaks(f.view(), plain);
  const auto peaks = ExtractPeaks(f.view(), PeakParams());
  Score s;
  Evaluate(f, peaks, &s);
  EXPECT_EQ(s.found, s.truth);
  EXPECT_EQ(s.false_peaks, 0);
  ASSERT_EQ(peaks.size(), reference.size());
  double worst = 0;
  for (const synth::Truth& t : f.truth) {
    for (const Peak& p : peaks) {
      if (p.u == t.u && std::abs(p.v - t.v) < 1.5) worst = std::max(worst, std::abs(p.v - t.v));
    }
  }
  std::printf("ends, gaps, steps: worst error %.4f px over %d truths\n", worst, s.truth);
  // Column-wise error here is <= ~0.01 px; a fit across the 1 px step errs by >= 0.08 px.
  EXPECT_LE(worst, 0.02);
}

// Adds a Gaussian column profile (amplitude `a`, sigma 1 px) at row v of column u.
void AddColumnProfile(Frame* f, int u, double v, double a) {
  for (int r = static_cast<int>(v) - 6; r <= static_cast<int>(v) + 6; ++r) {
    uint8_t& px = f->pixels[static_cast<size_t>(r) * f->width + u];
    px =
        static_cast<uint8_t>(std::min(255L, px + std::lround(a * synth::PixelIntegral(r, v, 1.0))));
  }
}

// Peaks of `peaks` within 1.5 px of row v in column u.
int CountAt(const std::vector<Peak>& peaks, int u, double v) {
  int n = 0;
  for (const Peak& p : peaks) n += p.u == u && std::abs(p.v - v) < 1.5;
  return n;
}

// A lone column-wide blob is no stripe; a stripe's end column far dimmer than the one
// next to it is a partly lit column; a dim stripe's one-column gap is no end; an end as
// bright as its stripe stays.
TEST(AlongStripe, IsolatedPeaksAndFadedEndsDropped) {
  Scene scene;
  scene.ambient_du = 0;
  scene.ambient_dv = 0;
  synth::Stripe ends{
      .v0 = 200.3, .amplitude = 120, .sigma = 1.0, .gap_begin = 500, .gap_end = 1024};
  synth::Stripe gapped{
      .v0 = 400.6, .slope = 0.01, .amplitude = 60, .sigma = 1.0, .gap_begin = 300, .gap_end = 301};
  scene.stripes = {ends, gapped};
  Frame f = synth::Render(scene, 9);
  AddColumnProfile(&f, 500, 200.3, 45);  // Faded end: 45 < 0.5 x 120.
  AddColumnProfile(&f, 800, 600.2, 80);  // Isolated.
  // The gapped stripe's column 301 dims to 25 DN above its neighbour's 60 (ratio 0.42),
  // but the stripe goes on at 299 across the gap: no end.
  for (int r = 390; r < 410; ++r) {
    uint8_t& px = f.pixels[static_cast<size_t>(r) * f.width + 301];
    px = static_cast<uint8_t>(30 + std::lround((px - 30) * 25.0 / 60.0));
  }
  const auto peaks = ExtractPeaks(f.view(), PeakParams());
  EXPECT_EQ(CountAt(peaks, 500, 200.3), 0);
  EXPECT_EQ(CountAt(peaks, 800, 600.2), 0);
  EXPECT_EQ(CountAt(peaks, 499, 200.3), 1);  // Now the stripe's end, as bright as it.
  EXPECT_EQ(CountAt(peaks, 301, gapped.Centre(301)), 1);
  EXPECT_EQ(CountAt(peaks, 299, gapped.Centre(299)), 1);
  EXPECT_EQ(CountAt(peaks, 0, 200.3), 1);  // The frame edge ends no stripe's light.
  EXPECT_EQ(CountAt(peaks, 1023, gapped.Centre(1023)), 1);
  PeakParams keep;
  keep.drop_isolated_peaks = false;
  keep.stripe_end_min_ratio = 0;
  const auto all = ExtractPeaks(f.view(), keep);
  EXPECT_EQ(CountAt(all, 500, 200.3), 1);
  EXPECT_EQ(CountAt(all, 800, 600.2), 1);
  EXPECT_EQ(all.size(), peaks.size() + 2);
}

// A threshold near the noise finds a dim stripe (a mirror's view of a back lit at a grazing
// angle: 10-17 DN on rendered frames) but also noise peaks, some in pairs of adjacent
// columns that the isolated-peak rule keeps. Dim peaks must lie on a stripe of
// dim_stripe_min_columns: the stripe stays, the noise and a short dim blob go, and a short
// bright stripe is untouched.
TEST(AlongStripe, DimPeaksStayOnlyOnLongStripes) {
  Scene scene;
  scene.ambient = 6;
  scene.ambient_du = 0;
  scene.ambient_dv = 0;
  scene.noise_sigma = 2.5;  // the rendered frames' dark background, ~2-3 DN
  synth::Stripe dim{.v0 = 300.4, .slope = 0.02, .amplitude = 16, .sigma = 0.9};
  scene.stripes = {dim};
  PeakParams low;
  low.threshold_dn = 8;
  PeakParams rule = low;
  rule.dim_peak_dn = 18;
  rule.dim_stripe_min_columns = 7;
  int stripe_found = 0, stripe_total = 0, false_low = 0, false_rule = 0;
  int short_dim_kept = 0, short_bright_kept = 0;
  constexpr int kFrames = 6;
  for (int seed = 0; seed < kFrames; ++seed) {
    Frame f = synth::Render(scene, 100 + seed);
    // Four columns of a dim blob and four of a bright one, far from the stripe.
    for (int u = 600; u < 604; ++u) AddColumnProfile(&f, u, 600.3, 14);
    for (int u = 800; u < 804; ++u) AddColumnProfile(&f, u, 650.3, 90);
    const auto with_low = ExtractPeaks(f.view(), low);
    const auto with_rule = ExtractPeaks(f.view(), rule);
    auto off_stripe = [&](const std::vector<Peak>& peaks) {
      int n = 0;
      for (const Peak& p : peaks) {
        const bool blob = (p.u >= 600 && p.u < 604) || (p.u >= 800 && p.u < 804);
        n += !blob && std::abs(p.v - dim.Centre(p.u)) > 2;
      }
      return n;
    };
    false_low += off_stripe(with_low);
    false_rule += off_stripe(with_rule);
    for (int u = 0; u < f.width; ++u) {
      ++stripe_total;
      stripe_found += CountAt(with_rule, u, dim.Centre(u));
    }
    for (int u = 600; u < 604; ++u) short_dim_kept += CountAt(with_rule, u, 600.3);
    for (int u = 800; u < 804; ++u) short_bright_kept += CountAt(with_rule, u, 650.3);
  }
  std::printf(
      "dim stripe found %d / %d; off-stripe peaks in %d frames: %d at 8 DN, %d with "
      "the rule\n",
      stripe_found, stripe_total, kFrames, false_low, false_rule);
  EXPECT_GT(stripe_found, 0.9 * stripe_total);
  EXPECT_GT(false_low, 4 * kFrames);  // the noise the rule is for
  EXPECT_LE(false_rule, 1);
  EXPECT_EQ(short_dim_kept, 0);
  EXPECT_EQ(short_bright_kept, 4 * kFrames);
  // At the default threshold the same stripe is mostly lost.
  const auto at18 = ExtractPeaks(synth::Render(scene, 100).view(), PeakParams());
  EXPECT_LT(at18.size(), 0.3 * scene.width);
}

// A wide stripe is blurred along u as much as across it, so its light fades out over a few
// columns past where the stripe ends; clipped, those columns are as wide as the stripe and
// more than half as bright as their neighbour, so the one-column end rule kept them (on
// rendered saturated wide stripes ~30 false peaks per frame). The end is compared with the
// brightest columns further in and peeled while it is dimmer than half of them.
TEST(AlongStripe, WideStripesFadingPastTheirEndAreDropped) {
  constexpr int kWidth = 400, kHeight = 200, kEnd = 300;  // the stripe's last column
  constexpr double kSigma = 2.0, kBlurU = 2.4, kAmplitude = 600, kAmbient = 30;
  Frame f;
  f.width = kWidth;
  f.height = kHeight;
  f.pixels.resize(static_cast<size_t>(kWidth) * kHeight);
  std::mt19937 rng(12);
  std::normal_distribution<double> noise(0.0, 1.0);
  auto centre = [](int u) { return 100.3 + 0.03 * u; };
  for (int u = 0; u < kWidth; ++u) {
    // The end blurred along u: the share of a Gaussian of sigma kBlurU before kEnd + 0.5.
    const double along = 0.5 * std::erfc((u - kEnd - 0.5) / (kBlurU * std::sqrt(2.0)));
    for (int r = 0; r < kHeight; ++r) {
      const double light = kAmplitude * along * synth::PixelIntegral(r, centre(u), kSigma);
      const double x = kAmbient + light + noise(rng);
      f.pixels[static_cast<size_t>(r) * kWidth + u] =
          static_cast<uint8_t>(std::clamp(std::lround(x), 0L, 255L));
    }
  }
  // Columns kEnd + 3 ... (light 12, 6, 3 % of the stripe's: 87, 41, 18 DN after clipping
  // beside 151 and 222 DN) go; kEnd + 2 (27 % of the stripe's light, clipped to 151 DN: 0.68
  // of its neighbour and of the clipped columns in) stays: clipping hides that it is dimmer.
  const auto peaks = ExtractPeaks(f.view(), PeakParams());
  int past_end = 0;
  for (const Peak& p : peaks) past_end += p.u > kEnd + 2;
  EXPECT_EQ(past_end, 0);
  for (int u = 1; u <= kEnd + 1; ++u) EXPECT_EQ(CountAt(peaks, u, centre(u)), 1) << u;
  // Without the end rule those columns are there (what the rule drops).
  PeakParams keep;
  keep.stripe_end_min_ratio = 0;
  int kept_past_end = 0;
  for (const Peak& p : ExtractPeaks(f.view(), keep)) kept_past_end += p.u > kEnd + 2;
  EXPECT_EQ(kept_past_end, 3);
}

TEST(PeakOutput, SortedScoredAndReusable) {
  std::mt19937 rng(4);
  Scene scene;
  scene.noise_sigma = 2;
  scene.stripes = synth::RandomStripes(9, scene.height, 40, 250, &rng);
  const Frame f = synth::Render(scene, 5);
  PeakExtractor extractor;
  std::vector<Peak> peaks;
  PeakParams params;
  extractor.Extract(f.view(), params, &peaks);
  ASSERT_FALSE(peaks.empty());
  for (size_t i = 1; i < peaks.size(); ++i) {
    ASSERT_TRUE(peaks[i - 1].u < peaks[i].u ||
                (peaks[i - 1].u == peaks[i].u && peaks[i - 1].v < peaks[i].v));
  }
  for (const Peak& p : peaks) {
    EXPECT_GE(p.score, 0.0f);
    EXPECT_LE(p.score, 1.0f);
    EXPECT_GT(p.width, params.min_width_px);
    EXPECT_GE(p.intensity, params.threshold_dn);
  }
  // Steady state: the same buffers are reused, nothing grows.
  const Peak* data = peaks.data();
  const size_t capacity = peaks.capacity();
  for (int i = 0; i < 5; ++i) extractor.Extract(f.view(), params, &peaks);
  EXPECT_EQ(peaks.data(), data);
  EXPECT_EQ(peaks.capacity(), capacity);
}

TEST(PeakOutput, RoiAndExcludedRectangles) {
  Scene scene;
  scene.stripes = {synth::Stripe{.v0 = 200, .amplitude = 100, .sigma = 1},
                   synth::Stripe{.v0 = 500, .amplitude = 100, .sigma = 1}};
  const Frame f = synth::Render(scene, 1);
  PeakParams params;
  params.roi = {100, 150, 500, 100};
  auto peaks = ExtractPeaks(f.view(), params);
  ASSERT_EQ(peaks.size(), 500u);
  EXPECT_EQ(peaks.front().u, 100);
  EXPECT_EQ(peaks.back().u, 599);
  params = PeakParams();
  params.excluded = {{0, 450, 512, 100}};
  peaks = ExtractPeaks(f.view(), params);
  EXPECT_EQ(peaks.size(), 1024u + 512u);
}

TEST(PeakParamsTest, FromJsonReadsAndRejects) {
  const auto good = JsonReader::ParseText(
      R"({"peaks": {"estimator": "gaussian3", "threshold_dn": 25, "window": 10,
          "along_stripe_half_width": 3, "drop_isolated_peaks": false,
          "stripe_end_min_ratio": 0.25, "dim_peak_dn": 20, "dim_stripe_min_columns": 9,
          "roi": {"x": 1, "y": 2, "width": 30, "height": 40},
          "excluded": [{"x": 5, "y": 6, "width": 7, "height": 8}]}})",
      "board.json");
  const PeakParams p = PeakParams::FromJson(JsonReader(good, "board.json").Object("peaks"));
  EXPECT_EQ(p.estimator, PeakEstimator::kGaussian3);
  EXPECT_EQ(p.threshold_dn, 25);
  EXPECT_EQ(p.window, 10);
  EXPECT_EQ(p.along_stripe_half_width, 3);
  EXPECT_FALSE(p.drop_isolated_peaks);
  EXPECT_FLOAT_EQ(p.stripe_end_min_ratio, 0.25f);
  EXPECT_EQ(p.dim_peak_dn, 20);
  EXPECT_EQ(p.dim_stripe_min_columns, 9);
  EXPECT_EQ(p.roi.height, 40);
  ASSERT_EQ(p.excluded.size(), 1u);
  EXPECT_EQ(p.excluded[0].width, 7);

  auto error = [](const std::string& text) -> std::string {
    const auto j = JsonReader::ParseText(text, "board.json");
    try {
      PeakParams::FromJson(JsonReader(j, "board.json").Object("peaks"));
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_EQ(error(R"({"peaks": {"treshold_dn": 3}})").rfind("board.json: peaks", 0), 0u);
  EXPECT_NE(error(R"({"peaks": {"treshold_dn": 3}})").find("treshold_dn"), std::string::npos);
  EXPECT_NE(error(R"({"peaks": {"estimator": "magic"}})").find("peaks.estimator"),
            std::string::npos);
  EXPECT_NE(error(R"({"peaks": {"threshold_dn": 0}})").find("peaks.threshold_dn"),
            std::string::npos);
  EXPECT_NE(
      error(R"({"peaks": {"min_width_px": 5, "max_width_px": 4}})").find("peaks.max_width_px"),
      std::string::npos);
  EXPECT_NE(error(R"({"peaks": {"roi": {"x": -1}}})").find("peaks.roi.x"), std::string::npos);
  EXPECT_NE(error(R"({"peaks": {"excluded": [{"x": 1, "y": 1, "width": 0, "height": 1}]}})")
                .find("peaks.excluded[0].width"),
            std::string::npos);
  EXPECT_NE(error(R"({"peaks": {"window": 2}})").find("peaks.window"), std::string::npos);
  EXPECT_NE(
      error(R"({"peaks": {"along_stripe_half_width": 9}})").find("peaks.along_stripe_half_width"),
      std::string::npos);
  EXPECT_NE(
      error(R"({"peaks": {"along_stripe_half_width": -1}})").find("peaks.along_stripe_half_width"),
      std::string::npos);

  EXPECT_NE(error(R"({"peaks": {"stripe_end_min_ratio": 1.5}})").find("peaks.stripe_end_min_ratio"),
            std::string::npos);
  EXPECT_NE(error(R"({"peaks": {"drop_isolated_peaks": 1}})").find("peaks.drop_isolated_peaks"),
            std::string::npos);
  EXPECT_NE(
      error(R"({"peaks": {"dim_stripe_min_columns": 65}})").find("peaks.dim_stripe_min_columns"),
      std::string::npos);
  PeakParams bad;
  bad.stripe_end_min_ratio = -0.1f;
  EXPECT_THROW(bad.Validate(), std::invalid_argument);
  bad.stripe_end_min_ratio = 0.5f;
  bad.along_stripe_half_width = kMaxAlongStripeHalfWidth + 1;
  EXPECT_THROW(bad.Validate(), std::invalid_argument);
  bad.along_stripe_half_width = 0;
  bad.max_peaks_per_column = 0;
  try {
    bad.Validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("peaks.max_peaks_per_column"), std::string::npos);
  }
}

}  // namespace
}  // namespace mirrorscan
