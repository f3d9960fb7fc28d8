#version 450
// conv2d backward-data, any parameters: one dx element per invocation,
// gathering dy[oy, ox] where oy·sy − pt + ky·dy = iy (and the same for x).
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer dy_out;  // [n, cout, hout, wout]
layout(binding = 1) uniform samplerBuffer weight;  // [cout, cin_g, kh, kw]
layout(std430, binding = 2) writeonly buffer DX { float dx_in[]; };

void main() {
  const uint i = linear_group() * 256u + gl_LocalInvocationID.x;
  if (i >= pc.n * pc.cin * pc.h * pc.w) return;
  const uint ix = i % pc.w;
  uint t = i / pc.w;
  const uint iy = t % pc.h;
  t /= pc.h;
  const uint ci = t % pc.cin;
  const uint n = t / pc.cin;
  const uint g = ci / pc.cin_g;
  const uint c = ci % pc.cin_g;
  float acc = 0.0;
  for (uint k = 0u; k < pc.cout_g; ++k) {
    const uint co = g * pc.cout_g + k;
    const uint plane = (n * pc.cout + co) * pc.hout;
    const uint wbase = (co * pc.cin_g + c) * pc.kh * pc.kw;
    for (uint ky = 0u; ky < pc.kh; ++ky) {
      const int ty = int(iy) + pc.pt - int(ky * pc.dy);
      if (ty < 0 || uint(ty) % pc.sy != 0u) continue;
      const uint oy = uint(ty) / pc.sy;
      if (oy >= pc.hout) continue;
      for (uint kx = 0u; kx < pc.kw; ++kx) {
        const int tx = int(ix) + pc.pl - int(kx * pc.dx);
        if (tx < 0 || uint(tx) % pc.sx != 0u) continue;
        const uint ox = uint(tx) / pc.sx;
        if (ox >= pc.wout) continue;
        acc = fma(texelFetch(weight, int(wbase + ky * pc.kw + kx)).r,
                  texelFetch(dy_out, int((plane + oy) * pc.wout + ox)).r, acc);
      }
    }
  }
  dx_in[i] = acc;
}
