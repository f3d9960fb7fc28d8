// vkjr2 simulate: degrade an image or a video with the fast turbulence simulator.
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"
#include "progress.hpp"
#include "sim_common.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct SimArgs {
  PathArgs path;
  std::string input, output, device, dump_fields;
  std::vector<std::string> blur_models;
  std::uint64_t seed = 1;
  int frames = 1, max_frames = 0;
  bool no_blur = false, no_tilt = false, json_out = false, quiet = false, force = false,
       fail_fast = false;
  double photons = 0, read_noise = 0, tilt_rho = 0.9, high_order_rho = 0.6;
};

// A signed map as grey: 128 + 127·v/scale.
Image signed_map(const float* v, std::int64_t h, std::int64_t w, double scale) {
  Image img;
  img.shape = {h, w, 3};
  img.values.resize(std::size_t(h * w * 3));
  for (std::size_t i = 0; i < std::size_t(h * w); ++i) {
    const auto g = static_cast<float>(128 + 127 * std::clamp(double(v[i]) / scale, -1.0, 1.0));
    img.values[i * 3] = img.values[i * 3 + 1] = img.values[i * 3 + 2] = g;
  }
  return img;
}

double max_abs(const float* v, std::size_t n) {
  double m = 0;
  for (std::size_t i = 0; i < n; ++i) m = std::max(m, std::fabs(double(v[i])));
  return m > 0 ? m : 1.0;
}

void dump_fields(const sim::Simulator& sim, const fs::path& dir, bool force) {
  const auto& im = sim.params().image;
  const std::int64_t h = im.height, w = im.width, hw = h * w;
  const auto flow = sim.flow().download();
  json info;
  const double tilt_max =
      std::max(max_abs(flow.data(), flow.size() / 2), max_abs(flow.data() + hw, flow.size() / 2));
  // The flow is the sampling offset (−tilt); the maps show the image shift.
  std::vector<float> shift(flow.size());
  for (std::size_t i = 0; i < flow.size(); ++i) shift[i] = -flow[i];
  write_image(dir / "tilt_x.png", signed_map(shift.data(), h, w, tilt_max), force);
  write_image(dir / "tilt_y.png", signed_map(shift.data() + hw, h, w, tilt_max), force);
  info["tilt_png"] = {
      {"files", {"tilt_x.png", "tilt_y.png"}}, {"grey_128_is_px", 0}, {"full_scale_px", tilt_max}};
  if (sim.beta().defined()) {
    const auto beta = sim.beta().download();
    const std::int64_t k = sim.beta().shape()[1];
    json maps = json::array();
    for (std::int64_t i = 0; i < std::min<std::int64_t>(k, 8); ++i) {
      const float* b = beta.data() + i * hw;
      const double scale = max_abs(b, std::size_t(hw));
      char name[32];
      std::snprintf(name, sizeof name, "beta_%02d.png", int(i));
      write_image(dir / name, signed_map(b, h, w, scale), force);
      maps.push_back({{"file", name}, {"k", i}, {"full_scale", scale}});
    }
    info["beta_png"] = maps;
  }
  info["grid"] = {sim.field().grid_h(), sim.field().grid_w()};
  info["grid_step_px"] = {sim.field().step_y_px(), sim.field().step_x_px()};
  const std::string text = info.dump(2) + "\n";
  vkjr2::write_file_atomic(dir / "fields.json", std::as_bytes(std::span(text)), "--dump-fields");
}

// The largest frame simulate takes on a device: each pixel's PSF-basis
// weights (K floats, K = 24 for the shipped models) and the frame's planes
// are single storage buffers, which a device binds only up to
// max_storage_buffer_range (lavapipe: 128 MiB, i.e. 1.40 MP with K = 24).
struct FrameLimit {
  std::int64_t max_pixels = 0;
  std::string why;
};

