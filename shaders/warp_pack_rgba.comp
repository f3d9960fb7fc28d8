#version 450
// N×C×H×W → N×G×H×W×4 with G = ceil(C / 4): every pixel's channels 4g..4g+3
// in one RGBA texel (missing channels 0), so that warp_sample_rgba reads one
// texel per bilinear tap for four channels (LAVAPIPE.md: 44–58 Mpix/s vs
// 28 one channel at a time). Grid: x over pixels (QUADS: 4 pixels per
// invocation, read as one RGBA texel per channel), y = n·G + g; no integer
// division per invocation (scalarized on llvmpipe).
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const bool QUADS = false;  // plane % 4 == 0: img bound as RGBA32F
layout(binding = 0) uniform samplerBuffer img;     // N×C×H×W, R32F (QUADS: RGBA32F)
layout(std430, binding = 1) writeonly buffer Out { vec4 packed_rgba[]; };
layout(push_constant) uniform Push {
  uint n_batch;
  uint channels;
  uint plane;   // H·W
  uint groups;  // G
} pc;

void main() {
  const uint ng = gl_WorkGroupID.y;  // uniform over the workgroup
  const uint g = ng % pc.groups, n = ng / pc.groups;
  const uint c0 = 4u * g;
  const uint i = gl_GlobalInvocationID.x;
  const bool c1 = c0 + 1u < pc.channels, c2 = c0 + 2u < pc.channels, c3 = c0 + 3u < pc.channels;
  if (QUADS) {
    const uint quads = pc.plane / 4u;
    if (i >= quads) return;
    const int step = int(quads);
    const int base = int((n * pc.channels + c0) * quads + i);
    const vec4 r = texelFetch(img, base);
    const vec4 gg = c1 ? texelFetch(img, base + step) : vec4(0.0);
    const vec4 b = c2 ? texelFetch(img, base + 2 * step) : vec4(0.0);
    const vec4 a = c3 ? texelFetch(img, base + 3 * step) : vec4(0.0);
    const uint o = ng * pc.plane + 4u * i;
    packed_rgba[o] = vec4(r.x, gg.x, b.x, a.x);
    packed_rgba[o + 1u] = vec4(r.y, gg.y, b.y, a.y);
    packed_rgba[o + 2u] = vec4(r.z, gg.z, b.z, a.z);
    packed_rgba[o + 3u] = vec4(r.w, gg.w, b.w, a.w);
  } else {
    if (i >= pc.plane) return;
    const int step = int(pc.plane);
    const int base = int((n * pc.channels + c0) * pc.plane + i);
    vec4 v = vec4(0.0);
    v.x = texelFetch(img, base).r;
    if (c1) v.y = texelFetch(img, base + step).r;
    if (c2) v.z = texelFetch(img, base + 2 * step).r;
    if (c3) v.w = texelFetch(img, base + 3 * step).r;
    packed_rgba[ng * pc.plane + i] = v;
  }
}
