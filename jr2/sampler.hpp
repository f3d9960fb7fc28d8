// Which frames of a probe video the recognition pipeline looks at.
//
// The JR² paper's sampler (segments): the video is cut into `segments` equal
// parts and, in each, a run of `run` consecutive frames starts at a seeded
// random position: 30 frames → 4 segments × 2 = 8 frames. Also the uniform
// choice of `count` frames and all frames.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace vkjr2::jr2 {

enum class SamplerKind : std::uint8_t { segments, uniform, all };

struct FrameSampler {
  SamplerKind kind = SamplerKind::segments;
  int segments = 4;  // segments: how many parts
  int run = 2;       // segments: consecutive frames per part
  int count = 8;     // uniform: how many frames
};

// "segments:4x2", "uniform:8", "all" (the --frames syntax of vkjr2 eval).
FrameSampler parse_frame_sampler(const std::string& text);
std::string to_string(const FrameSampler& sampler);

// The chosen frame indices of a video of frame_count frames, ascending and
// distinct. Segments: part i covers [⌊i·F/S⌋, ⌊(i+1)·F/S⌋); a part shorter
// than `run` gives all its frames. Uniform: frame ⌊(i + ½)·F/K⌋ for
// i < K (all frames when F ≤ K). The same seed gives the same frames.
// Throws InvalidArgument for frame_count < 1 or a sampler with a count,
// segment or run below 1.
std::vector<int> sample_frames(int frame_count, const FrameSampler& sampler, std::uint64_t seed);

}  // namespace vkjr2::jr2
