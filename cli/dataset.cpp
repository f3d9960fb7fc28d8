// vkjr2 dataset make / merge: the JR² benchmark (jr2/benchmark.hpp) as files:
// clean gallery clips (PNG) and turbulent probe videos (Motion-JPEG .avi),
// with manifest.json and manifest.csv.
#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/host_tensor.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <CLI/CLI.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <map>
#include <memory>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "checks.hpp"
#include "cleanup.hpp"
#include "clips.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"
#include "progress.hpp"
#include "sim_common.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;

struct MakeArgs {
  std::string out, source, strengths = "weak,moderate,strong", shard, device;
  int frames = 30, clip_size = 160, face_px = 80, probes = 1, input_size = 416, max_identities = 0;
  double enrolled = 0.5;
  std::uint64_t seed = 1;
  bool force = false, resume = false, quiet = false, json_out = false;
};

constexpr double kProbeFps = 30.0;

fs::path bundled_root() { return nets::face_api_model_dir().parent_path() / "demo"; }

// A face source: its images, each image's detections cached (a bundled photo
// holds several identities; each probe and gallery item needs its box).
class FaceSource {
 public:
  FaceSource(const jr2::FaceAnalyzer& analyzer, Stream& stream, int input_size)
      : analyzer_(analyzer), stream_(stream) {
    options_.input_size = input_size;
    options_.descriptors = false;
  }

  const Image& image(const fs::path& path) {
    auto it = images_.find(path.string());
    if (it == images_.end()) {
      if (images_.size() >= kCachedImages) {  // bounded memory for large sources
        images_.clear();
        faces_.clear();
      }
      it = images_.emplace(path.string(), read_image(path)).first;
    }
    return it->second;
  }
  const std::vector<jr2::Face>& faces(const fs::path& path) {
    auto it = faces_.find(path.string());
    if (it == faces_.end()) {
      const Image& img = image(path);
      it = faces_
               .emplace(path.string(),
                        analyzer_.analyze(stream_, nets::image_to_device(stream_.device(), img),
                                          options_))
               .first;
    }
    return it->second;
  }

 private:
  static constexpr std::size_t kCachedImages = 32;
  const jr2::FaceAnalyzer& analyzer_;
  Stream& stream_;
  jr2::FaceOptions options_;
  std::map<std::string, Image> images_;
  std::map<std::string, std::vector<jr2::Face>> faces_;
};

// ROOT/<identity>/<image>: every image of every identity folder, sorted.
std::vector<jr2::SourceImage> folder_source(const fs::path& root) {
  std::vector<fs::path> ids;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(root, ec)) {
    if (e.is_directory()) ids.push_back(e.path());
  }
  if (ec) {
    throw Error("dataset make", "cannot list " + root.string() + ": " + ec.message(),
                "check --source");
  }
  std::sort(ids.begin(), ids.end());
  std::vector<jr2::SourceImage> images;
  for (const fs::path& dir : ids) {
    for (const fs::path& img : list_images(dir)) {
      images.push_back(
          {dir.filename().string(), (dir.filename() / img.filename()).generic_string(), 0});
    }
  }
  if (images.empty()) {
    throw UsageError("--source", root.string() + " holds no ROOT/<identity>/<image> files",
                     "lay the faces out one folder per identity (as LFW, VGGFace2 and WebFace "
                     "ship), or leave --source out for the bundled photos");
  }
  return images;
}

// Whether detection f is a box between faces rather than a face: more than
// half of it lies inside stronger detections (sample6.jpg has one, between
// two faces, that NMS keeps at IoU 0.27 with each; as an identity of its own
// it would be a copy of its neighbours).
bool straddles(const std::vector<jr2::Face>& found, std::size_t f) {
  const nets::FaceBox& b = found[f].box;
  double covered = 0;
  for (std::size_t g = 0; g < f; ++g) {  // stronger: earlier (highest score first)
    const nets::FaceBox& o = found[g].box;
    const double w = std::min(b.x + b.width, o.x + o.width) - std::max(b.x, o.x);
    const double h = std::min(b.y + b.height, o.y + o.height) - std::max(b.y, o.y);
    if (w > 0 && h > 0) covered += w * h;
  }
  return covered > 0.5 * b.width * b.height;
}

