// The JR² benchmark: which faces are enrolled, which probe videos are made
// of which face at which turbulence, and the manifest that lists them
// (docs/eval.md). `vkjr2 dataset make` plans a benchmark here and writes its
// files; `vkjr2 eval` reads the manifest back.
//
// The plan is a pure function of the identities, the options and the seed:
// every probe's turbulence strength (D/r0) and simulator seed come from
// (seed, probe index), never from the order work is done in, so a shard of
// the work (--shard I/N) writes exactly the files the one-process run writes,
// and the merged shard manifests equal its manifest.
#pragma once

#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace vkjr2::jr2 {

// A named turbulence strength: D/r0 drawn log-uniformly in [lo, hi].
struct StrengthRange {
  std::string name;
  double d_over_r0_lo = 0, d_over_r0_hi = 0;
};
// weak [1, 2], moderate [2, 4], strong [4, 8]: around the simulator presets
// (D/r0 ≈ 1.5, 3, 6).
std::vector<StrengthRange> default_strengths();
// "weak,strong" → those of default_strengths(); throws InvalidArgument
// naming an unknown one.
std::vector<StrengthRange> parse_strengths(const std::string& names);

// One face image of the source: where it is and whose it is.
struct SourceImage {
  std::string identity;
  std::string path;  // as given (absolute, or relative to the source root)
  int face = 0;      // which detected face of the image (bundled photos hold several)
};

struct BenchmarkOptions {
  std::vector<StrengthRange> strengths = default_strengths();
  int frames = 30;                // frames per probe video
  int clip_size = 160;            // probe and gallery clips are clip_size² pixels
  int face_px = 80;               // the face box's width in the clip (context: clip/face ≈ 2)
  int probes = 1;                 // probe videos per identity, strength and split
  double enrolled = 0.5;          // the share of identities enrolled: ⌊share · N⌋, at least 1
  double val_share = 0.3;         // identity-disjoint splits: the share of identities in val
  int min_split_identities = 20;  // per split, for identity-disjoint splits
  std::uint64_t seed = 1;
};

enum class SplitKind : std::uint8_t {
  identity,     // val and test hold different identities (and realizations)
  realization,  // too few identities: both hold every identity, with other realizations
};

struct GalleryItem {
  std::string identity;
  std::string split;  // "val", "test", or "all" (realization splits)
  std::string file;   // relative to the benchmark folder
  SourceImage source;
};

struct ProbeItem {
  std::string identity;
  bool mated = false;  // the identity is enrolled
  std::string split;   // "val" or "test"
  std::string strength;
  double d_over_r0 = 0;
  std::uint64_t seed = 0;  // the simulator's
  std::string file;        // relative to the benchmark folder (.avi)
  std::string clean_file;  // the clip before turbulence (.png): PSNR and SSIM are against it
  SourceImage source;
  bool same_image_as_gallery = false;  // the identity had one image only
};

struct Manifest {
  int version = 1;
  std::string source_kind;  // "bundled" or "folder"
  std::string source_root;
  std::size_t identities = 0;
  BenchmarkOptions options;
  SplitKind split_kind = SplitKind::realization;
  std::vector<GalleryItem> gallery;
  std::vector<ProbeItem> probes;
  // Images of the source that could not be used, and why.
  std::vector<std::pair<std::string, std::string>> skipped;
  int shard_index = 0, shard_count = 1;  // a shard's manifest lists its part only
};

// Plans the benchmark over the source's images (each identity's images in
// the order given; its first image is its gallery image, the others its
// probes' sources, or the first again when it has one only). Throws
// InvalidArgument when there are fewer than 2 identities or the options are
// out of range.
Manifest plan_benchmark(const std::vector<SourceImage>& images, const BenchmarkOptions& options);

// The part of a plan that shard `index` of `count` makes: gallery items and
// probes whose position (gallery first, then probes) ≡ index mod count.
Manifest shard_of(const Manifest& plan, int index, int count);
// Parses "I/N" (0 ≤ I < N); throws InvalidArgument otherwise.
std::pair<int, int> parse_shard(const std::string& text);
// The whole benchmark from all the shards' manifests: every shard of one
// plan present once. Throws InvalidArgument naming what is missing or
// inconsistent.
Manifest merge_shards(const std::vector<Manifest>& shards);

// JSON text (keys in a fixed order, so equal manifests are equal bytes) and
// back. read throws Error naming the file and the field at fault.
std::string manifest_json(const Manifest& m);
Manifest parse_manifest(const std::string& text, const std::string& what);
Manifest read_manifest(const std::filesystem::path& path);
// The probes and the gallery as CSV rows (for spreadsheets).
std::string manifest_csv(const Manifest& m);
// Throws Error naming the first file of the manifest missing under `dir`.
void check_manifest_files(const Manifest& m, const std::filesystem::path& dir);

// The file names a shard writes: manifest.shard-I-of-N.json.
std::string shard_manifest_name(int index, int count);

// How a probe is simulated: the "moderate" preset's path and optics (L =
// 1 km, D = 0.2 m, 525 nm on every channel) with r0 = D / d_over_r0, on a
// clip_size² RGB frame; the tilt correlated 0.9 and the blur 0.6 from frame
// to frame (vkjr2 simulate's defaults). Throws InvalidArgument for a D/r0
// the simulator refuses.
sim::Params probe_sim_params(double d_over_r0, int clip_size);
sim::SimOptions probe_sim_options();

}  // namespace vkjr2::jr2
