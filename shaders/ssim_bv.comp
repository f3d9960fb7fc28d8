#version 450
// SSIM backward pass 2: the transpose of the vertical valid Gaussian of the
// vec4 maps of ssim_bh, combined into the gradient w.r.t. x:
//   dx = G'a + 2 x G'b + y G'c   (a, b, c: the ssim_v MODE 1 terms).
// Each invocation computes 4 consecutive rows of one column.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer u;  // RGBA32F
layout(binding = 1) uniform samplerBuffer x;
layout(binding = 2) uniform samplerBuffer y;
layout(std430, binding = 3) writeonly buffer DX { float dx[]; };
layout(push_constant) uniform Push {
  uint planes; uint channels; int h; int w; float c1; float c2; float g[11];
} pc;

void main() {
  const int hv = pc.h - 10;
  const uint blocks = (uint(pc.h) + 3u) / 4u;
  const uint item = linear_group() * 256u + gl_LocalInvocationID.x;
  if (item >= pc.planes * blocks * uint(pc.w)) return;
  const int col = int(item % uint(pc.w));
  const uint rest = item / uint(pc.w);
  const int y0 = int(rest % blocks) * 4;
  const uint plane = rest / blocks;
  vec4 acc[4] = vec4[4](vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0));
  [[unroll]] for (int k = 0; k < 14; ++k) {
    const int r = y0 - 10 + k;  // u row, zero outside [0, H')
    const uint src = (plane * uint(hv) + uint(clamp(r, 0, hv - 1))) * uint(pc.w) + uint(col);
    const vec4 f = r >= 0 && r < hv ? texelFetch(u, int(src)) : vec4(0.0);
    [[unroll]] for (int o = 0; o < 4; ++o) {
      const int tap = o + 10 - k;  // row y0 + o takes u[y0 + o - tap]
      if (tap >= 0 && tap < 11) acc[o] += pc.g[tap] * f;
    }
  }
  [[unroll]] for (int o = 0; o < 4; ++o) {
    const int r = y0 + o;
    if (r >= pc.h) break;
    const int i = int(plane * uint(pc.h) + uint(r)) * pc.w + col;
    dx[i] = acc[o].x + 2.0 * texelFetch(x, i).r * acc[o].y + texelFetch(y, i).r * acc[o].z;
  }
}
