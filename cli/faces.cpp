// `vkjr2 detect | embed | verify | identify`: the face stack from the command line.
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/runtime/error.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct FaceArgs {
  std::string device;
  bool json = false;
  int input_size = 416;
  float score_threshold = 0.5f;
  std::string align = "face-api";
  bool aligned = false;    // inputs are already face crops
  bool fail_fast = false;  // batches: stop at the first input that fails
};

// --input-size: the detector's grid is 32 pixels.
CLI::Validator multiple_of_32() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        std::string in_range = integer_range(32, 4096)(text);
        if (!in_range.empty()) return in_range;
        if (std::stoll(text) % 32 != 0)
          return text + " is not a multiple of 32 (use e.g. 320, 416 or 608)";
        return {};
      },
      "a multiple of 32 in 32..4096");
}

void add_common(CLI::App* cmd, FaceArgs& a, bool with_aligned) {
  cmd->add_option("--device", a.device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", a.json, "Print JSON instead of text");
  cmd->add_option("--input-size", a.input_size, "Detector input size, a multiple of 32")
      ->default_val(416)
      ->check(multiple_of_32());
  cmd->add_option("--min-score", a.score_threshold, "Detector score threshold in (0, 1)")
      ->default_val(0.5f)
      ->check(finite_range(0.0001, 0.9999));
  if (with_aligned) {
    cmd->add_option("--align", a.align,
                    "face-api: face-api's axis-aligned dlib box (matches face-api's descriptors); "
                    "similarity: 5-point similarity alignment")
        ->default_val("face-api")
        ->check(CLI::IsMember({"face-api", "similarity"}));
    cmd->add_flag("--aligned", a.aligned,
                  "Inputs are already face crops (e.g. 150x150): skip detection and describe the "
                  "whole image");
  }
}

jr2::FaceOptions options_of(const FaceArgs& a, bool descriptors) {
  jr2::FaceOptions o;
  o.input_size = a.input_size;
  o.score_threshold = a.score_threshold;
  o.descriptors = descriptors;
  o.align = a.align == "similarity" ? jr2::AlignMode::similarity : jr2::AlignMode::face_api;
  return o;
}

json box_json(const nets::FaceBox& b) {
  return {{"x", b.x}, {"y", b.y}, {"width", b.width}, {"height", b.height}};
}

json face_json(const jr2::Face& f, bool with_descriptor) {
  json lm = json::array();
  for (std::size_t i = 0; i + 1 < f.landmarks.size(); i += 2) {
    lm.push_back({f.landmarks[i], f.landmarks[i + 1]});
  }
  json j = {{"score", f.score},
            {"box", box_json(f.box)},
            {"landmarks", lm},
            {"cut_by_border", f.cut_by_border}};
  if (with_descriptor && !f.descriptor.empty()) {
    j["chip_box"] = box_json(f.chip_box);
    j["descriptor"] = f.descriptor;
  }
  return j;
}

// ---- drawing ------------------------------------------------------------------------

void draw_rect(Image& img, const nets::FaceBox& b, const std::array<float, 3>& rgb, int thick) {
  const int h = int(img.shape[0]), w = int(img.shape[1]);
  const auto put = [&](int x, int y) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    for (int c = 0; c < 3; ++c)
      img.values[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * 3 + std::size_t(c)] =
          rgb[std::size_t(c)];
  };
  const int x0 = int(std::lround(b.x)), y0 = int(std::lround(b.y));
  const int x1 = int(std::lround(b.x + b.width)), y1 = int(std::lround(b.y + b.height));
  for (int t = 0; t < thick; ++t) {
    for (int x = x0; x <= x1; ++x) {
      put(x, y0 + t);
      put(x, y1 - t);
    }
    for (int y = y0; y <= y1; ++y) {
      put(x0 + t, y);
      put(x1 - t, y);
    }
  }
}

