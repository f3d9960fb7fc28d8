#version 450
// Bilinear resampling forward from an RGBA-packed image (warp_pack_rgba):
// as warp_sample.comp, but one texel read per tap serves four channels, and
// a grid of (row segment, row, batch) so that no invocation divides by the
// width (128×1 groups measured faster than 32×4 here).
// Output N×C×H×W.
#include "warp_sampling.glsl"
layout(local_size_x = 128, local_size_y = 1) in;
layout(binding = 0) uniform samplerBuffer img;     // N×G×in_h×in_w×4, RGBA32F
layout(binding = 1) uniform samplerBuffer coords;  // flow (R32F) or grid (RG32F)
layout(std430, binding = 2) writeonly buffer Out { float out_values[]; };

void main() {
  const uint x = gl_GlobalInvocationID.x, y = gl_GlobalInvocationID.y;
  if (x >= pc.out_w || y >= pc.out_h) return;
  const uint n = gl_WorkGroupID.z;
  const uint plane_out = pc.out_h * pc.out_w;
  const uint p = y * pc.out_w + x;
  vec2 dpos;
  vec2 pos;
  if (kGridMode == 0u) {
    const float dx = texelFetch(coords, int(2u * n * plane_out + p)).r;
    const float dy = texelFetch(coords, int((2u * n + 1u) * plane_out + p)).r;
    dpos = vec2(1.0);
    pos = vec2(float(x) + dx, float(y) + dy);
  } else {
    pos = sample_position(coords, n, p, dpos);
  }
  const Taps t = make_taps(pos, dpos);
  const uint plane_in = pc.in_h * pc.in_w;
  const uint c_total = pc.channels;
  const uint groups = (c_total + 3u) / 4u;
  int in_base = int(n * groups * plane_in);
  uint out_index = n * c_total * plane_out + p;
  for (uint c = 0u; c < c_total; c += 4u) {
    // Out-of-range taps read 0 (mix selects, so NaN in a valid tap propagates).
    const vec4 v00 = mix(vec4(0.0), texelFetch(img, in_base + t.idx.x), bvec4(t.valid.x));
    const vec4 v10 = mix(vec4(0.0), texelFetch(img, in_base + t.idx.y), bvec4(t.valid.y));
    const vec4 v01 = mix(vec4(0.0), texelFetch(img, in_base + t.idx.z), bvec4(t.valid.z));
    const vec4 v11 = mix(vec4(0.0), texelFetch(img, in_base + t.idx.w), bvec4(t.valid.w));
    vec4 v = t.wy0 * (t.wx0 * v00 + t.wx1 * v10) + t.wy1 * (t.wx0 * v01 + t.wx1 * v11);
    v = t.finite ? v : vec4(kNaN);
    const uint left = c_total - c;
    out_values[out_index] = v.x;
    if (left > 1u) out_values[out_index + plane_out] = v.y;
    if (left > 2u) out_values[out_index + 2u * plane_out] = v.z;
    if (left > 3u) out_values[out_index + 3u * plane_out] = v.w;
    in_base += int(plane_in);
    out_index += 4u * plane_out;
  }
}
