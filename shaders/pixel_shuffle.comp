#version 450
// Pixel shuffle (PyTorch's PixelShuffle / PixelUnshuffle) with factor R:
//   big[n, c, h*R + i, w*R + j] = small[n, c*R*R + i*R + j, h, w],
// big: [N, C, H*R, W*R], small: [N, C*R*R, H, W]. UNSHUFFLE = 0 reads small
// and writes big (shuffle), 1 reads big and writes small (unshuffle); each is
// the other's backward. Grid over big: x = 256-column chunks of a row, y =
// row, z = plane n*C + c, so the only divisions are by the constant R.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint R = 2u;
layout(constant_id = 1) const uint UNSHUFFLE = 0u;
layout(binding = 0) uniform samplerBuffer src;
layout(std430, binding = 1) writeonly buffer Dst { float dst[]; };
layout(push_constant) uniform Push { uint h; uint w; } pc;  // small's H and W

void main() {
  const uint bw = pc.w * R;
  const uint ox = gl_WorkGroupID.x * 256u + gl_LocalInvocationID.x;
  if (ox >= bw) return;
  const uint oy = gl_WorkGroupID.y, plane = gl_WorkGroupID.z;
  const uint i = oy % R, j = ox % R;
  const uint big = (plane * pc.h * R + oy) * bw + ox;
  const uint small = ((plane * R + i) * R + j) * pc.h * pc.w + (oy / R) * pc.w + ox / R;
  if (UNSHUFFLE == 0u) {
    dst[big] = texelFetch(src, int(small)).r;
  } else {
    dst[small] = texelFetch(src, int(big)).r;
  }
}