void draw_faces(Image& img, const std::vector<jr2::Face>& faces) {
  const int thick = std::max(1, int(std::max(img.shape[0], img.shape[1]) / 400));
  for (const jr2::Face& f : faces) {
    draw_rect(img, f.box, {0.f, 255.f, 0.f}, thick);
    for (std::size_t i = 0; i + 1 < f.landmarks.size(); i += 2) {
      const nets::FaceBox dot{f.landmarks[i] - thick, f.landmarks[i + 1] - thick, 2.0 * thick,
                              2.0 * thick};
      draw_rect(img, dot, {255.f, 40.f, 40.f}, thick);
    }
  }
}

// ---- detect ---------------------------------------------------------------------------

struct DetectArgs : FaceArgs {
  std::string input;
  std::string draw;
  bool force = false;
  std::size_t every = 1;
  std::size_t max_frames = 0;
};

void print_faces_text(const std::string& what, const std::vector<jr2::Face>& faces) {
  std::printf("%s: %zu face%s\n", what.c_str(), faces.size(), faces.size() == 1 ? "" : "s");
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const jr2::Face& f = faces[i];
    std::printf("  #%zu score %.3f box x %.1f y %.1f w %.1f h %.1f%s\n", i + 1, double(f.score),
                f.box.x, f.box.y, f.box.width, f.box.height,
                f.cut_by_border ? " (cut by the image border)" : "");
  }
}

void run_detect(const DetectArgs& a) {
  const fs::path input = a.input;
  check_input_file(input, "input");
  const bool video = is_video_path(input);
  if (!video && !is_image_path(input)) {
    throw UsageError("input", a.input + " is neither an image nor a video (by its extension)",
                     "pass .png/.jpg/.tif/.bmp/.webp/.npy or .avi/.mp4/...");
  }
  if (!a.draw.empty()) {
    if (video) throw UsageError("--draw", "drawing is for single images", "pass an image");
    check_output_file(a.draw, a.force, "--draw");
    check_extension(a.draw, kImageOutputExtensions, "--draw");
    watch_output_folder(fs::path(a.draw).parent_path());
  }
  const Device device = open_device(a.device);
  const jr2::FaceAnalyzer analyzer(device);
  Stream stream(device);
  const jr2::FaceOptions opts = options_of(a, false);
  const auto detect = [&](const Image& img) {
    const Tensor t = nets::image_to_device(device, img);
    return analyzer.analyze(stream, t, opts);
  };
  if (video) {
    json frames = json::array();
    read_video(input, a.every, a.max_frames, [&](std::size_t index, const Image& img) {
      const auto faces = detect(img);
      if (a.json) {
        json fj = json::array();
        for (const auto& f : faces) fj.push_back(face_json(f, false));
        frames.push_back({{"frame", index}, {"faces", fj}});
      } else {
        print_faces_text(input.filename().string() + " frame " + std::to_string(index), faces);
      }
    });
    if (a.json) std::cout << json{{"input", a.input}, {"frames", frames}}.dump(2) << "\n";
    return;
  }
  Image img = read_image(input);
  const auto faces = detect(img);
  if (a.json) {
    json fj = json::array();
    for (const auto& f : faces) fj.push_back(face_json(f, false));
    std::cout << json{{"input", a.input},
                      {"width", img.shape[1]},
                      {"height", img.shape[0]},
                      {"faces", fj}}
                     .dump(2)
              << "\n";
  } else {
    print_faces_text(input.filename().string(), faces);
  }
  if (!a.draw.empty()) {
    draw_faces(img, faces);
    write_image(a.draw, img, a.force);
    if (!a.json) std::printf("wrote %s\n", a.draw.c_str());
  }
}

// ---- shared: descriptors of one image ------------------------------------------------

struct Described {
  std::vector<jr2::Face> faces;  // with descriptors (one pseudo-face for --aligned)
};

Described describe(const jr2::FaceAnalyzer& analyzer, Stream& stream, const Device& device,
                   const fs::path& path, const FaceArgs& a) {
  const Image img = read_image(path);
  const Tensor t = nets::image_to_device(device, img);
  Described out;
  if (a.aligned) {
    jr2::Face f;
    f.score = 1.f;
    f.box = {0, 0, double(img.shape[1]), double(img.shape[0])};
    f.chip_box = f.box;
    f.descriptor = analyzer.describe_chip(stream, t);
    out.faces.push_back(std::move(f));
  } else {
    out.faces = analyzer.analyze(stream, t, options_of(a, true));
  }
  return out;
}