// The bundled photos: every face the detector finds in a clean photo is its
// own identity ("sample1#2": the second face of sample1.jpg, by score), but
// for boxes that straddle stronger ones.
// max_identities > 0: the photos are read only until that many faces are
// found (the first N identities by name come from the first photos).
std::vector<jr2::SourceImage> bundled_source(FaceSource& faces, int max_identities) {
  std::vector<jr2::SourceImage> images;
  for (int i = 1; i <= 6; ++i) {
    if (max_identities > 0 && images.size() >= std::size_t(max_identities)) break;
    const std::string name = "sample" + std::to_string(i) + ".jpg";
    const fs::path p = bundled_root() / name;
    std::error_code ec;
    if (!fs::is_regular_file(p, ec)) {
      throw Error("dataset make", p.string() + " is missing",
                  "run scripts/setup (it fetches face-api's sample photos)");
    }
    const auto& found = faces.faces(p);
    for (std::size_t f = 0; f < found.size(); ++f) {
      if (straddles(found, f)) continue;
      images.push_back({"sample" + std::to_string(i) + "#" + std::to_string(f + 1), name, int(f)});
    }
  }
  return images;
}

// The face box of a source image: the face'th detection for bundled photos;
// for folder images, the detection nearest the image centre (else a centred
// box of 45 % of the shorter side, as face-centred crops such as LFW's have).
nets::FaceBox face_box(FaceSource& faces, const fs::path& path, const jr2::SourceImage& s,
                       bool bundled, std::size_t& undetected) {
  const Image& img = faces.image(path);
  const double w = double(img.shape[1]), h = double(img.shape[0]);
  const auto& found = faces.faces(path);
  if (bundled) {
    if (std::size_t(s.face) >= found.size()) {
      throw Error("dataset make",
                  path.string() + ": face " + std::to_string(s.face + 1) + " is no longer found",
                  "make the benchmark with one vkjr2 version and device");
    }
    return found[std::size_t(s.face)].box;
  }
  const jr2::Face* best = nullptr;
  double best_d = 0;
  for (const jr2::Face& f : found) {
    const double dx = f.box.x + f.box.width / 2 - w / 2, dy = f.box.y + f.box.height / 2 - h / 2;
    const double d = dx * dx + dy * dy;
    if (best == nullptr || d < best_d) {
      best = &f;
      best_d = d;
    }
  }
  if (best != nullptr) return best->box;
  ++undetected;
  const double side = 0.45 * std::min(w, h);
  return {(w - side) / 2, (h - side) / 2, side, side};
}

void write_text_file(const fs::path& path, const std::string& text) {
  vkjr2::write_file_atomic(path, std::as_bytes(std::span(text)), "dataset");
}

