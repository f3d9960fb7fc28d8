// vkjr2 restore: the restorer (jr2/restorer.hpp) over a turbulent clip, a
// video, or a folder of them.
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/kernels/layout.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"
#include "progress.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

struct RestoreArgs {
  std::string input, output, model, device;
  int max_frames = 0;
  std::optional<int> frame;
  bool faces = false;
  double face_margin = 0.5;
  int detector_size = 416;
  float face_threshold = 0.5f;
  bool json_out = false, quiet = false, force = false, fail_fast = false;
};

// --faces: the faces of frame i are the detections in the T frames of its
// window (the frame's own first, then the nearest frames': a face the
// detector misses in one frame is kept from its neighbours).
class FaceTracks {
 public:
  FaceTracks(const Device& device, const RestoreArgs& a) : analyzer_(device) {
    options_.input_size = a.detector_size;
    options_.score_threshold = a.face_threshold;
    options_.descriptors = false;
  }
  std::vector<nets::FaceBox> boxes(Stream& stream, const std::vector<std::vector<float>>& planes,
                                   std::int64_t h, std::int64_t w,
                                   const std::vector<std::size_t>& window, std::size_t i) {
    std::vector<std::size_t> order(window.begin(), window.end());
    std::stable_sort(order.begin(), order.end(), [&](std::size_t p, std::size_t q) {
      const auto dp = p > i ? p - i : i - p, dq = q > i ? q - i : i - q;
      return dp < dq;
    });
    std::vector<nets::FaceBox> out;
    for (std::size_t f : order) {
      auto it = cache_.find(f);
      if (it == cache_.end()) {
        std::vector<float> pixels(planes[f]);
        for (float& v : pixels) v *= 255.f;
        const Tensor image = Tensor::from(stream.device(), Shape{1, 3, h, w}, pixels);
        std::vector<nets::FaceBox> found;
        for (const auto& d : analyzer_.detect(stream, image, options_)) found.push_back(d.box);
        it = cache_.emplace(f, std::move(found)).first;
      }
      out.insert(out.end(), it->second.begin(), it->second.end());
    }
    return out;
  }

 private:
  jr2::FaceAnalyzer analyzer_;
  jr2::FaceOptions options_;
  std::map<std::size_t, std::vector<nets::FaceBox>> cache_;
};

