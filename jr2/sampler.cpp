#include <vkjr2/jr2/sampler.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <charconv>
#include <random>

#include "internal/text_and_draws.hpp"

namespace vkjr2::jr2 {
namespace {

constexpr const char* kSyntax = "write segments:SxR (e.g. segments:4x2), uniform:K or all";

int parse_positive(const std::string& text, std::size_t begin, std::size_t end,
                   const std::string& whole) {
  int value = 0;
  const char* first = text.data() + begin;
  const char* last = text.data() + end;
  const auto [ptr, ec] = std::from_chars(first, last, value);
  if (ec != std::errc() || ptr != last || value < 1) {
    throw InvalidArgument("frame sampler", "'" + whole + "' is not a frame sampler", kSyntax);
  }
  return value;
}

}  // namespace

FrameSampler parse_frame_sampler(const std::string& text) {
  FrameSampler s;
  if (text == "all") {
    s.kind = SamplerKind::all;
    return s;
  }
  const std::string seg = "segments:";
  const std::string uni = "uniform:";
  if (text.rfind(seg, 0) == 0) {
    const std::size_t x = text.find('x', seg.size());
    if (x == std::string::npos) {
      throw InvalidArgument("frame sampler", "'" + text + "' is not a frame sampler", kSyntax);
    }
    s.kind = SamplerKind::segments;
    s.segments = parse_positive(text, seg.size(), x, text);
    s.run = parse_positive(text, x + 1, text.size(), text);
    return s;
  }
  if (text.rfind(uni, 0) == 0) {
    s.kind = SamplerKind::uniform;
    s.count = parse_positive(text, uni.size(), text.size(), text);
    return s;
  }
  throw InvalidArgument("frame sampler", "'" + text + "' is not a frame sampler", kSyntax);
}

std::string to_string(const FrameSampler& s) {
  switch (s.kind) {
    case SamplerKind::segments:
      return "segments:" + std::to_string(s.segments) + "x" + std::to_string(s.run);
    case SamplerKind::uniform:
      return "uniform:" + std::to_string(s.count);
    case SamplerKind::all:
      break;
  }
  return "all";
}

std::vector<int> sample_frames(int frame_count, const FrameSampler& s, std::uint64_t seed) {
  if (frame_count < 1 || s.segments < 1 || s.run < 1 || s.count < 1) {
    throw InvalidArgument(
        "sample_frames",
        "frame_count = " + std::to_string(frame_count) + ", sampler " + to_string(s),
        "a video has at least one frame; counts, segments and runs are ≥ 1");
  }
  std::vector<int> frames;
  if (s.kind == SamplerKind::all) {
    for (int f = 0; f < frame_count; ++f) frames.push_back(f);
    return frames;
  }
  if (s.kind == SamplerKind::uniform) {
    const int k = std::min(s.count, frame_count);
    for (int i = 0; i < k; ++i) {
      frames.push_back(int((2 * std::int64_t(i) + 1) * frame_count / (2 * std::int64_t(k))));
    }
    return frames;
  }
  std::mt19937_64 rng(seed);
  const int parts = std::min(s.segments, frame_count);
  for (int i = 0; i < parts; ++i) {
    const int lo = int(std::int64_t(i) * frame_count / parts);
    const int hi = int(std::int64_t(i + 1) * frame_count / parts);
    const int starts = std::max(1, hi - lo - s.run + 1);
    const int start = lo + int(detail::draw_below(rng, std::uint64_t(starts)));
    for (int f = start; f < std::min(hi, start + s.run); ++f) frames.push_back(f);
  }
  return frames;
}

}  // namespace vkjr2::jr2
