#version 450
// SSIM backward pass 1: the transpose of the horizontal valid Gaussian,
// u[plane][i][x] = sum_k g[k] * v[plane][i][x - k] over 0 <= x - k < W', on
// the vec4 gradient terms of ssim_v (MODE 1). u: [planes][H'][W] vec4.
// Each invocation computes 4 consecutive columns of one row.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer v;  // RGBA32F
layout(std430, binding = 1) writeonly buffer U { vec4 u[]; };
layout(push_constant) uniform Push {
  uint planes; uint channels; int h; int w; float c1; float c2; float g[11];
} pc;

void main() {
  const int hv = pc.h - 10, wv = pc.w - 10;
  const uint blocks = (uint(pc.w) + 3u) / 4u;
  const uint item = linear_group() * 256u + gl_LocalInvocationID.x;
  if (item >= pc.planes * uint(hv) * blocks) return;
  const int x0 = int(item % blocks) * 4;
  const uint row = item / blocks;  // plane * H' + i
  vec4 vs[14];  // v columns x0 - 10 .. x0 + 3, zero outside [0, W')
  [[unroll]] for (int k = 0; k < 14; ++k) {
    const int c = x0 - 10 + k;
    const vec4 f = texelFetch(v, int(row * uint(wv)) + clamp(c, 0, wv - 1));
    vs[k] = c >= 0 && c < wv ? f : vec4(0.0);
  }
  [[unroll]] for (int o = 0; o < 4; ++o) {
    if (x0 + o >= pc.w) break;
    vec4 acc = vec4(0.0);
    // column x = x0 + o takes v[x - k] for k = 0..10, i.e. vs[o + 10 - k].
    [[unroll]] for (int k = 0; k < 11; ++k) acc += pc.g[k] * vs[o + 10 - k];
    u[row * uint(pc.w) + uint(x0 + o)] = acc;
  }
}