FrameLimit frame_limit(const Device& device,
                       const std::vector<std::shared_ptr<const sim::BlurModel>>& blur) {
  std::int64_t floats_per_pixel = 3;  // the RGB planes
  for (const auto& m : blur) floats_per_pixel = std::max(floats_per_pixel, m->basis().shape()[0]);
  const std::uint64_t range = device.info().max_storage_buffer_range;
  FrameLimit f;
  f.max_pixels = std::min<std::int64_t>(std::int64_t(range / (4 * std::uint64_t(floats_per_pixel))),
                                        kMaxImagePixels);
  const auto side = static_cast<std::int64_t>(std::sqrt(double(f.max_pixels)));
  char text[256];
  std::snprintf(text, sizeof text,
                "this device binds buffers of at most %s and the simulator keeps %lld floats a "
                "pixel in one: at most %.2f MP, e.g. %lldx%lld",
                format_bytes(range).c_str(), static_cast<long long>(floats_per_pixel),
                double(f.max_pixels) / 1e6, static_cast<long long>(side),
                static_cast<long long>(side));
  f.why = text;
  return f;
}

void check_frame_size(const std::string& source, std::int64_t h, std::int64_t w,
                      const FrameLimit& limit) {
  if (h * w > limit.max_pixels) {
    throw Error("simulate",
                source + " is " + std::to_string(w) + "x" + std::to_string(h) +
                    " pixels: too large to simulate (" + limit.why + ")",
                "scale or crop it, or cut it into tiles within the limit (or pass --no-blur, "
                "or use a device with larger buffers)");
  }
}

// One input file → one output file, on a Simulator made for its frame size.
// The paths and options were checked by check_job; `limit` is the device's
// frame limit. Returns the JSON summary; `text` gets the human-readable one.
json simulate_one(const Device& device,
                  const std::vector<std::shared_ptr<const sim::BlurModel>>& blur,
                  const FrameLimit& limit, const SimArgs& a, const fs::path& in,
                  const fs::path& out, std::uint64_t seed, std::string& text) {
  const std::string in_name = in.string(), out_name = out.string();
  const bool video_in = is_video_path(in);
  const bool video_out = is_video_output_path(out);
  sim::SimOptions so;
  so.blur = !a.no_blur;
  so.tilt = !a.no_tilt;
  so.field.tilt_rho = a.tilt_rho;
  so.field.high_order_rho = a.high_order_rho;
  so.noise.photons_per_unit = a.photons;
  so.noise.read_std = a.read_noise;

  std::unique_ptr<sim::Simulator> sim;
  std::unique_ptr<VideoWriter> writer;
  std::unique_ptr<Stream> stream;
  Tensor x, y;
  std::size_t done = 0;
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t total = video_in ? std::size_t(a.max_frames) : std::size_t(a.frames);
  Progress progress("simulate " + in.filename().string(), total, a.quiet);
  auto step = [&](const Image& img) {
    const auto h = img.shape[0], w = img.shape[1];
    if (!sim) {
      check_frame_size(in_name, h, w, limit);
      const sim::Params p = params_for_image(a.path, int(h), int(w));
      sim = std::make_unique<sim::Simulator>(device, p, blur, so);
      for (const auto& warn : sim->derived().warnings) log_warn(warn);
      sim->reset(seed);
      stream = std::make_unique<Stream>(device);
      const Shape shape{1, p.image.channels, h, w};
      x = Tensor::empty(device, shape);
      y = Tensor::empty(device, shape);
      if (video_out) {
        writer = std::make_unique<VideoWriter>(out, video_in ? video_fps(in) : 25.0, int(w), int(h),
                                               a.force);
      }
    } else if (h != sim->params().image.height || w != sim->params().image.width) {
      throw Error("simulate", in_name + " changes frame size mid-stream",
                  "re-encode it at one size");
    }
    const int channels = sim->params().image.channels;
    x.upload(image_to_planes(img, channels, 255.f));
    sim->frame(*stream, x, y);
    stream->run();
    const Image frame = planes_to_image(y.download(), channels, h, w, 3, 255.f);
    if (done == 0 && !a.dump_fields.empty()) dump_fields(*sim, a.dump_fields, a.force);
    if (writer) {
      writer->write(frame);
    } else {
      write_image(out, frame, a.force);
    }
    progress.update(++done);
  };
  if (video_in) {
    read_video(in, 1, std::size_t(a.max_frames), [&](std::size_t, const Image& img) { step(img); });
  } else {
    const Image img = read_image(in);
    for (std::size_t t = 0; t < total; ++t) step(img);
  }
  if (writer) writer->finish();
  progress.done();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const sim::ChannelDerived& c0 = sim->derived().channels[0];
  const auto& im = sim->params().image;
  json per_channel = json::array();
  for (const sim::ChannelDerived& c : sim->derived().channels) {
    per_channel.push_back({{"wavelength_nm", c.wavelength_m * 1e9},
                           {"r0_m", c.r0_m},
                           {"d_over_r0", c.d_over_r0},
                           {"nyquist", c.nyquist}});
  }
  json summary = {{"input", in_name},
                  {"output", out_name},
                  {"frames", done},
                  {"height", im.height},
                  {"width", im.width},
                  {"channels", im.channels},
                  {"seconds", seconds},
                  {"fps", double(done) / seconds},
                  {"seed", seed},
                  {"blur", so.blur},
                  {"tilt", so.tilt},
                  {"r0_m", c0.r0_m},
                  {"d_over_r0", c0.d_over_r0},
                  {"isoplanatic_angle_px", c0.isoplanatic_angle_px},
                  {"tilt_std_px", c0.tilt_std_px},
                  {"rytov", c0.rytov},
                  {"per_channel", per_channel},
                  {"grid", {sim->field().grid_h(), sim->field().grid_w()}},
                  {"warnings", sim->derived().warnings}};
  char line[512];
  std::snprintf(line, sizeof line,
                "simulate: %s -> %s: %zu frame(s) %lldx%lldx%d in %.2f s (%.2f frames/s)\n",
                in_name.c_str(), out_name.c_str(), done, static_cast<long long>(im.width),
                static_cast<long long>(im.height), im.channels, seconds, double(done) / seconds);
  text = line;
  text += "  " + sim::summary(sim->params(), sim->derived()) + "\n";
  std::snprintf(line, sizeof line, "  field grid %dx%d (step %.2f px), tilt %s, blur %s\n",
                sim->field().grid_w(), sim->field().grid_h(), sim->field().step_x_px(),
                so.tilt ? "on" : "off", so.blur ? "on" : "off");
  text += line;
  return summary;
}