// The face a one-face command uses: the highest detection score.
const jr2::Face& best_face(const Described& d, const std::string& path) {
  if (d.faces.empty()) {
    throw Error("face", "no face found in " + path,
                "use an image with a visible face, lower --min-score, or pass --aligned for "
                "images that are already face crops");
  }
  return d.faces.front();
}

// ---- embed ------------------------------------------------------------------------------

struct EmbedArgs : FaceArgs {
  std::vector<std::string> inputs;
};

// Reports an input of a batch that failed (or rethrows it with --fail-fast).
void skip_failed(const FaceArgs& a, const std::string& input, const Error& e, json& failed) {
  if (a.fail_fast) throw;  // the Error being handled
  log_warn("skipped " + input + ": " + describe_error(e));
  failed.push_back({{"input", input}, {"error", describe_error(e)}});
}

// Exit code 1 after a batch in which some inputs failed.
void fail_if_any(const json& failed, std::size_t total, const std::string& what) {
  if (failed.empty()) return;
  throw Error("batch",
              std::to_string(failed.size()) + " of " + std::to_string(total) + " " + what +
                  " failed (each is named above); the others were used",
              "fix or remove them and run again (--fail-fast stops at the first)");
}

void run_embed(const EmbedArgs& a) {
  // A folder stands for its images, sorted by name.
  std::vector<std::string> inputs;
  std::error_code ec;
  for (const std::string& in : a.inputs) {
    if (!fs::is_directory(in, ec)) {
      check_input_file(in, "inputs");
      inputs.push_back(in);
      continue;
    }
    check_input_folder(in, "inputs");
    const auto images = list_images(in);
    if (images.empty())
      throw UsageError("inputs", in + " holds no image", "put .png/.jpg/.tif/.npy files in it");
    for (const fs::path& p : images) inputs.push_back(p.string());
  }
  const Device device = open_device(a.device);
  const jr2::FaceAnalyzer analyzer(device);
  Stream stream(device);
  json all = json::array(), failed = json::array();
  std::size_t without = 0;
  for (const std::string& in : inputs) {
    Described d;
    try {
      d = describe(analyzer, stream, device, in, a);
    } catch (const Error& e) {
      if (inputs.size() == 1) throw;
      skip_failed(a, in, e, failed);
      continue;
    }
    if (d.faces.empty()) {
      ++without;
      log_warn("no face found in " + in);
    }
    if (a.json) {
      json fj = json::array();
      for (const auto& f : d.faces) fj.push_back(face_json(f, true));
      all.push_back({{"input", in}, {"faces", fj}});
      continue;
    }
    std::printf("%s: %zu face%s\n", in.c_str(), d.faces.size(), d.faces.size() == 1 ? "" : "s");
    for (std::size_t i = 0; i < d.faces.size(); ++i) {
      const auto& desc = d.faces[i].descriptor;
      double norm = 0;
      for (float v : desc) norm += double(v) * v;
      std::printf("  #%zu box x %.1f y %.1f w %.1f h %.1f  |d| %.4f  d =", i + 1, d.faces[i].box.x,
                  d.faces[i].box.y, d.faces[i].box.width, d.faces[i].box.height, std::sqrt(norm));
      for (float v : desc) std::printf(" %.6f", double(v));
      std::printf("\n");
    }
  }
  if (a.json) std::cout << all.dump(2) << "\n";
  if (!failed.empty() && !a.json) {
    std::printf("embed: %zu of %zu inputs described, %zu failed\n", inputs.size() - failed.size(),
                inputs.size(), failed.size());
  }
  fail_if_any(failed, inputs.size(), "inputs");
  if (without == inputs.size()) {
    throw Error("embed", "no face found in any input",
                "lower --min-score or pass --aligned for face crops");
  }
}