void run_make(const MakeArgs& a) {
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path out(a.out);
  check_output_folder(out, "--out");
  jr2::BenchmarkOptions o;
  try {
    o.strengths = jr2::parse_strengths(a.strengths);
  } catch (const InvalidArgument& e) {
    throw UsageError("--strengths", e.problem(), e.fix());
  }
  o.frames = a.frames;
  o.clip_size = a.clip_size;
  o.face_px = a.face_px;
  o.probes = a.probes;
  o.enrolled = a.enrolled;
  o.seed = a.seed;
  if (a.face_px > a.clip_size) {
    throw UsageError(
        "--face-px",
        std::to_string(a.face_px) + " px faces in " + std::to_string(a.clip_size) + " px clips",
        "make the face smaller than the clip (about half of it keeps context)");
  }
  int shard = 0, shards = 1;
  if (!a.shard.empty()) {
    try {
      std::tie(shard, shards) = jr2::parse_shard(a.shard);
    } catch (const InvalidArgument& e) {
      throw UsageError("--shard", e.problem(), e.fix());
    }
  }
  const bool bundled = a.source.empty();
  const fs::path root = bundled ? bundled_root() : fs::path(a.source);
  if (!bundled) check_input_folder(root, "--source");
  const std::string manifest_name =
      shards > 1 ? jr2::shard_manifest_name(shard, shards) : "manifest.json";
  std::error_code ec;
  if (!a.force && !a.resume && fs::exists(out / manifest_name, ec)) {
    throw UsageError("--out", (out / manifest_name).string() + " exists",
                     "pass --force to make it again, --resume to finish it, or another --out");
  }

  const Device device = open_device(a.device);
  const jr2::FaceAnalyzer analyzer(device);
  Stream stream(device);
  FaceSource faces(analyzer, stream, a.input_size);
  std::vector<jr2::SourceImage> images =
      bundled ? bundled_source(faces, a.max_identities) : folder_source(root);
  if (a.max_identities > 0) {  // the first N identities by name
    std::set<std::string> ids;
    for (const auto& im : images) ids.insert(im.identity);
    if (ids.size() > std::size_t(a.max_identities)) {
      ids.erase(std::next(ids.begin(), a.max_identities), ids.end());
      std::erase_if(images,
                    [&](const jr2::SourceImage& im) { return ids.count(im.identity) == 0; });
    }
  }
  jr2::Manifest plan;
  try {
    plan = jr2::plan_benchmark(images, o);
  } catch (const InvalidArgument& e) {
    throw UsageError(bundled ? "dataset make" : "--source", e.problem(), e.fix());
  }
  plan.source_kind = bundled ? "bundled" : "folder";
  plan.source_root = bundled ? std::string("face-api-1.7.15/demo") : fs::absolute(root).string();
  const jr2::Manifest part = jr2::shard_of(plan, shard, shards);

  create_output_folder(out, "--out");
  const auto blur = sim::load_shipped_blur_models(device);
  const std::size_t steps = part.gallery.size() + part.probes.size() * std::size_t(o.frames);
  Progress bar("dataset make" + (shards > 1 ? " " + a.shard : std::string()), steps, a.quiet);
  std::size_t done = 0, made = 0, kept = 0, undetected = 0;
  const auto exists = [&](const fs::path& p) {
    std::error_code e;
    return fs::is_regular_file(p, e);
  };

  for (const jr2::GalleryItem& g : part.gallery) {
    const fs::path file = out / g.file;
    if (a.resume && exists(file)) {
      ++kept;
    } else {
      create_output_folder(file.parent_path(), "--out");
      const fs::path src = root / g.source.path;
      const nets::FaceBox box = face_box(faces, src, g.source, bundled, undetected);
      write_image(file, face_clip(faces.image(src), box, o.clip_size, o.face_px), a.force);
      ++made;
    }
    bar.update(++done);
  }

  const int c = o.clip_size;
  const Shape shape{1, 3, c, c};
  const Tensor x = Tensor::empty(device, shape), y = Tensor::empty(device, shape);
  const sim::SimOptions so = jr2::probe_sim_options();
  for (const jr2::ProbeItem& p : part.probes) {
    const fs::path file = out / p.file;
    if (a.resume && exists(file) && exists(out / p.clean_file)) {
      ++kept;
      done += std::size_t(o.frames);
      bar.update(done);
      continue;
    }
    create_output_folder(file.parent_path(), "--out");
    const fs::path src = root / p.source.path;
    const nets::FaceBox box = face_box(faces, src, p.source, bundled, undetected);
    // 8-bit, as written: the clean file is exactly what went into the simulator.
    Image clip = face_clip(faces.image(src), box, c, o.face_px);
    for (float& v : clip.values) v = std::round(v);
    if (!(a.resume && exists(out / p.clean_file))) write_image(out / p.clean_file, clip, a.force);
    sim::Simulator simulator(device, jr2::probe_sim_params(p.d_over_r0, c), blur, so);
    simulator.reset(p.seed);
    x.upload(image_to_planes(clip, 3, 255.f));
    VideoWriter writer(file, kProbeFps, c, c, a.force);
    for (int t = 0; t < o.frames; ++t) {
      simulator.frame(stream, x, y);
      stream.run();
      writer.write(planes_to_image(y.download(), 3, c, c, 3, 255.f));
      bar.update(++done);
    }
    writer.finish();
    ++made;
  }
  bar.done();
  if (undetected > 0) {
    log_warn(std::to_string(undetected) +
             " source images had no face the detector found: their clips are centred crops");
  }
  write_text_file(out / manifest_name, jr2::manifest_json(part));
  if (shards == 1) write_text_file(out / "manifest.csv", jr2::manifest_csv(part));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::size_t mated = 0;
  for (const auto& p : part.probes) mated += p.mated ? 1 : 0;
  if (a.json_out) {
    std::printf(
        "{\"manifest\": \"%s\", \"identities\": %zu, \"gallery\": %zu, \"probes\": %zu, "
        "\"mated\": %zu, \"made\": %zu, \"kept\": %zu, \"split_kind\": \"%s\", \"seconds\": "
        "%.1f}\n",
        (out / manifest_name).string().c_str(), plan.identities, part.gallery.size(),
        part.probes.size(), mated, made, kept,
        plan.split_kind == jr2::SplitKind::identity ? "identity" : "realization", seconds);
    return;
  }
  std::printf(
      "%s: %zu identities, %zu gallery clips, %zu probe videos (%zu mated, %zu non-mated) "
      "of %d frames, %s-disjoint val/test splits; %zu made, %zu kept, %.0f s\n",
      (out / manifest_name).string().c_str(), plan.identities, part.gallery.size(),
      part.probes.size(), mated, part.probes.size() - mated, o.frames,
      plan.split_kind == jr2::SplitKind::identity ? "identity" : "realization", made, kept,
      seconds);
  if (shards > 1) {
    std::printf("when all %d shards are done: vkjr2 dataset merge %s\n", shards,
                out.string().c_str());
  }
}

