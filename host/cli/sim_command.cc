#include "host/cli/sim_command.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <mutex>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "boards/virtual/renderer.h"
#include "boards/virtual/scene.h"
#include "boards/virtual/surface_samples.h"
#include "boards/virtual/sweep_peaks.h"
#include "common/config/calibration.h"
#include "common/config/json_reader.h"
#include "common/mesh/mesh_io.h"
#include "common/peaks/peaks.h"
#include "common/protocol/sha256.h"
#include "common/scan_format/scan_format.h"
#include "host/board/board_json.h"

namespace mirrorscan::cli {

namespace fs = std::filesystem;
using virtual_cabinet::GrayImage;
using virtual_cabinet::Renderer;
using virtual_cabinet::Scene;
using virtual_cabinet::TruthPeak;

namespace {

struct SimOptions {
  std::string scene_path;
  std::string out;
  std::string truth_out;
  std::string camera;
  int frame = -1;
  double time = -1;
  int frames = -1;
  bool no_lasers = false;
  bool no_noise = false;
  bool truth = false;
  bool json = false;
  std::string contact_sheet;
  std::string peaks;  // .mscan archive of the sweep's peaks
  std::string board;  // peak extractor parameters from this board.json
  // The calibration the archive is made with (as a device records the one it holds);
  // default: the scene's true calibration, embedded whole.
  std::string calibration;
  bool no_images = false;
  bool pgm = false;            // frames as binary PGM (what the replay camera plays) instead of PNG
  double distance_mm = 900.0;  // chessboard: from the camera
  double spacing_mm = 4.0;     // `sim surface`: one truth sample per spacing² of area
};

// A view of the rendered pixels (no copy); valid while `image` lives.
cv::Mat MatView(const GrayImage& image) {
  return cv::Mat(image.height, image.width, CV_8U, const_cast<uint8_t*>(image.pixels.data()));
}

void WritePng(const fs::path& path, const cv::Mat& image) {
  if (!cv::imwrite(path.string(), image)) throw std::runtime_error("cannot write " + path.string());
}

void WriteJson(const fs::path& path, const nlohmann::json& json) {
  std::ofstream out(path);
  out << json.dump(2) << "\n";
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

void WriteTruthCsv(std::ostream& out, int frame, const std::vector<TruthPeak>& peaks) {
  out << std::setprecision(10);
  for (const auto& p : peaks) {
    out << frame << ',' << p.u << ',' << p.v << ',' << p.laser << ',' << ViewName(p.view) << ','
        << p.point_in_world.x() << ',' << p.point_in_world.y() << ',' << p.point_in_world.z() << ','
        << p.peak_dn << ',' << MaterialName(p.material) << '\n';
  }
}
constexpr const char* kTruthHeader = "frame,u,v,laser,view,x_mm,y_mm,z_mm,peak_dn,material\n";

Scene LoadScene(const SimOptions& o) {
  Scene scene = Scene::Load(o.scene_path);
  if (o.no_noise) scene.sensor.noise = false;
  if (o.frames > 0) scene.frames = o.frames;
  return scene;
}

std::vector<int> SelectCameras(const Scene& scene, const std::string& name) {
  std::vector<int> cameras;
  for (size_t i = 0; i < scene.cameras.size(); ++i) {
    if (name.empty() || scene.cameras[i].name == name) cameras.push_back(static_cast<int>(i));
  }
  if (cameras.empty()) {
    std::string names;
    for (const auto& c : scene.cameras) names += (names.empty() ? "" : ", ") + c.name;
    throw std::runtime_error("--camera " + name + ": no such camera (scene has: " + names + ")");
  }
  return cameras;
}

nlohmann::json SceneInfo(const Scene& scene) {
  nlohmann::json info = {
      {"subject", {{"type", scene.subject.type}, {"metadata", scene.subject.metadata}}},
      {"frames", scene.frames},
      {"fps", scene.cameras[0].fps},
      {"seed", scene.seed}};
  if (scene.target) info["target"] = scene.target->ToJson();
  return info;
}

void Render(const SimOptions& o) {
  const Scene scene = LoadScene(o);
  const Renderer renderer(scene);
  int frame = o.frame >= 0 ? o.frame : scene.frames / 2;
  double t = scene.FrameTime(frame);
  if (o.time >= 0) t = o.time;
  fs::create_directories(o.out);
  nlohmann::json written = nlohmann::json::array();
  for (int camera : SelectCameras(scene, o.camera)) {
    const std::string stem = scene.cameras[camera].name + "_frame" + std::to_string(frame);
    const fs::path png = fs::path(o.out) / (stem + ".png");
    const GrayImage image =
        renderer.RenderFrame(camera, t, static_cast<uint64_t>(frame), !o.no_lasers);
    WritePng(png, MatView(image));
    nlohmann::json entry = {
        {"camera", scene.cameras[camera].name}, {"image", png.string()}, {"time_s", t}};
    if (!o.no_lasers) {
      const fs::path csv = fs::path(o.out) / (stem + "_truth.csv");
      std::ofstream out(csv);
      out << kTruthHeader;
      const auto peaks = renderer.Truth(camera, t);
      WriteTruthCsv(out, frame, peaks);
      entry["truth"] = csv.string();
      entry["truth_peaks"] = peaks.size();
    }
    written.push_back(entry);
  }
  WriteJson(fs::path(o.out) / "calibration.json", scene.TrueCalibration());
  WriteJson(fs::path(o.out) / "scene.json", SceneInfo(scene));
  if (o.json) {
    std::printf("%s\n", nlohmann::json({{"frames", written}}).dump(2).c_str());
  } else {
    for (const auto& e : written) std::printf("%s\n", e["image"].get<std::string>().c_str());
  }
}

void Scan(const SimOptions& o) {
  const Scene scene = LoadScene(o);
  const Renderer renderer(scene);
  const std::vector<int> cameras = SelectCameras(scene, o.camera);
  fs::create_directories(o.out);
  for (int camera : cameras) fs::create_directories(fs::path(o.out) / scene.cameras[camera].name);

  const auto start = std::chrono::steady_clock::now();
  const int total = scene.frames * static_cast<int>(cameras.size());
  std::atomic<int> next{0}, done{0};
  std::mutex truth_mutex, error_mutex;
  std::string error;
  std::vector<std::ofstream> truth_files;
  if (o.truth) {
    for (int camera : cameras) {
      truth_files.emplace_back(fs::path(o.out) / scene.cameras[camera].name / "truth.csv");
      truth_files.back() << kTruthHeader;
    }
  }
  const int sheet_step = std::max(1, scene.frames / 12);
  const PeakParams peak_params =
      o.board.empty() ? PeakParams() : host_board::PeakParamsFromBoard(o.board);
  // Frames render out of order on several threads; records are kept by job and written
  // in order once the sweep is done.
  std::vector<FrameRecord> records(o.peaks.empty() ? 0 : total);
  std::vector<cv::Mat> sheet_frames(cameras.size() * 12);

  auto worker = [&] {
    PeakExtractor extractor;
    for (int job = next++; job < total; job = next++) {
      try {
        const int frame = job / static_cast<int>(cameras.size());
        const size_t which = job % cameras.size();
        const int camera = cameras[which];
        const double t = scene.FrameTime(frame);
        const GrayImage rendered =
            renderer.RenderFrame(camera, t, static_cast<uint64_t>(frame), !o.no_lasers);
        const cv::Mat image = MatView(rendered);
        if (!o.no_images) {
          std::ostringstream name;
          name << "frame_" << std::setw(6) << std::setfill('0') << frame
               << (o.pgm ? ".pgm" : ".png");
          WritePng(fs::path(o.out) / scene.cameras[camera].name / name.str(), image);
        }
        if (!o.peaks.empty()) {
          records[job] = virtual_cabinet::SweepFrameRecord(scene, camera, frame, rendered,
                                                           !o.no_lasers, peak_params, &extractor);
        }
        if (!o.contact_sheet.empty() && frame % sheet_step == 0 && frame / sheet_step < 12) {
          sheet_frames[which * 12 + frame / sheet_step] = image.clone();
        }
        if (o.truth) {
          const auto peaks = renderer.Truth(camera, t);
          std::lock_guard<std::mutex> lock(truth_mutex);
          WriteTruthCsv(truth_files[which], frame, peaks);
        }
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (error.empty()) error = e.what();
        next = total;
      }
      const int finished = ++done;
      if (!o.json && (finished % 20 == 0 || finished == total)) {
        std::fprintf(stderr, "\rsim scan: %d/%d frames", finished, total);
      }
    }
  };
  std::vector<std::thread> pool;
  for (unsigned i = 0; i < std::max(1u, std::thread::hardware_concurrency()); ++i)
    pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  if (!o.json) std::fprintf(stderr, "\n");
  if (!error.empty()) throw std::runtime_error(error);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  nlohmann::json sweep = SceneInfo(scene);
  sweep["cameras"] = nlohmann::json::array();
  for (int camera : cameras) sweep["cameras"].push_back(scene.cameras[camera].name);
  sweep["frame_time_s"] = 1.0 / scene.cameras[0].fps;
  sweep["laser_height_at_t0_mm"] = scene.lasers.start_mm;
  sweep["slide_speed_mm_s"] = scene.lasers.speed_mm_s;
  sweep["laser_spacing_mm"] = scene.lasers.spacing_mm;
  sweep["lasers"] = scene.lasers.count;
  WriteJson(fs::path(o.out) / "sweep.json", sweep);
  WriteJson(fs::path(o.out) / "calibration.json", scene.TrueCalibration());
  if (!o.peaks.empty()) {
    ScanFileWriterOptions writer_options;
    writer_options.overwrite = true;
    ScanFileWriter writer(o.peaks, writer_options);
    nlohmann::json header = virtual_cabinet::SweepArchiveHeader(scene);
    header["device"] = "virtual-cabinet";
    header["board"] = "virtual";
    header["source"] = "mirrorscan sim scan";
    header["scene"] = o.scene_path;
    if (!o.calibration.empty()) {
      header.erase("calibration");
      header["calibration_sha256"] = protocol::Sha256::HexOfFile(o.calibration);
      header["calibration_hash"] = Calibration::Load(o.calibration).ContentHash();
    }
    writer.Begin(header);
    size_t peak_count = 0;
    for (const FrameRecord& record : records) {
      writer.AppendFrame(record);
      peak_count += record.peaks.size();
    }
    writer.Finish(
        {{"frames", records.size()},
         {"peaks", peak_count},
         {"dropped_frames", 0},
         {"status", "complete"},
         {"end_time_ns", static_cast<int64_t>(std::llround(scene.FrameTime(scene.frames) * 1e9))}});
    if (!o.json)
      std::printf("wrote %zu frames, %zu peaks to %s\n", records.size(), peak_count,
                  o.peaks.c_str());
  }

  if (!o.contact_sheet.empty()) {
    // Twelve frames per camera spread over the sweep, one row per camera, at half size.
    std::vector<cv::Mat> rows;
    for (size_t c = 0; c < cameras.size(); ++c) {
      std::vector<cv::Mat> tiles;
      for (int i = 0; i < 12; ++i) {
        cv::Mat tile = sheet_frames[c * 12 + i];
        if (tile.empty()) continue;
        cv::resize(tile, tile, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
        tiles.push_back(tile);
      }
      if (tiles.empty()) continue;
      std::vector<cv::Mat> grid_rows;
      for (size_t i = 0; i < tiles.size(); i += 4) {
        std::vector<cv::Mat> line(tiles.begin() + i, tiles.begin() + std::min(tiles.size(), i + 4));
        while (line.size() < 4) line.push_back(cv::Mat::zeros(tiles[0].size(), CV_8U));
        cv::Mat joined;
        cv::hconcat(line, joined);
        grid_rows.push_back(joined);
      }
      cv::Mat grid;
      cv::vconcat(grid_rows, grid);
      rows.push_back(grid);
    }
    cv::Mat sheet;
    cv::vconcat(rows, sheet);
    WritePng(o.contact_sheet, sheet);
  }
  const double fps = total / seconds;
  if (o.json) {
    std::printf(
        "%s\n",
        nlohmann::json(
            {{"frames", total}, {"seconds", seconds}, {"frames_per_second", fps}, {"out", o.out}})
            .dump(2)
            .c_str());
  } else {
    std::printf("rendered %d frames in %.2f s (%.1f frames/s) into %s\n", total, seconds, fps,
                o.out.c_str());
  }
}

// Photographs for a lens calibration: the scene's chessboard (or the default one) held in
// front of each camera in the poses an operator would use, lasers off.
void Chessboard(const SimOptions& o) {
  const Scene base = LoadScene(o);
  const virtual_cabinet::ChessboardConfig board =
      base.chessboard ? base.chessboard->config() : virtual_cabinet::ChessboardConfig{};
  fs::create_directories(o.out);
  nlohmann::json images = nlohmann::json::array();
  for (int camera : SelectCameras(base, o.camera)) {
    const auto poses =
        virtual_cabinet::LensCalibrationPoses(base.cameras[camera].camera, board, o.distance_mm);
    for (size_t i = 0; i < poses.size(); ++i) {
      Scene scene = base;
      scene.chessboard.emplace(poses[i]);
      scene.lasers.power = 0.0;  // lasers off for a lens calibration
      const Renderer renderer(scene);
      const GrayImage image = renderer.RenderFrame(camera, 0.0, i, /*lasers_on=*/false);
      const std::string name = scene.cameras[camera].name + "_chessboard" + (i < 10 ? "0" : "") +
                               std::to_string(i) + ".png";
      WritePng(fs::path(o.out) / name, MatView(image));
      const Eigen::Vector3d& c = poses[i].center_mm;
      images.push_back({{"camera", scene.cameras[camera].name},
                        {"image", name},
                        {"center_mm", {c.x(), c.y(), c.z()}}});
      std::fprintf(stderr, "sim chessboard: %s (%zu of %zu)\n", name.c_str(), i + 1, poses.size());
    }
  }
  const nlohmann::json info = {{"inner_corners", {board.inner_columns, board.inner_rows}},
                               {"square_mm", board.square_mm},
                               {"distance_mm", o.distance_mm},
                               {"images", images}};
  WriteJson(fs::path(o.out) / "chessboard.json", info);
  if (o.json) {
    std::printf("%s\n", info.dump(2).c_str());
  } else {
    std::printf("rendered %zu chessboard images (%dx%d inner corners, %g mm squares) into %s\n",
                images.size(), board.inner_columns, board.inner_rows, board.square_mm,
                o.out.c_str());
  }
}

// The scene's subject as a mesh file, and its metadata (a mannequin's "truth" with it).
void WriteSubject(const SimOptions& o) {
  const Scene scene = Scene::Load(o.scene_path);
  if (scene.subject.mesh.empty())
    throw std::runtime_error(o.scene_path + ": the scene has no subject");
  try {
    WriteTriangleMesh(scene.subject.mesh, o.out);
  } catch (const MeshIoError& e) {
    throw std::runtime_error(e.what());
  }
  if (!o.truth_out.empty()) {
    std::ofstream out(o.truth_out);
    out << scene.subject.metadata.dump(2) << "\n";
    if (!out) throw std::runtime_error(o.truth_out + ": cannot write");
  }
  const nlohmann::json summary = {{"mesh", o.out},
                                  {"type", scene.subject.type},
                                  {"triangles", scene.subject.mesh.triangles.size()}};
  if (o.json) {
    std::printf("%s\n", summary.dump(2).c_str());
  } else {
    std::printf("wrote the %s (%zu triangles) to %s\n", scene.subject.type.c_str(),
                scene.subject.mesh.triangles.size(), o.out.c_str());
  }
}

// The subject's true surface for scoring a mesh: the mesh itself and samples on it marked
// with whether the cabinet can scan them.
void Surface(const SimOptions& o) {
  const Scene scene = LoadScene(o);
  if (scene.subject.mesh.empty())
    throw std::runtime_error(o.scene_path + ": the scene has no subject");
  const Renderer renderer(scene);
  fs::create_directories(o.out);
  WriteTriangleMesh(scene.subject.mesh, fs::path(o.out) / "subject.ply");
  const auto samples = virtual_cabinet::SampleSubjectSurface(renderer, o.spacing_mm, scene.seed);
  std::ofstream csv(fs::path(o.out) / "surface-samples.csv");
  csv << "x_mm,y_mm,z_mm,nx,ny,nz,visible\n" << std::setprecision(10);
  size_t visible = 0;
  for (const auto& s : samples) {
    csv << s.point_in_world.x() << ',' << s.point_in_world.y() << ',' << s.point_in_world.z() << ','
        << s.normal.x() << ',' << s.normal.y() << ',' << s.normal.z() << ',' << (s.visible ? 1 : 0)
        << '\n';
    visible += s.visible ? 1 : 0;
  }
  if (!csv)
    throw std::runtime_error("cannot write " + (fs::path(o.out) / "surface-samples.csv").string());
  WriteJson(fs::path(o.out) / "scene.json", SceneInfo(scene));
  if (o.json) {
    std::printf("%s\n",
                nlohmann::json({{"samples", samples.size()}, {"visible", visible}, {"out", o.out}})
                    .dump(2)
                    .c_str());
  } else {
    std::printf("%zu surface samples, %zu visible to the cabinet, in %s\n", samples.size(), visible,
                o.out.c_str());
  }
}

}  // namespace

void AddSimCommands(CLI::App& app) {
  auto* sim =
      app.add_subcommand("sim", "The virtual cabinet: render frames with ground truth, offline");
  sim->require_subcommand(1);
  auto options = std::make_shared<SimOptions>();

  auto* render = sim->add_subcommand(
      "render", "Render one frame per camera, its ground truth and the true calibration");
  render->add_option("--scene", options->scene_path, "Scene file (see docs/virtual-cabinet.md)")
      ->required()
      ->check(CLI::ExistingFile);
  render->add_option("--out", options->out, "Output directory")->required();
  render->add_option("--frame", options->frame, "Frame index of the sweep (default: the middle)")
      ->check(CLI::NonNegativeNumber);
  render->add_option("--time", options->time, "Slide time in seconds (overrides --frame)")
      ->check(CLI::NonNegativeNumber);
  render->add_option("--camera", options->camera, "Only this camera (by name)");
  render->add_flag("--no-lasers", options->no_lasers,
                   "Lasers off (e.g. a calibration target frame)");
  render->add_flag("--no-noise", options->no_noise,
                   "Noise-free sensor (no shot/read noise, no speckle)");
  render->add_flag("--json", options->json, "Machine-readable output");
  render->callback([options] { Render(*options); });

  auto* scan = sim->add_subcommand(
      "scan",
      "Render the frames of a whole sweep, per camera, with sweep.json and the true calibration");
  scan->add_option("--scene", options->scene_path, "Scene file")
      ->required()
      ->check(CLI::ExistingFile);
  scan->add_option("--out", options->out, "Output directory")->required();
  scan->add_option("--frames", options->frames, "Render only the first N frames")
      ->check(CLI::PositiveNumber);
  scan->add_option("--camera", options->camera, "Only this camera (by name)");
  scan->add_flag("--truth", options->truth,
                 "Also write <camera>/truth.csv (stripe centres per column)");
  scan->add_flag("--no-noise", options->no_noise, "Noise-free sensor");
  scan->add_option("--contact-sheet", options->contact_sheet,
                   "Write a PNG with 12 frames per camera");
  scan->add_option("--peaks", options->peaks,
                   "Also extract laser peaks from every frame into this .mscan archive");
  scan->add_option("--board", options->board,
                   "Peak extractor parameters from this board.json (its \"peaks\" object)")
      ->check(CLI::ExistingFile);
  scan->add_option("--calibration", options->calibration,
                   "With --peaks: record this calibration in the archive's header (its SHA-256 "
                   "and content hash, as the device does) instead of the scene's true one")
      ->check(CLI::ExistingFile);
  scan->add_flag("--no-images", options->no_images, "Do not write PNG frames (e.g. with --peaks)");
  scan->add_flag("--pgm", options->pgm,
                 "Write frames as 8-bit binary PGM (P5), which the firmware's replay camera plays");
  scan->add_flag("--json", options->json, "Machine-readable output");
  scan->callback([options] { Scan(*options); });

  auto* chessboard =
      sim->add_subcommand("chessboard",
                          "Render a chessboard held in front of each camera in several poses, for "
                          "calibrate-intrinsics");
  chessboard
      ->add_option("--scene", options->scene_path,
                   "Scene file (its \"chessboard\" object sets the pattern)")
      ->required()
      ->check(CLI::ExistingFile);
  chessboard->add_option("--out", options->out, "Output directory")->required();
  chessboard->add_option("--camera", options->camera, "Only this camera (by name)");
  chessboard
      ->add_option("--distance-mm", options->distance_mm,
                   "Board distance from the camera (default 900)")
      ->check(CLI::Range(100.0, 5000.0));
  chessboard->add_flag("--no-noise", options->no_noise, "Noise-free sensor");
  chessboard->add_flag("--json", options->json, "Machine-readable output");
  chessboard->callback([options] { Chessboard(*options); });

  auto* subject = sim->add_subcommand(
      "subject", "Write the scene's exact subject surface as a mesh, and its truth as JSON");
  subject->add_option("--scene", options->scene_path, "Scene file")
      ->required()
      ->check(CLI::ExistingFile);
  subject->add_option("--out", options->out, "Mesh file (.ply, .obj or .stl)")->required();
  subject->add_option("--truth", options->truth_out,
                      "Write the subject's metadata here (a mannequin's measurement truth)");
  subject->add_flag("--json", options->json, "Machine-readable output");
  subject->callback([options] { WriteSubject(*options); });
  auto* surface = sim->add_subcommand(
      "surface",
      "The subject's true surface (subject.ply) and samples on it marked visible when a camera "
      "view sees them and a laser reaches them (surface-samples.csv), for scoring a mesh");
  surface->add_option("--scene", options->scene_path, "Scene file")
      ->required()
      ->check(CLI::ExistingFile);
  surface->add_option("--out", options->out, "Output directory")->required();
  surface->add_option("--spacing", options->spacing_mm, "About one sample per spacing² (mm)")
      ->check(CLI::Range(0.5, 100.0))
      ->capture_default_str();
  surface->add_flag("--json", options->json, "Machine-readable output");
  surface->callback([options] { Surface(*options); });
}

}  // namespace mirrorscan::cli
