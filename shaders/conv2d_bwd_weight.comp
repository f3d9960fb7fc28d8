#version 450
// conv2d backward-weight: one dw[co, c, ky, kx] per invocation, summing
// dy[n, co, oy, ox] · x[n, ci, oy·sy − pt + ky·dy, ox·sx − pl + kx·dx] over
// n and the (oy, ox) range whose input pixel lies inside the image.
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 64) in;
layout(binding = 0) uniform samplerBuffer x;       // [n, cin, h, w]
layout(binding = 1) uniform samplerBuffer dy_out;  // [n, cout, hout, wout]
layout(std430, binding = 2) writeonly buffer DW { float dw[]; };

// Output positions o in [lo, hi) with 0 <= o·s + off < size.
void valid_range(int off, uint s, uint size, uint count, out uint lo, out uint hi) {
  const int si = int(s);
  lo = off >= 0 ? 0u : uint((-off + si - 1) / si);
  const int last = int(size) - 1 - off;  // o·s <= last
  hi = last < 0 ? 0u : min(count, uint(last / si) + 1u);
  lo = min(lo, hi);
}

void main() {
  const uint i = linear_group() * 64u + gl_LocalInvocationID.x;
  const uint taps = pc.kh * pc.kw;
  if (i >= pc.cout * pc.cin_g * taps) return;
  const uint tap = i % taps;
  const uint ky = tap / pc.kw;
  const uint kx = tap % pc.kw;
  const uint t = i / taps;
  const uint c = t % pc.cin_g;
  const uint co = t / pc.cin_g;
  const uint ci = (co / pc.cout_g) * pc.cin_g + c;
  const int offy = int(ky * pc.dy) - pc.pt;
  const int offx = int(kx * pc.dx) - pc.pl;
  uint oy0, oy1, ox0, ox1;
  valid_range(offy, pc.sy, pc.h, pc.hout, oy0, oy1);
  valid_range(offx, pc.sx, pc.w, pc.wout, ox0, ox1);
  float acc = 0.0;
  for (uint n = 0u; n < pc.n; ++n) {
    const uint xplane = (n * pc.cin + ci) * pc.h;
    const uint yplane = (n * pc.cout + co) * pc.hout;
    for (uint oy = oy0; oy < oy1; ++oy) {
      const int xrow = int((xplane + uint(int(oy * pc.sy) + offy)) * pc.w) + offx;
      const int yrow = int((yplane + oy) * pc.wout);
      for (uint ox = ox0; ox < ox1; ++ox) {
        acc = fma(texelFetch(x, xrow + int(ox * pc.sx)).r, texelFetch(dy_out, yrow + int(ox)).r,
                  acc);
      }
    }
  }
  dw[i] = acc;
}
