#version 450
// Bilinear resampling forward: out[n, c, p] = bilinear(img[n, c], pos(n, p)),
// for warp (pixel displacements) and grid_sample (normalized grid); see
// warp_sampling.glsl. One invocation per output pixel, all channels: the
// position and taps are computed once and reused for every channel.
#include "warp_sampling.glsl"
layout(local_size_x = 128) in;
layout(binding = 0) uniform samplerBuffer img;     // N×C×in_h×in_w, R32F
layout(binding = 1) uniform samplerBuffer coords;  // flow (R32F) or grid (RG32F)
layout(std430, binding = 2) writeonly buffer Out { float out_values[]; };

void main() {
  const uint plane_out = pc.out_h * pc.out_w;
  const uint gid = linear_group() * 128u + gl_LocalInvocationID.x;
  if (gid >= pc.n_batch * plane_out) return;
  const uint n = gid / plane_out, p = gid % plane_out;
  vec2 dpos;
  const vec2 pos = sample_position(coords, n, p, dpos);
  const Taps t = make_taps(pos, dpos);
  const uint plane_in = pc.in_h * pc.in_w;
  const uint c_total = pc.channels;
  uint in_base = n * c_total * plane_in;
  uint out_index = n * c_total * plane_out + p;
  uint c = 0u;
  for (; c + 4u <= c_total; c += 4u) {
    [[unroll]] for (uint k = 0u; k < 4u; ++k) {
      const float v = interpolate(fetch_taps(img, int(in_base), t), t);
      out_values[out_index] = t.finite ? v : kNaN;
      in_base += plane_in;
      out_index += plane_out;
    }
  }
  for (; c < c_total; ++c) {
    const float v = interpolate(fetch_taps(img, int(in_base), t), t);
    out_values[out_index] = t.finite ? v : kNaN;
    in_base += plane_in;
    out_index += plane_out;
  }
}