// ---- verify ------------------------------------------------------------------------------

struct VerifyArgs : FaceArgs {
  std::string a_path, b_path;
  double threshold = jr2::kFaceApiMatchThreshold;
};

void run_verify(const VerifyArgs& a) {
  check_input_file(a.a_path, "a");
  check_input_file(a.b_path, "b");
  const Device device = open_device(a.device);
  const jr2::FaceAnalyzer analyzer(device);
  Stream stream(device);
  const Described da = describe(analyzer, stream, device, a.a_path, a);
  const Described db = describe(analyzer, stream, device, a.b_path, a);
  const double d = jr2::descriptor_distance(best_face(da, a.a_path).descriptor,
                                            best_face(db, a.b_path).descriptor);
  const bool same = d < a.threshold;
  if (a.json) {
    std::cout << json{{"a", a.a_path},
                      {"b", a.b_path},
                      {"distance", d},
                      {"threshold", a.threshold},
                      {"same_person", same}}
                     .dump(2)
              << "\n";
  } else {
    std::printf("distance %.4f → %s (threshold %.2f)\n", d,
                same ? "same person" : "different people", a.threshold);
  }
}

// ---- identify ----------------------------------------------------------------------------

struct IdentifyArgs : FaceArgs {
  std::string probe;
  std::string gallery;
  std::size_t top = 5;
};

void run_identify(const IdentifyArgs& a) {
  const fs::path root = a.gallery;
  check_input_file(a.probe, "probe");
  check_input_folder(root, "--gallery");
  const Device device = open_device(a.device);
  const jr2::FaceAnalyzer analyzer(device);
  Stream stream(device);
  std::vector<jr2::GalleryEntry> gallery;
  std::vector<fs::path> identities;
  for (const auto& e : fs::directory_iterator(root)) {
    if (e.is_directory()) identities.push_back(e.path());
  }
  std::sort(identities.begin(), identities.end());
  json failed = json::array();
  std::size_t gallery_images = 0;
  for (const fs::path& dir : identities) {
    for (const fs::path& img : list_images(dir)) {
      ++gallery_images;
      Described d;
      try {
        d = describe(analyzer, stream, device, img, a);
      } catch (const Error& e) {
        skip_failed(a, img.string(), e, failed);
        continue;
      }
      if (d.faces.empty()) {
        log_warn("no face in gallery image " + img.string() + " (skipped)");
        continue;
      }
      gallery.push_back({dir.filename().string(), img.string(), d.faces.front().descriptor});
    }
  }
  if (gallery.empty()) {
    throw Error("identify", "gallery " + a.gallery + " holds no usable face image",
                "put images (PNG, JPEG, .npy) with one visible face into DIR/<identity>/");
  }
  const Described p = describe(analyzer, stream, device, a.probe, a);
  const auto ranked = jr2::rank_identities(gallery, best_face(p, a.probe).descriptor);
  const std::size_t n = std::min(a.top, ranked.size());
  if (a.json) {
    json c = json::array();
    for (std::size_t i = 0; i < n; ++i) {
      c.push_back({{"rank", i + 1},
                   {"identity", ranked[i].identity},
                   {"distance", ranked[i].distance},
                   {"source", ranked[i].source}});
    }
    std::cout << json{{"probe", a.probe},
                      {"gallery_images", gallery.size()},
                      {"candidates", c},
                      {"failed", failed}}
                     .dump(2)
              << "\n";
    fail_if_any(failed, gallery_images, "gallery images");
    return;
  }
  std::printf("%s against %zu gallery images:\n", a.probe.c_str(), gallery.size());
  for (std::size_t i = 0; i < n; ++i) {
    std::printf("  %zu. %-24s distance %.4f%s\n", i + 1, ranked[i].identity.c_str(),
                ranked[i].distance,
                ranked[i].distance < jr2::kFaceApiMatchThreshold ? "  (match)" : "");
  }
  if (!failed.empty()) {
    std::printf("identify: %zu of %zu gallery images failed\n", failed.size(), gallery_images);
  }
  fail_if_any(failed, gallery_images, "gallery images");
}

}  // namespace