// What one input → output job needs, checked before any work.
void check_job(const SimArgs& a, const fs::path& in, const fs::path& out) {
  const bool video_in = is_video_path(in);
  if (!video_in && !is_image_path(in)) {
    throw UsageError("IN", in.string() + " is neither an image nor a video (by its extension)",
                     "pass .png/.jpg/.tif/.bmp/.webp/.npy or .avi/.mp4/.mkv/...");
  }
  check_output_file(out, a.force, "OUT");
  const bool video_out = is_video_output_path(out);
  if (!video_out && !is_image_output_path(out)) {
    throw UsageError("OUT", out.string() +
                                ": name an image (.png, .jpg, .tif, .bmp) or a video (.avi "
                                "Motion-JPEG, .mp4/.mov/.mkv MPEG-4)");
  }
  if (video_in && !video_out) {
    throw UsageError("OUT", "a video input needs a video output, got " + out.string(),
                     "name OUT .avi or .mp4");
  }
  if (!video_in && !video_out && a.frames > 1) {
    throw UsageError("--frames", std::to_string(a.frames) + " frames need a video output",
                     "name OUT .avi or .mp4");
  }
}

// The image and video files directly in `dir`, sorted by name.
std::vector<fs::path> list_media(const fs::path& dir) {
  return list_files(dir, [](const fs::path& p) { return is_image_path(p) || is_video_path(p); });
}

