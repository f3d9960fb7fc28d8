#version 450
// SSIM pass 2 (Wang et al. 2004, eq. 13): vertical 11-tap Gaussian of the
// five pass-1 maps gives mu_x, mu_y, E[x^2], E[y^2], E[xy] on the valid
// region; then
//   MODE 0: map = (2 mx my + C1)(2 sxy + C2) / ((mx^2 + my^2 + C1)(sxx + syy + C2));
//   MODE 1: the terms of the gradient w.r.t. x, scaled by dL/dssim[n] / M
//           (M = C * H' * W'), interleaved as one vec4 per pixel
//           (ds/dmx - 2 mx ds/dsxx - my ds/dsxy, ds/dsxx, ds/dsxy, 0),
//           [planes][H'][W'].
// Each invocation computes 8 consecutive rows of one column (18 taps).
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint MODE = 0u;
layout(binding = 0) uniform samplerBuffer t4;      // RGBA32F: (x, y, x^2, y^2)
layout(binding = 1) uniform samplerBuffer t1;      // x*y
layout(binding = 2) uniform samplerBuffer d_ssim;  // [N]; MODE 1 only
layout(std430, binding = 3) writeonly buffer Map { float map[]; };      // MODE 0
layout(std430, binding = 3) writeonly buffer Terms { vec4 terms[]; };  // MODE 1
layout(push_constant) uniform Push {
  uint planes; uint channels; int h; int w; float c1; float c2; float g[11];
} pc;

void main() {
  const int hv = pc.h - 10, wv = pc.w - 10;
  const uint blocks = (uint(hv) + 7u) / 8u;
  const uint item = linear_group() * 256u + gl_LocalInvocationID.x;
  if (item >= pc.planes * blocks * uint(wv)) return;
  const int j = int(item % uint(wv));
  const uint rest = item / uint(wv);
  const int i0 = int(rest % blocks) * 8;
  const uint plane = rest / blocks;
  float scale = 0.0;
  if (MODE == 1u) {
    scale = texelFetch(d_ssim, int(plane / pc.channels)).r / float(pc.channels * uint(hv * wv));
  }
  float acc[8][5];
  [[unroll]] for (int o = 0; o < 8; ++o) {
    [[unroll]] for (int m = 0; m < 5; ++m) acc[o][m] = 0.0;
  }
  [[unroll]] for (int k = 0; k < 18; ++k) {
    const int r = min(i0 + k, pc.h - 1);  // rows past the edge feed no output
    const uint src = (plane * uint(pc.h) + uint(r)) * uint(wv) + uint(j);
    const vec4 v4 = texelFetch(t4, int(src));
    const float v[5] = float[5](v4.x, v4.y, v4.z, v4.w, texelFetch(t1, int(src)).r);
    [[unroll]] for (int o = 0; o < 8; ++o) {
      const int tap = k - o;
      if (tap >= 0 && tap < 11) {
        [[unroll]] for (int m = 0; m < 5; ++m) acc[o][m] += pc.g[tap] * v[m];
      }
    }
  }
  [[unroll]] for (int o = 0; o < 8; ++o) {
    const int i = i0 + o;
    if (i >= hv) break;
    const float mx = acc[o][0], my = acc[o][1];
    const float sxx = acc[o][2] - mx * mx, syy = acc[o][3] - my * my, sxy = acc[o][4] - mx * my;
    const float a1 = 2.0 * mx * my + pc.c1, a2 = 2.0 * sxy + pc.c2;
    const float b1 = mx * mx + my * my + pc.c1, b2 = sxx + syy + pc.c2;
    const uint d = (plane * uint(hv) + uint(i)) * uint(wv) + uint(j);
    if (MODE == 0u) {
      map[d] = (a1 * a2) / (b1 * b2);
    } else {
      const float inv = 1.0 / (b1 * b2);
      const float s = a1 * a2 * inv;
      const float ds_dmx = 2.0 * a2 * inv * (my - mx * a1 / b1);
      const float ds_dsxx = -s / b2;
      const float ds_dsxy = 2.0 * a1 * inv;
      terms[d] = scale * vec4(ds_dmx - 2.0 * mx * ds_dsxx - my * ds_dsxy, ds_dsxx, ds_dsxy, 0.0);
    }
  }
}