void add_faces(CLI::App& app) {
  {
    auto a = std::make_shared<DetectArgs>();
    CLI::App* cmd = app.add_subcommand("detect", "Detect faces and their 68 landmarks");
    cmd->add_option("input", a->input, "Image (PNG, JPEG, TIFF, .npy) or video file")->required();
    add_common(cmd, *a, false);
    cmd->add_option("--draw", a->draw,
                    "Write the image with boxes and landmarks drawn; the format follows the "
                    "extension (.png, .jpg, .tif, .bmp)");
    cmd->add_flag("--force", a->force, "Replace an existing --draw file");
    cmd->add_option("--every", a->every, "Videos: use every N-th frame")
        ->default_val(1)
        ->check(integer_range(1, 1000000));
    cmd->add_option("--max-frames", a->max_frames, "Videos: stop after this many frames (0 = all)")
        ->default_val(0)
        ->check(integer_range(0, 100000000));
    cmd->footer(
        "Examples:\n  vkjr2 detect photo.jpg --draw boxes.png\n  vkjr2 detect vtest.avi --every 10 "
        "--max-frames 5 --json\n  vkjr2 detect chip.jpg --input-size 160   # a face that fills a "
        "small image\n"
        "A face filling the whole image is larger than the detector's anchors at 416: face-api "
        "misses such crops too;\n--input-size 160 or 224 finds them (or pass the crop to embed "
        "--aligned).");
    cmd->callback([a] { run_detect(*a); });
  }
  {
    auto a = std::make_shared<EmbedArgs>();
    CLI::App* cmd = app.add_subcommand("embed", "Compute a 128-d descriptor per detected face");
    cmd->add_option("inputs", a->inputs,
                    "Images (PNG, JPEG, TIFF, .npy float32 HWC RGB 0..255) or folders of them")
        ->required();
    add_common(cmd, *a, true);
    cmd->add_flag("--fail-fast", a->fail_fast,
                  "Stop at the first input that fails (default: report it, go on, exit 1 at "
                  "the end)");
    cmd->footer(
        "Examples:\n  vkjr2 embed a.jpg b.png --json\n  vkjr2 embed chip150.npy --aligned\n"
        "Images without a face are reported on stderr; the command fails only when no input "
        "has a face.\nAn input that cannot be read is reported and skipped; the exit code is 1 "
        "when any was.");
    cmd->callback([a] { run_embed(*a); });
  }
  {
    auto a = std::make_shared<VerifyArgs>();
    CLI::App* cmd = app.add_subcommand("verify", "Are two images the same person? (1:1)");
    cmd->add_option("a", a->a_path, "First image")->required();
    cmd->add_option("b", a->b_path, "Second image")->required();
    add_common(cmd, *a, true);
    cmd->add_option("--threshold", a->threshold, "Same person below this descriptor distance")
        ->default_val(jr2::kFaceApiMatchThreshold)
        ->check(positive_up_to(100));
    cmd->footer(
        "Uses the highest-scoring face of each image.\nExample:\n  vkjr2 verify a.jpg b.jpg");
    cmd->callback([a] { run_verify(*a); });
  }
  {
    auto a = std::make_shared<IdentifyArgs>();
    CLI::App* cmd = app.add_subcommand("identify", "Rank gallery identities for a probe (1:N)");
    cmd->add_option("probe", a->probe, "Probe image")->required();
    cmd->add_option("--gallery", a->gallery, "Folder with one sub-folder of images per identity")
        ->required();
    cmd->add_option("--top", a->top, "Candidates to list")
        ->default_val(5)
        ->check(integer_range(1, 1000000));
    add_common(cmd, *a, true);
    cmd->add_flag("--fail-fast", a->fail_fast,
                  "Stop at the first gallery image that fails (default: report it, go on, exit 1 "
                  "at the end)");
    cmd->footer("Example:\n  vkjr2 identify probe.jpg --gallery people/ --top 3");
    cmd->callback([a] { run_identify(*a); });
  }
}

}  // namespace vkjr2::cli