void run_simulate(const SimArgs& a) {
  const fs::path in(a.input), out(a.output);
  std::error_code ec;
  const bool folder = fs::is_directory(in, ec);
  std::vector<std::pair<fs::path, fs::path>> jobs;  // (input, output)
  if (folder) {
    check_input_folder(in, "IN");
    check_output_folder(out, "OUT");
    if (!a.dump_fields.empty())
      throw UsageError("--dump-fields", "takes a single input file, IN is a folder",
                       "dump the fields of one file at a time");
    const auto files = list_media(in);
    if (files.empty())
      throw UsageError("IN", a.input + " holds no image or video",
                       "put .png/.jpg/.tif/.npy or .avi/.mp4/... files in it");
    for (const fs::path& f : files) {
      const bool video = is_video_path(f) || a.frames > 1;
      jobs.emplace_back(f, out / (f.stem().string() + (video ? ".avi" : ".png")));
    }
    // Refuse before any work when two inputs would write one output.
    for (std::size_t i = 1; i < jobs.size(); ++i)
      for (std::size_t k = 0; k < i; ++k)
        if (jobs[i].second == jobs[k].second)
          throw UsageError("IN",
                           jobs[k].first.string() + " and " + jobs[i].first.string() +
                               " would both write " + jobs[i].second.string(),
                           "rename one of them");
    for (const auto& job : jobs) {
      if (fs::exists(job.second, ec) || fs::is_directory(job.second, ec))
        check_output_file(job.second, a.force, "OUT");
    }
  } else {
    check_input_file(in, "IN");
    check_job(a, in, out);
    jobs.emplace_back(in, out);
  }
  if (!a.dump_fields.empty()) {
    check_output_folder(a.dump_fields, "--dump-fields");
    for (const char* f : {"tilt_x.png", "tilt_y.png", "fields.json"})
      if (fs::exists(fs::path(a.dump_fields) / f, ec))
        check_output_file(fs::path(a.dump_fields) / f, a.force, "--dump-fields");
  }
  // The parameters are checked on a placeholder frame: only the optics and
  // the path decide whether they can be simulated.
  const sim::Params checked = params_for_image(a.path, 64, 64);
  for (const auto& path : a.blur_models) check_input_file(path, "--blur-model");

  const Device device = open_device(a.device);
  std::vector<std::shared_ptr<const sim::BlurModel>> blur;
  if (!a.no_blur) {
    blur = load_blur_models(device, a.blur_models);
    check_blur_models(a.path, checked, blur);
  }
  // Images whose header gives their size: too large for this device is said
  // before any of them is decoded.
  const FrameLimit limit = frame_limit(device, blur);
  for (const auto& job : jobs) {
    if (is_video_path(job.first)) continue;
    try {
      const ImageHeader h = peek_image_size(job.first);
      if (h.width > 0) check_frame_size(job.first.string(), h.height, h.width, limit);
    } catch (const Error&) {
      if (!folder) throw;  // a folder run reports it with the file's turn
    }
  }
  if (folder) create_output_folder(out, "OUT");
  watch_output_folder(folder ? out : out.parent_path());
  if (!a.dump_fields.empty()) create_output_folder(a.dump_fields, "--dump-fields");

  json all = json::array(), failed = json::array();
  std::size_t failures = 0;
  for (std::size_t i = 0; i < jobs.size(); ++i) {
    // Each file of a folder gets its own turbulence: seed + its position.
    std::string text;
    json summary;
    try {
      if (folder) check_job(a, jobs[i].first, jobs[i].second);
      summary =
          simulate_one(device, blur, limit, a, jobs[i].first, jobs[i].second, a.seed + i, text);
    } catch (const Error& e) {
      if (!folder || a.fail_fast) throw;
      ++failures;
      log_warn("skipped " + jobs[i].first.string() + ": " + describe_error(e));
      failed.push_back({{"input", jobs[i].first.string()}, {"error", describe_error(e)}});
      continue;
    }
    if (a.json_out) {
      all.push_back(std::move(summary));
    } else {
      std::fputs(text.c_str(), stdout);
    }
  }
  if (a.json_out) {
    const json j =
        folder ? json{{"input", a.input}, {"output", a.output}, {"files", all}, {"failed", failed}}
               : all.front();
    std::printf("%s\n", j.dump(2).c_str());
  } else if (folder) {
    std::printf("simulate: %zu of %zu files written to %s, %zu failed\n", jobs.size() - failures,
                jobs.size(), a.output.c_str(), failures);
  }
  if (failures > 0) {
    throw Error("simulate",
                std::to_string(failures) + " of " + std::to_string(jobs.size()) +
                    " inputs failed (each is named above); the others were written",
                "fix or remove the failed inputs and run again (--fail-fast stops at the first)");
  }
}

}  // namespace