json restore_one(const Device& device, const jr2::Restorer& net, const RestoreArgs& a,
                 const fs::path& in, const fs::path& out) {
  const auto t0 = std::chrono::steady_clock::now();
  const int t_frames = net.config().frames;
  std::vector<std::vector<float>> planes;  // each frame as [3, H, W] in 0..1
  std::int64_t h = 0, w = 0;
  auto add = [&](const Image& img) {
    if (planes.empty()) {
      h = img.shape[0];
      w = img.shape[1];
    } else if (img.shape[0] != h || img.shape[1] != w) {
      throw Error("restore", in.string() + " changes frame size mid-stream",
                  "re-encode it at one size");
    }
    planes.push_back(image_to_planes(img, 3, 255.f));
  };
  const bool video_in = is_video_path(in);
  if (video_in) {
    read_video(in, 1, std::size_t(a.max_frames), [&](std::size_t, const Image& img) { add(img); });
  } else {
    add(read_image(in));
  }
  const std::size_t count = planes.size();
  const bool video_out = is_video_output_path(out);
  std::vector<std::size_t> targets;
  if (video_out) {
    for (std::size_t i = 0; i < count; ++i) targets.push_back(i);
  } else {
    const std::size_t i = a.frame ? std::size_t(*a.frame) : count / 2;
    if (i >= count) {
      throw UsageError(
          "--frame",
          std::to_string(i) + " is past the " + std::to_string(count) + " frames of " + in.string(),
          "pass 0.." + std::to_string(count - 1));
    }
    targets.push_back(i);
  }
  std::unique_ptr<VideoWriter> writer;
  if (video_out) {
    writer = std::make_unique<VideoWriter>(out, video_in ? video_fps(in) : 25.0, int(w), int(h),
                                           a.force);
  }
  Stream stream(device);
  const std::size_t plane = std::size_t(3 * h * w);
  std::vector<float> stacked(plane * std::size_t(t_frames));
  const Tensor x = Tensor::empty(device, Shape{1, 3LL * t_frames, h, w});
  Progress progress("restore " + in.filename().string(), targets.size(), a.quiet);
  std::size_t done = 0, regions = 0, frames_with_faces = 0;
  std::unique_ptr<FaceTracks> tracks;
  if (a.faces) tracks = std::make_unique<FaceTracks>(device, a);
  const int multiple = 1 << net.config().levels();
  for (const std::size_t i : targets) {
    const auto window = jr2::restore_window(count, i, t_frames);
    for (std::size_t j = 0; j < window.size(); ++j) {
      std::copy(planes[window[j]].begin(), planes[window[j]].end(),
                stacked.begin() + std::ptrdiff_t(j * plane));
    }
    x.upload(stacked);
    std::vector<float> restored;
    if (tracks) {
      // Only the face regions, restored from the same crop of every frame of
      // the window and blended into the frame.
      restored = planes[i];
      const auto boxes = tracks->boxes(stream, planes, h, w, window, i);
      const auto found = jr2::face_regions(boxes, int(h), int(w), a.face_margin, multiple);
      for (const jr2::Region& r : found) {
        const Tensor crop = Tensor::empty(device, Shape{1, 3LL * t_frames, r.height, r.width});
        kernels::slice(stream, x, {.row = r.y, .col = r.x}, crop);
        nets::Tape tape(stream, false);
        const nets::Var y = net.forward(tape, nets::Var(crop));
        stream.run();
        jr2::paste_region(restored, int(h), int(w), y.value().download(), r,
                          std::max(2, std::min(r.width, r.height) / 8));
      }
      regions += found.size();
      frames_with_faces += found.empty() ? 0 : 1;
    } else {
      nets::Tape tape(stream, false);
      const nets::Var y = net.forward(tape, nets::Var(x));
      stream.run();
      restored = y.value().download();
    }
    const Image frame = planes_to_image(restored, 3, h, w, 3, 255.f);
    if (writer) {
      writer->write(frame);
    } else {
      write_image(out, frame, a.force);
    }
    progress.update(++done);
  }
  if (writer) writer->finish();
  progress.done();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  json r = {{"input", in.string()}, {"output", out.string()},
            {"frames_read", count}, {"restored", done},
            {"height", h},          {"width", w},
            {"seconds", seconds},   {"fps", double(done) / seconds}};
  if (a.faces) {
    r["face_regions"] = regions;
    r["frames_with_faces"] = frames_with_faces;
  }
  return r;
}

void check_job(const RestoreArgs& a, const fs::path& in, const fs::path& out) {
  if (!is_video_path(in) && !is_image_path(in)) {
    throw UsageError("IN", in.string() + " is neither a video nor an image (by its extension)",
                     "pass a clip (.avi/.mp4/...) or a frame (.png/.jpg/...)");
  }
  check_output_file(out, a.force, "OUT");
  if (!is_video_output_path(out) && !is_image_output_path(out)) {
    throw UsageError("OUT", out.string() +
                                ": name an image (.png, .jpg, .tif, .bmp: the restored frame) or a "
                                "video (.avi, .mp4, .mov, .mkv: every frame)");
  }
}

