#version 450
// conv2d forward, any parameters: one output element per invocation, bounds
// checked. The fallback; conv2d_blocked/pointwise/depthwise are the fast paths.
#define CONV2D_RESIDUAL
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(binding = 1) uniform samplerBuffer weight;  // [cout, cin_g, kh, kw]
layout(binding = 2) uniform samplerBuffer bias;
layout(std430, binding = 3) writeonly buffer Y { float y[]; };

void main() {
  const uint i = linear_group() * 256u + gl_LocalInvocationID.x;
  if (i >= pc.n * pc.cout * pc.hout * pc.wout) return;
  const uint ox = i % pc.wout;
  uint t = i / pc.wout;
  const uint oy = t % pc.hout;
  t /= pc.hout;
  const uint co = t % pc.cout;
  const uint n = t / pc.cout;
  const uint g = co / pc.cout_g;
  float acc = pc.has_bias != 0u ? texelFetch(bias, int(co)).r : 0.0;
  const int iy0 = int(oy * pc.sy) - pc.pt;
  const int ix0 = int(ox * pc.sx) - pc.pl;
  for (uint c = 0u; c < pc.cin_g; ++c) {
    const uint plane = (n * pc.cin + g * pc.cin_g + c) * pc.h;
    const uint wbase = (co * pc.cin_g + c) * pc.kh * pc.kw;
    for (uint ky = 0u; ky < pc.kh; ++ky) {
      const int iy = iy0 + int(ky * pc.dy);
      if (iy < 0 || iy >= int(pc.h)) continue;
      const uint row = (plane + uint(iy)) * pc.w;
      for (uint kx = 0u; kx < pc.kw; ++kx) {
        const int ix = ix0 + int(kx * pc.dx);
        if (ix < 0 || ix >= int(pc.w)) continue;
        float xv = texelFetch(x, int(row + uint(ix))).r;
        if (pc.xrelu != 0u) xv = max(xv, 0.0);
        acc = fma(texelFetch(weight, int(wbase + ky * pc.kw + kx)).r, xv, acc);
      }
    }
  }
  y[i] = conv_act(acc + conv_residual(n, co, oy * pc.wout + ox));
}
