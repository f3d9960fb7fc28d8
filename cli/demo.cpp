// vkjr2 demo-turbulence: the turbulence-vs-recognition study on media Debian
// and npm ship.
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/jr2/metrics.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/nets/face_box.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/host_tensor.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "cv_image.hpp"
#include "log.hpp"
#include "media.hpp"
#include "progress.hpp"
#include "sim_common.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kVideo = "/usr/share/doc/opencv-doc/examples/data/vtest.avi";
constexpr std::array<const char*, 3> kStrengths{"weak", "moderate", "strong"};
constexpr double kMatchIou = 0.3;  // a degraded detection is the clean face it overlaps this much

struct DemoArgs {
  std::string out = "out/demo_turbulence", device, video = kVideo;
  int frames = 2, video_frames = 16, width = 640, photos = 6;
  std::uint64_t seed = 1;
  bool quiet = false, force = false, json_out = false;
};

struct Photo {
  std::string name;
  cv::Mat bgr;  // resized, 8-bit
  Image rgb;    // the same, H×W×3 float 0..255
  std::vector<jr2::Face> faces;
  std::vector<std::string> ids;  // per clean face: "sampleN#i"
};

void label(cv::Mat& img, const nets::FaceBox& box, const std::string& text,
           const cv::Scalar& colour) {
  const cv::Rect r(int(box.x), int(box.y), int(box.width), int(box.height));
  cv::rectangle(img, r, colour, 2);
  int base = 0;
  const cv::Size ts = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, 0.4, 1, &base);
  const cv::Point at(std::max(0, r.x), std::max(ts.height + 2, r.y - 3));
  cv::rectangle(img, cv::Rect(at.x, at.y - ts.height - 2, ts.width + 2, ts.height + 4), colour,
                cv::FILLED);
  cv::putText(img, text, cv::Point(at.x + 1, at.y), cv::FONT_HERSHEY_SIMPLEX, 0.4,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
}

void banner(cv::Mat& img, const std::string& text) {
  cv::rectangle(img, cv::Rect(0, 0, img.cols, 22), cv::Scalar(0, 0, 0), cv::FILLED);
  cv::putText(img, text, cv::Point(6, 16), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255),
              1, cv::LINE_AA);
}

void write_image_mat(const fs::path& path, const cv::Mat& m, bool force) {
  Image img = image_from_bgr(m);
  write_image(path, img, force);
}

void write_text(const fs::path& path, const std::string& text, bool force) {
  check_writable(path, force);
  vkjr2::write_file_atomic(path, std::as_bytes(std::span(text)), "demo");
}

struct StrengthStats {
  std::string name;
  double d_over_r0 = 0, tilt_std_px = 0;
  std::size_t expected = 0, detected = 0, rank1 = 0;
  double distance_sum = 0, cosine_sum = 0;
  json to_json() const {
    const double n = double(std::max<std::size_t>(detected, 1));
    return {{"strength", name},
            {"d_over_r0", d_over_r0},
            {"tilt_std_px", tilt_std_px},
            {"faces", expected},
            {"detected", detected},
            {"detection_rate", double(detected) / double(std::max<std::size_t>(expected, 1))},
            {"mean_descriptor_distance", distance_sum / n},
            {"mean_cosine_similarity", cosine_sum / n},
            {"rank1_of_detected", double(rank1) / n},
            {"rank1_of_all", double(rank1) / double(std::max<std::size_t>(expected, 1))}};
  }
};