void run_merge(const std::string& dir_text, bool force) {
  const fs::path dir(dir_text);
  check_input_folder(dir, "DIR");
  const std::regex name(R"(manifest\.shard-(\d+)-of-(\d+)\.json)");
  std::vector<jr2::Manifest> shards;
  for (const fs::path& p : list_files(
           dir, [&](const fs::path& f) { return std::regex_match(f.filename().string(), name); })) {
    shards.push_back(jr2::read_manifest(p));
  }
  if (shards.empty()) {
    throw UsageError("DIR", dir.string() + " holds no manifest.shard-I-of-N.json",
                     "run vkjr2 dataset make --shard I/N --out " + dir.string() + " first");
  }
  jr2::Manifest m;
  try {
    m = jr2::merge_shards(shards);
  } catch (const InvalidArgument& e) {
    throw Error("dataset merge", dir.string() + ": " + e.problem(), e.fix());
  }
  jr2::check_manifest_files(m, dir);
  check_output_file(dir / "manifest.json", force, "DIR");
  write_text_file(dir / "manifest.json", jr2::manifest_json(m));
  write_text_file(dir / "manifest.csv", jr2::manifest_csv(m));
  std::printf("%s: %zu shards merged, %zu gallery clips, %zu probe videos\n",
              (dir / "manifest.json").string().c_str(), shards.size(), m.gallery.size(),
              m.probes.size());
}

}  // namespace

