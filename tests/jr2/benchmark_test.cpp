// The benchmark plan and its manifest: determinism, the splits, shards that
// merge back into the one-process plan, and clear errors for a bad manifest.
#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

namespace vkjr2::jr2 {
namespace {

std::vector<SourceImage> source(int identities, int images_each) {
  std::vector<SourceImage> s;
  for (int i = 0; i < identities; ++i) {
    for (int k = 0; k < images_each; ++k) {
      s.push_back({"person " + std::to_string(i),
                   "p" + std::to_string(i) + "/" + std::to_string(k) + ".jpg", 0});
    }
  }
  return s;
}

TEST(Benchmark, RealizationSplitsForAFewIdentities) {
  BenchmarkOptions o;
  o.seed = 7;
  const Manifest m = plan_benchmark(source(22, 1), o);
  EXPECT_EQ(m.split_kind, SplitKind::realization);
  EXPECT_EQ(m.identities, 22u);
  EXPECT_EQ(m.gallery.size(), 11u);  // 22 · 0.5
  // Every identity in both splits at every strength.
  EXPECT_EQ(m.probes.size(), 22u * 3 * 2);
  std::set<std::uint64_t> seeds;
  std::set<std::string> files;
  for (const ProbeItem& p : m.probes) {
    seeds.insert(p.seed);
    files.insert(p.file);
    const auto& r = p.strength == "weak"       ? o.strengths[0]
                    : p.strength == "moderate" ? o.strengths[1]
                                               : o.strengths[2];
    EXPECT_GE(p.d_over_r0, r.d_over_r0_lo);
    EXPECT_LE(p.d_over_r0, r.d_over_r0_hi);
    EXPECT_EQ(p.same_image_as_gallery, p.mated);  // one image each
  }
  EXPECT_EQ(seeds.size(), m.probes.size());  // disjoint realizations
  EXPECT_EQ(files.size(), m.probes.size());
  for (const GalleryItem& g : m.gallery) EXPECT_EQ(g.split, "all");
  // The same seed plans the same benchmark; another seed another one.
  EXPECT_EQ(manifest_json(plan_benchmark(source(22, 1), o)), manifest_json(m));
  o.seed = 8;
  EXPECT_NE(manifest_json(plan_benchmark(source(22, 1), o)), manifest_json(m));
}

TEST(Benchmark, IdentitySplitsForManyIdentities) {
  BenchmarkOptions o;
  o.strengths = parse_strengths("strong");
  const Manifest m = plan_benchmark(source(100, 3), o);
  ASSERT_EQ(m.split_kind, SplitKind::identity);
  std::map<std::string, std::set<std::string>> splits;
  for (const ProbeItem& p : m.probes) {
    splits[p.identity].insert(p.split);
    EXPECT_FALSE(p.same_image_as_gallery);
    if (p.mated) {  // not the gallery image
      EXPECT_NE(p.source.path.substr(p.source.path.size() - 5), "0.jpg");
    }
  }
  std::size_t val = 0;
  for (const auto& [id, s] : splits) {
    EXPECT_EQ(s.size(), 1u) << id;
    val += s.count("val");
  }
  EXPECT_EQ(val, 30u);
  for (const GalleryItem& g : m.gallery) EXPECT_NE(g.split, "all");
  EXPECT_NO_THROW(parse_manifest(manifest_json(m), "m"));
}

TEST(Benchmark, ShardsMergeIntoTheOneProcessPlan) {
  const Manifest m = plan_benchmark(source(9, 2), BenchmarkOptions{});
  for (int n : {1, 2, 3, 7, 200}) {
    std::vector<Manifest> shards;
    std::size_t items = 0;
    for (int i = n - 1; i >= 0; --i) {  // any order
      shards.push_back(parse_manifest(manifest_json(shard_of(m, i, n)), "shard"));
      items += shards.back().gallery.size() + shards.back().probes.size();
    }
    EXPECT_EQ(items, m.gallery.size() + m.probes.size());
    EXPECT_EQ(manifest_json(merge_shards(shards)), manifest_json(m)) << n << " shards";
    if (n > 1) {
      shards.pop_back();
      EXPECT_THROW(merge_shards(shards), InvalidArgument);
    }
  }
  BenchmarkOptions other;
  other.seed = 2;
  const std::vector<Manifest> mixed = {shard_of(m, 0, 2),
                                       shard_of(plan_benchmark(source(9, 2), other), 1, 2)};
  EXPECT_THROW(merge_shards(mixed), InvalidArgument);
  EXPECT_EQ(parse_shard("3/8"), std::make_pair(3, 8));
  for (const char* bad : {"8/8", "-1/2", "1/0", "1", "a/b", "1/2/3", "1 /2"}) {
    EXPECT_THROW(parse_shard(bad), InvalidArgument) << bad;
  }
}

TEST(Benchmark, ManifestErrorsNameTheItem) {
  const Manifest m = plan_benchmark(source(4, 1), BenchmarkOptions{});
  const std::string good = manifest_json(m);
  const auto message = [](const std::string& text) -> std::string {
    try {
      parse_manifest(text, "bench/manifest.json");
    } catch (const Error& e) {
      return e.what();
    }
    return "(accepted)";
  };
  EXPECT_EQ(message(good), "(accepted)");
  EXPECT_NE(message("{").find("not JSON"), std::string::npos);
  EXPECT_NE(message("{\"a\": 1}").find("not a vkjr2 benchmark"), std::string::npos);
  std::string text = good;
  text.replace(text.find("\"split\": \"val\""), 14, "\"split\": \"dev\"");
  EXPECT_NE(message(text).find("probes[0]: split 'dev'"), std::string::npos) << message(text);
  text = good;
  text.replace(text.find("\"file\": \"probes/"), 16, "\"file\": \"../x/");
  EXPECT_NE(message(text).find("not a path inside"), std::string::npos) << message(text);
  text = good;
  text.replace(text.find("\"mated\": true"), 13, "\"mated\": false");
  EXPECT_NE(message(text).find("who is enrolled"), std::string::npos) << message(text);
  EXPECT_THROW(parse_strengths("weak,medium"), InvalidArgument);
  EXPECT_THROW(parse_strengths("weak,weak"), InvalidArgument);
  EXPECT_THROW(plan_benchmark(source(1, 3), BenchmarkOptions{}), InvalidArgument);
  BenchmarkOptions o;
  o.face_px = 500;
  EXPECT_THROW(plan_benchmark(source(4, 1), o), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::jr2