void run_demo(const DemoArgs& a) {
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path out(a.out);
  check_output_folder(out, "--out");
  std::error_code ec;
  if (!fs::exists(a.video, ec)) {
    throw UsageError(
        "--video", a.video + " is missing",
        a.video == kVideo ? "install Debian's opencv-doc (scripts/setup)" : "check the path");
  }
  check_input_file(a.video, "--video");
  // The video is read last: a file that cannot be decoded fails here, before
  // minutes of work and before --out is made.
  read_video(a.video, 1, 1, [](std::size_t, const Image&) {});
  for (const char* f : {"montage.png", "vtest_strong.avi", "results.json", "report.md"})
    if (fs::exists(out / f, ec)) check_output_file(out / f, a.force, "--out");
  create_output_folder(out, "--out");
  const fs::path demo_dir = nets::face_api_model_dir().parent_path() / "demo";
  std::vector<Photo> photos;
  for (int i = 1; i <= a.photos; ++i) {
    const fs::path p = demo_dir / ("sample" + std::to_string(i) + ".jpg");
    cv::Mat m = cv::imread(p.string());
    if (m.empty())
      throw Error("demo", "cannot read " + p.string(),
                  "run scripts/setup (it fetches face-api's photos)");
    cv::Mat small;
    cv::resize(m, small, cv::Size(a.width, int(std::lround(double(m.rows) * a.width / m.cols))), 0,
               0, cv::INTER_AREA);
    photos.push_back({p.stem().string(), small, image_from_bgr(small), {}, {}});
  }

  const Device device = open_device(a.device);
  const jr2::FaceAnalyzer analyzer(device);
  const auto blur = sim::load_shipped_blur_models(device);
  Stream stream(device);
  jr2::FaceOptions fo;
  // Clean faces and the gallery.
  std::vector<jr2::GalleryEntry> gallery;
  for (Photo& ph : photos) {
    ph.faces = analyzer.analyze(stream, nets::image_to_device(device, ph.rgb), fo);
    for (std::size_t i = 0; i < ph.faces.size(); ++i) {
      ph.ids.push_back(ph.name + "#" + std::to_string(i + 1));
      gallery.push_back({ph.ids.back(), ph.name, ph.faces[i].descriptor});
    }
  }
  const std::size_t total_faces = gallery.size();
  const std::size_t steps =
      kStrengths.size() * photos.size() * std::size_t(a.frames) + std::size_t(a.video_frames);
  Progress bar("demo", steps, a.quiet);
  std::size_t done = 0;
  std::vector<StrengthStats> stats;
  std::vector<std::vector<cv::Mat>> panels(
      photos.size());  // [photo][clean, weak, moderate, strong]
  for (std::size_t p = 0; p < photos.size(); ++p) {
    cv::Mat clean = photos[p].bgr.clone();
    for (std::size_t i = 0; i < photos[p].faces.size(); ++i)
      label(clean, photos[p].faces[i].box, photos[p].ids[i], {0, 200, 0});
    banner(clean,
           photos[p].name + ": clean (" + std::to_string(photos[p].faces.size()) + " faces)");
    panels[p].push_back(clean);
  }
  for (std::size_t s = 0; s < kStrengths.size(); ++s) {
    StrengthStats st;
    st.name = kStrengths[s];
    for (std::size_t p = 0; p < photos.size(); ++p) {
      const Photo& ph = photos[p];
      PathArgs pa;
      pa.preset = kStrengths[s];
      const sim::Params params = params_for_image(pa, int(ph.rgb.shape[0]), int(ph.rgb.shape[1]));
      sim::SimOptions so;
      sim::Simulator sim(device, params, blur, so);
      st.d_over_r0 = sim.derived().channels[0].d_over_r0;
      st.tilt_std_px = sim.derived().channels[0].tilt_std_px;
      sim.reset(a.seed + 1000 * s + p);
      const Shape shape{1, 3, ph.rgb.shape[0], ph.rgb.shape[1]};
      const Tensor x = Tensor::from(device, shape, image_to_planes(ph.rgb, 3, 255.f));
      const Tensor y = Tensor::empty(device, shape), y255 = Tensor::empty(device, shape);
      for (int t = 0; t < a.frames; ++t) {
        sim.frame(stream, x, y);
        kernels::scale_shift(stream, y, 255.f, 0.f, y255);
        const auto faces = analyzer.analyze(stream, y255, fo);
        cv::Mat panel;
        if (t == 0)
          panel = image_to_bgr(planes_to_image(y.download(), 3, shape[2], shape[3], 3, 255.f));
        for (std::size_t i = 0; i < ph.faces.size(); ++i) {
          ++st.expected;
          const jr2::Face* best = nullptr;
          double best_iou = kMatchIou;
          for (const auto& f : faces) {
            const double v = nets::box_iou(f.box, ph.faces[i].box);
            if (v >= best_iou) {
              best_iou = v;
              best = &f;
            }
          }
          if (best == nullptr) continue;
          ++st.detected;
          const double d = jr2::descriptor_distance(best->descriptor, ph.faces[i].descriptor);
          st.distance_sum += d;
          st.cosine_sum += jr2::cosine_similarity(best->descriptor, ph.faces[i].descriptor);
          const auto ranked = jr2::rank_identities(gallery, best->descriptor);
          const bool ok = !ranked.empty() && ranked.front().identity == ph.ids[i];
          st.rank1 += ok ? 1 : 0;
          if (t == 0) {
            char text[96];
            std::snprintf(text, sizeof text, "%s d=%.2f", ranked.front().identity.c_str(), d);
            label(panel, best->box, text, ok ? cv::Scalar(0, 200, 0) : cv::Scalar(0, 0, 230));
          }
        }
        if (t == 0) {
          char text[128];
          std::snprintf(text, sizeof text, "%s  D/r0 = %.1f  tilt %.1f px", kStrengths[s],
                        st.d_over_r0, st.tilt_std_px);
          banner(panel, text);
          panels[p].push_back(panel);
        }
        bar.update(++done);
      }
    }
    stats.push_back(st);
  }
  // The montage: one row per photo, clean | weak | moderate | strong.
  std::vector<cv::Mat> rows;
  for (auto& row : panels) {
    cv::Mat r;
    cv::hconcat(row, r);
    rows.push_back(r);
  }
  int width = 0;
  for (const auto& r : rows) width = std::max(width, r.cols);
  for (auto& r : rows) {
    if (r.cols < width) cv::copyMakeBorder(r, r, 0, 0, 0, width - r.cols, cv::BORDER_CONSTANT);
  }
  cv::Mat montage;
  cv::vconcat(rows, montage);
  write_image_mat(out / "montage.png", montage, a.force);

  // A degraded video: Debian's vtest.avi through strong turbulence.
  const fs::path video_out = out / "vtest_strong.avi";
  {
    std::unique_ptr<sim::Simulator> vsim;
    std::unique_ptr<VideoWriter> writer;
    Tensor x, y;
    read_video(a.video, 1, std::size_t(a.video_frames), [&](std::size_t, const Image& img) {
      const auto h = img.shape[0], w = img.shape[1];
      if (!vsim) {
        PathArgs pa;
        pa.preset = "strong";
        sim::SimOptions so;
        so.field.tilt_rho = 0.9;
        so.field.high_order_rho = 0.6;
        vsim = std::make_unique<sim::Simulator>(device, params_for_image(pa, int(h), int(w)), blur,
                                                so);
        vsim->reset(a.seed);
        writer =
            std::make_unique<VideoWriter>(video_out, video_fps(a.video), int(w), int(h), a.force);
        x = Tensor::empty(device, {1, 3, h, w});
        y = Tensor::empty(device, {1, 3, h, w});
      }
      x.upload(image_to_planes(img, 3, 255.f));
      vsim->frame(stream, x, y);
      stream.run();
      writer->write(planes_to_image(y.download(), 3, h, w, 3, 255.f));
      bar.update(++done);
    });
    writer->finish();
  }
  bar.done();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  json results = {{"photos", photos.size()},
                  {"photo_width_px", a.width},
                  {"faces", total_faces},
                  {"frames_per_strength", a.frames},
                  {"seed", a.seed},
                  {"seconds", seconds},
                  {"device", device.info().name},
                  {"strengths", json::array()}};
  for (const auto& st : stats) results["strengths"].push_back(st.to_json());
  write_text(out / "results.json", results.dump(2) + "\n", a.force);

  std::string table =
      "| strength | D/r0 | tilt σ (px) | detection rate | mean distance to clean | mean cosine to "
      "clean | Rank-1 (detected) | Rank-1 (all) |\n"
      "|---|---|---|---|---|---|---|---|\n";
  for (const auto& st : stats) {
    const json j = st.to_json();
    char line[256];
    std::snprintf(
        line, sizeof line,
        "| %s | %.2f | %.2f | %.1f %% (%zu/%zu) | %.3f | %.3f | %.1f %% | %.1f %% |\n",
        st.name.c_str(), st.d_over_r0, st.tilt_std_px, 100 * j["detection_rate"].get<double>(),
        st.detected, st.expected, j["mean_descriptor_distance"].get<double>(),
        j["mean_cosine_similarity"].get<double>(), 100 * j["rank1_of_detected"].get<double>(),
        100 * j["rank1_of_all"].get<double>());
    table += line;
  }
  char head[512];
  std::snprintf(head, sizeof head,
                "# Turbulence vs recognition\n\n"
                "%zu faces in face-api's %zu sample photos (resized to %d px wide: a face spans "
                "~80 px, 2.2 mm per "
                "pixel at 1 km), each photo simulated as a %d-frame video per preset (seeded), "
                "every face detected, "
                "aligned and embedded (face-api's models on vkjr2's Vulkan kernels) and matched "
                "against the clean "
                "gallery of all %zu faces. Device: %s; %.0f s.\n\n",
                total_faces, photos.size(), a.width, a.frames, total_faces,
                device.info().name.c_str(), seconds);
  const std::string report =
      std::string(head) + table +
      "\nFiles: montage.png (clean | weak | moderate | strong; green: Rank-1 correct, red: "
      "wrong), vtest_strong.avi (Debian's vtest.avi through the strong preset), results.json.\n";
  write_text(out / "report.md", report, a.force);
  if (a.json_out) {
    std::printf("%s\n", results.dump(2).c_str());
  } else {
    std::printf("%s\nwrote %s/{montage.png, vtest_strong.avi, results.json, report.md} in %.0f s\n",
                table.c_str(), out.string().c_str(), seconds);
  }
}

}  // namespace

