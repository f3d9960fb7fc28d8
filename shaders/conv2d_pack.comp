#version 450
// Repacks OIHW weights [cout, cin, kh, kw] (groups == 1) into blocks of 8
// output channels: packed[cout/8][cin][kh][kw][8], zero for channels ≥ cout,
// so the blocked and pointwise kernels read 8 channels as two vec4 texels.
// TRANSPOSED: the source is the weight of the forward conv whose backward-data
// this is, [cin][cout][kh][kw], spatially flipped (dX = conv(dY, flip(Wᵀ))).
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint TRANSPOSED = 0u;
layout(binding = 0) uniform samplerBuffer weight;
layout(std430, binding = 1) writeonly buffer Packed { float packed[]; };

void main() {
  const uint taps = pc.kh * pc.kw;
  const uint total = ((pc.cout + 7u) / 8u) * pc.cin * taps * 8u;
  const uint i = linear_group() * 256u + gl_LocalInvocationID.x;
  if (i >= total) return;
  const uint j = i % 8u;
  uint t = i / 8u;
  const uint tap = t % taps;
  t /= taps;
  const uint c = t % pc.cin;
  const uint co = (t / pc.cin) * 8u + j;
  float v = 0.0;
  if (co < pc.cout) {
    const uint src = TRANSPOSED != 0u ? (c * pc.cout + co) * taps + (taps - 1u - tap)
                                      : (co * pc.cin + c) * taps + tap;
    v = texelFetch(weight, int(src)).r;
  }
  packed[i] = v;
}