void add_dataset(CLI::App& app) {
  CLI::App* cmd =
      app.add_subcommand("dataset", "Make the JR² benchmark (gallery + turbulent probe videos)");
  cmd->require_subcommand(1);
  auto a = std::make_shared<MakeArgs>();
  CLI::App* make = cmd->add_subcommand(
      "make",
      "Make a benchmark: clean gallery clips and turbulent probe videos, with manifest.json");
  make->footer(
      "Input: face-api's sample photos (every face found is its own identity), or --source ROOT "
      "laid out\n"
      "ROOT/<identity>/<image> (LFW, VGGFace2, WebFace). A share of the identities (--enrolled) is "
      "enrolled:\n"
      "their first image's clean clip is the gallery; their other images (or the same one, when "
      "they have\n"
      "one) become mated probe videos; the other identities become non-mated probes (distractors). "
      "Each\n"
      "probe is a clip of the face with context (the face --face-px wide in a --clip-size square) "
      "through\n"
      "--frames of turbulence at each strength, D/r0 drawn log-uniformly: weak 1–2, moderate 2–4, "
      "strong 4–8.\n"
      "Splits val and test: identity-disjoint when the source has enough identities (20 per "
      "split), else\n"
      "the same identities with other turbulence realizations. The same seed gives the same "
      "files.\n"
      "Writes DIR/gallery/*.png, DIR/probes/SPLIT/STRENGTH/*.avi, DIR/manifest.json and "
      "manifest.csv.\n"
      "On a cluster: --shard I/N in each of N jobs (docs/eval.md), then vkjr2 dataset merge DIR.\n"
      "Examples:\n"
      "  vkjr2 dataset make --out bench/jr2\n"
      "  vkjr2 dataset make --source lfw/ --out bench/lfw --strengths moderate,strong --probes 2\n"
      "  vkjr2 dataset make --out bench/jr2 --shard $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT");
  make->add_option("--out", a->out, "Output folder")->required();
  make->add_option("--source", a->source,
                   "ROOT/<identity>/<image> face folder (default: face-api's sample photos)");
  make->add_option("--strengths", a->strengths, "Comma-separated turbulence strengths")
      ->default_val("weak,moderate,strong");
  make->add_option("--frames", a->frames, "Frames per probe video")
      ->default_val(30)
      ->check(integer_range(1, 10000));
  make->add_option("--clip-size", a->clip_size, "Side of the gallery and probe clips (px)")
      ->default_val(160)
      ->check(integer_range(32, 1024));
  make->add_option("--face-px", a->face_px, "Width of the face box in a clip (px)")
      ->default_val(80)
      ->check(integer_range(8, 1024));
  make->add_option("--probes", a->probes, "Probe videos per identity, strength and split")
      ->default_val(1)
      ->check(integer_range(1, 1000));
  make->add_option("--enrolled", a->enrolled, "Share of the identities enrolled in the gallery")
      ->capture_default_str()
      ->check(finite_range(0.01, 1));
  make->add_option("--max-identities", a->max_identities,
                   "Use only the first N identities by name (0: all; a quick, small benchmark)")
      ->default_val(0)
      ->check(integer_range(0, 100000000));
  make->add_option("--input-size", a->input_size, "Detector input size for the source images")
      ->default_val(416)
      ->check(integer_range(32, 1024));
  add_seed_option(make, a->seed, "Seed of the identities' roles and the turbulence");
  make->add_option("--shard", a->shard, "Make part I of N (0 ≤ I < N): manifest.shard-I-of-N.json");
  make->add_option("--device", a->device,
                   "Vulkan device index or name substring (else VKJR2_DEVICE)");
  make->add_flag("--resume", a->resume,
                 "Keep the files already made (they are written whole or not at all)");
  make->add_flag("--force", a->force, "Replace existing files");
  make->add_flag("--quiet", a->quiet, "No progress bar");
  make->add_flag("--json", a->json_out, "Print a JSON summary");
  make->callback([a] {
    if (a->input_size % 32 != 0) {
      throw UsageError("--input-size", std::to_string(a->input_size) + " is not a multiple of 32",
                       "use 160, 224, 320, 416, 512 or 608");
    }
    run_make(*a);
  });

  auto dir = std::make_shared<std::string>();
  auto force = std::make_shared<bool>(false);
  CLI::App* merge = cmd->add_subcommand(
      "merge", "Merge the manifests of a sharded dataset make into manifest.json");
  merge->footer(
      "Checks that all N shards of one run are there and every file they list exists.\n"
      "Example:\n  vkjr2 dataset merge bench/jr2");
  merge->add_option("DIR", *dir, "The --out folder of the shards")->required();
  merge->add_flag("--force", *force, "Replace an existing manifest.json");
  merge->callback([dir, force] { run_merge(*dir, *force); });
}

}  // namespace vkjr2::cli