void add_demo_turbulence(CLI::App& app) {
  auto a = std::make_shared<DemoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "demo-turbulence", "The turbulence-vs-recognition study on the sample photos and video");
  cmd->footer(
      "Simulates turbulence at three strengths (weak, moderate, strong presets; fixed seeds) on "
      "face-api's sample\n"
      "photos and on Debian's vtest.avi, detects, aligns and embeds every face clean and degraded, "
      "and reports per\n"
      "strength the detection rate, the descriptor distance and cosine to the clean face, and "
      "Rank-1 against the\n"
      "clean gallery. Writes montage.png, vtest_strong.avi, results.json and report.md.\n"
      "Example:\n  vkjr2 demo-turbulence --out out/demo_turbulence --force");
  cmd->add_option("--out", a->out, "Output folder")->default_val("out/demo_turbulence");
  cmd->add_option("--frames", a->frames, "Frames of each short video")
      ->default_val(2)
      ->check(integer_range(1, 1000));
  cmd->add_option("--photos", a->photos, "How many of the 6 sample photos to use")
      ->default_val(6)
      ->check(integer_range(1, 6));
  cmd->add_option("--video-frames", a->video_frames, "Frames of vtest.avi to degrade")
      ->default_val(16)
      ->check(integer_range(1, 100000));
  cmd->add_option("--width", a->width, "Width the photos are resized to (px)")
      ->default_val(640)
      ->check(integer_range(64, 4096));
  cmd->add_option("--video", a->video, "The video to degrade")->default_val(kVideo);
  add_seed_option(cmd, a->seed, "Seed of the simulations");
  cmd->add_option("--device", a->device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", a->json_out, "Print results.json instead of the table");
  cmd->add_flag("--quiet", a->quiet, "No progress bar");
  cmd->add_flag("--force", a->force, "Replace existing output files");
  cmd->callback([a] { run_demo(*a); });
}

}  // namespace vkjr2::cli
