#version 450
// SSIM pass 1 (Wang et al. 2004): horizontal 11-tap Gaussian over the valid
// columns of x, y, x^2, y^2 and x*y, stored interleaved so that pass 2 reads
// them with one vec4 and one scalar gather: t4 = (x, y, x^2, y^2), t1 = x*y,
// each [planes][H][W-10]. Each invocation computes 8 consecutive output
// columns of one row (18 taps of x and y).
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(binding = 1) uniform samplerBuffer y;
layout(std430, binding = 2) writeonly buffer T4 { vec4 t4[]; };
layout(std430, binding = 3) writeonly buffer T1 { float t1[]; };
layout(push_constant) uniform Push {
  uint planes; uint channels; int h; int w; float c1; float c2; float g[11];
} pc;

void main() {
  const int wv = pc.w - 10;
  const uint blocks = (uint(wv) + 7u) / 8u;
  const uint item = linear_group() * 256u + gl_LocalInvocationID.x;
  if (item >= pc.planes * uint(pc.h) * blocks) return;
  const int j0 = int(item % blocks) * 8;
  const uint row = item / blocks;  // plane * H + i
  float xs[18], ys[18];
  [[unroll]] for (int k = 0; k < 18; ++k) {
    const int c = min(j0 + k, pc.w - 1);  // taps past the edge feed no output
    xs[k] = texelFetch(x, int(row) * pc.w + c).r;
    ys[k] = texelFetch(y, int(row) * pc.w + c).r;
  }
  [[unroll]] for (int o = 0; o < 8; ++o) {
    if (j0 + o >= wv) break;
    float mx = 0.0, my = 0.0, xx = 0.0, yy = 0.0, xy = 0.0;
    [[unroll]] for (int k = 0; k < 11; ++k) {
      const float a = xs[o + k], b = ys[o + k], g = pc.g[k];
      mx += g * a;
      my += g * b;
      xx += g * a * a;
      yy += g * b * b;
      xy += g * a * b;
    }
    const uint d = row * uint(wv) + uint(j0 + o);
    t4[d] = vec4(mx, my, xx, yy);
    t1[d] = xy;
  }
}