void add_simulate(CLI::App& app) {
  auto a = std::make_shared<SimArgs>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Degrade an image or a video with the fast turbulence simulator");
  cmd->footer(
      "Examples:\n"
      "  vkjr2 simulate face.png face_turb.png --preset strong --seed 7\n"
      "  vkjr2 simulate face.png clip.avi --frames 60          # a turbulent video from one image\n"
      "  vkjr2 simulate vtest.avi vtest_turb.avi --max-frames 100 --dump-fields fields/\n"
      "  vkjr2 simulate in.png out.png --config path.json --photons 2000 --read-noise 0.005\n"
      "  vkjr2 simulate faces/ faces_turb/ --preset moderate   # every image/video in a folder\n"
      "A folder IN writes OUT/<name>.png per image (.avi per video, or with --frames > 1); file i "
      "(sorted by name) uses seed + i;\na file that fails is reported and skipped (exit code 1 at "
      "the end; --fail-fast stops at it).\n"
      "OUT's format follows its extension: .png, .jpg, .tif, .bmp images; .avi, .mp4, .mov, .mkv "
      "videos.\nThe largest frame is what the device binds in one buffer over 4 K bytes a pixel "
      "(K = 24 PSF-basis weights):\n1.40 MP, e.g. 1182x1182, on lavapipe (128 MiB); the error "
      "names the limit of the device in use.\n"
      "Presets: weak, moderate, strong (1 km path, D = 0.2 m, f = 1.6 m; docs/sim.md).");
  cmd->add_option(
         "IN", a->input,
         "Input image (.png, .jpg, .tif, .npy), video (.avi, .mp4, ...) or a folder of them")
      ->required();
  cmd->add_option(
         "OUT", a->output,
         "Output image (.png, .jpg, .tif, .bmp) or video (.avi Motion-JPEG, .mp4); a folder when "
         "IN is one")
      ->required();
  add_path_options(cmd, a->path);
  add_seed_option(cmd, a->seed, "Seed of the turbulence and the noise");
  cmd->add_option("--frames", a->frames,
                  "Frames to make from an image input (more than 1: a video output)")
      ->default_val(1)
      ->check(integer_range(1, 100000));
  cmd->add_option("--max-frames", a->max_frames, "Frames to read from a video input (0 = all)")
      ->check(integer_range(0, 10000000));
  cmd->add_option("--tilt-rho", a->tilt_rho, "Frame-to-frame correlation of the tilt field")
      ->default_val(0.9)
      ->check(finite_range(0.0, 0.999));
  cmd->add_option("--high-order-rho", a->high_order_rho, "Frame-to-frame correlation of the blur")
      ->default_val(0.6)
      ->check(finite_range(0.0, 0.999));
  cmd->add_option("--photons", a->photons, "Shot noise: photons at full white (0 = none)")
      ->check(finite_range(0.0, 1e12));
  cmd->add_option("--read-noise", a->read_noise, "Read noise σ as a fraction of full white")
      ->check(finite_range(0.0, 1.0));
  cmd->add_flag("--no-blur", a->no_blur, "Tilt (and noise) only");
  cmd->add_flag("--no-tilt", a->no_tilt, "Blur (and noise) only");
  cmd->add_option("--blur-model", a->blur_models,
                  "PSF basis + P2S network (.safetensors from vkjr2 sim-train); repeat it for "
                  "channels of other wavelengths (each channel takes the one made for its "
                  "sampling); default: the shipped ones (525 nm, and 610/465 nm for --wavelengths "
                  "rgb)");
  cmd->add_option(
      "--dump-fields", a->dump_fields,
      "Folder for the first frame's tilt maps and PSF-basis weights as PNG (+ fields.json)");
  cmd->add_option("--device", a->device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", a->json_out, "Print JSON instead of text");
  cmd->add_flag("--quiet", a->quiet, "No progress bar");
  cmd->add_flag("--force", a->force, "Replace existing output files");
  cmd->add_flag("--fail-fast", a->fail_fast,
                "Folder input: stop at the first file that fails (default: report it, go on "
                "with the rest, exit 1 at the end)");
  cmd->callback([a] { run_simulate(*a); });
}

}  // namespace vkjr2::cli