void run_restore(const RestoreArgs& a) {
  const fs::path in = a.input, out = a.output;
  std::error_code ec;
  const bool folder = fs::is_directory(in, ec);
  if (!folder) check_input_file(in, "IN");
  if (a.faces && a.detector_size % 32 != 0) {
    throw UsageError("--detector-size",
                     std::to_string(a.detector_size) + " is not a multiple of 32",
                     "use 160, 320, 416, 512 or 608");
  }
  const fs::path model = a.model.empty() ? jr2::default_restorer_path() : fs::path(a.model);
  check_input_file(model, a.model.empty() ? "the shipped restorer" : "--model");
  std::vector<std::pair<fs::path, fs::path>> jobs;
  if (folder) {
    check_output_folder(out, "OUT");
    for (const fs::path& p : list_files(in, [](const fs::path& f) { return is_video_path(f); })) {
      jobs.emplace_back(p, out / (p.stem().string() + ".png"));
    }
    if (jobs.empty()) {
      throw UsageError("IN", in.string() + " holds no video", "pass a folder of clips");
    }
  } else {
    jobs.emplace_back(in, out);
  }
  for (const auto& [i, o] : jobs) check_job(a, i, o);
  if (folder) create_output_folder(out, "OUT");
  watch_output_folder(folder ? out : out.parent_path());
  Device device = open_device(a.device);
  const auto net = jr2::Restorer::load(device, model);
  json results = json::array();
  int failed = 0;
  for (const auto& [i, o] : jobs) {
    try {
      const json r = restore_one(device, *net, a, i, o);
      results.push_back(r);
      if (!a.json_out) {
        std::printf("restore: %s -> %s: %zu frame(s) %lldx%lld in %.2f s\n", i.string().c_str(),
                    o.string().c_str(), r["restored"].get<std::size_t>(),
                    r["width"].get<long long>(), r["height"].get<long long>(),
                    r["seconds"].get<double>());
      }
    } catch (const Error& e) {
      if (!folder || a.fail_fast) throw;
      log_warn(describe_error(e) + " (skipped)");
      ++failed;
    }
  }
  if (a.json_out)
    std::printf("%s\n", json{{"model", model.string()}, {"results", results}}.dump(2).c_str());
  if (failed > 0) {
    throw Error("restore",
                std::to_string(failed) + " of " + std::to_string(jobs.size()) +
                    " clips failed (reported above)",
                "fix or remove them");
  }
}

}  // namespace

void add_restore(CLI::App& app) {
  auto a = std::make_shared<RestoreArgs>();
  CLI::App* cmd =
      app.add_subcommand("restore", "Restore a turbulent clip with the restorer (multi-frame)");
  cmd->footer(
      "Each restored frame comes from the T frames around it (T: the model's, the reference "
      "frame in the\n"
      "middle; the clip's first and last frames repeat near its ends). An image OUT is one "
      "restored frame\n"
      "(--frame, default the middle one); a video OUT restores every frame. A folder IN writes "
      "OUT/<clip>.png\n"
      "per video. --faces restores only the regions around the faces found in the frame's "
      "window (a face the\n"
      "detector misses in one frame is kept from its neighbours) and blends them back with a "
      "feathered edge.\n"
      "Outputs are written atomically.\n"
      "Examples:\n"
      "  vkjr2 restore probe.avi restored.png            # the middle frame\n"
      "  vkjr2 restore probe.avi restored.avi            # every frame\n"
      "  vkjr2 restore street.mp4 faces.mp4 --faces      # only the faces, pasted back\n"
      "  vkjr2 restore bench/jr2/probes/ restored/ --model mine.safetensors");
  cmd->add_option("IN", a->input, "A clip (.avi, .mp4, ...), one frame, or a folder of clips")
      ->required();
  cmd->add_option("OUT", a->output,
                  "Image (one restored frame) or video (every frame); a folder "
                  "when IN is one")
      ->required();
  cmd->add_option("--model", a->model,
                  "Restorer (.safetensors from vkjr2 restore-train; default the shipped one)");
  cmd->add_option("--frames", a->max_frames, "Frames to read from a video (0 = all)")
      ->default_val(0)
      ->check(integer_range(0, 10000000));
  cmd->add_option("--frame", a->frame, "The frame an image OUT restores (default: the middle)")
      ->check(integer_range(0, 10000000));
  cmd->add_flag("--faces", a->faces,
                "Restore only the faces: the regions around the faces detected in each frame's "
                "window, blended back into the frame (the rest stays as it is)");
  cmd->add_option("--face-margin", a->face_margin,
                  "--faces: context around a face box, as a share of its side on each side")
      ->default_val(a->face_margin)
      ->check(finite_range(0, 4));
  cmd->add_option("--detector-size", a->detector_size,
                  "--faces: the face detector's input size (a multiple of 32)")
      ->default_val(a->detector_size)
      ->check(integer_range(32, 1024));
  cmd->add_option("--face-threshold", a->face_threshold, "--faces: the detector's score threshold")
      ->default_val(a->face_threshold)
      ->check(finite_range(0.01, 0.99));
  cmd->add_option("--device", a->device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", a->json_out, "Print JSON instead of text");
  cmd->add_flag("--quiet", a->quiet, "No progress bar");
  cmd->add_flag("--force", a->force, "Replace existing output files");
  cmd->add_flag("--fail-fast", a->fail_fast, "Folder input: stop at the first clip that fails");
  cmd->callback([a] { run_restore(*a); });
}

}  // namespace vkjr2::cli
