#version 450
// Pixel shuffle (PyTorch's PixelShuffle / PixelUnshuffle) with factor R:
//   big[n, c, h*R + i, w*R + j] = small[n, c*R*R + i*R + j, h, w],
// big: [N, C, H*R, W*R], small: [N, C*R*R, H, W]. UNSHUFFLE = 0 reads small
// and writes big (shuffle), 1 reads big and writes small (unshuffle); each is
// the other's backward.
// VEC4 = 0: one element per invocation; grid over big: x = LANES-column
// chunks of a row, y = row, z = plane n*C + c, so the only divisions are by
// the constant R.
// VEC4 = 1 (W a multiple of 4, R <= 4, both tensors 16-byte aligned): one
// invocation moves a quad of small pixels in all R*R phases, R*R vec4 texel
// reads and R*R vec4 stores (llvmpipe runs scalar loads and stores lane by
// lane); grid: x = quads of one plane's H * W/4 (row by fast_div), z = plane.
#include "common.glsl"
layout(local_size_x_id = 3) in;
layout(constant_id = 0) const uint R = 2u;
layout(constant_id = 1) const uint UNSHUFFLE = 0u;
layout(constant_id = 2) const uint VEC4 = 0u;
layout(constant_id = 3) const uint LANES = 256u;
layout(binding = 0) uniform samplerBuffer src;  // R32F; RGBA32F when VEC4
layout(std430, binding = 1) writeonly buffer Dst { float dst[]; };
layout(std430, binding = 1) writeonly buffer Dst4 { vec4 dst4[]; };
layout(push_constant) uniform Push {
  uint h;  // small's H and W
  uint w;
  uvec2 quads_magic;  // VEC4: fast_div by W/4
} pc;

void scalar_path() {
  const uint bw = pc.w * R;
  const uint ox = gl_WorkGroupID.x * LANES + gl_LocalInvocationID.x;
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

void vec4_path() {
  const uint quads = pc.w / 4u;
  const uint idx = gl_WorkGroupID.x * LANES + gl_LocalInvocationID.x;
  if (idx >= pc.h * quads) return;
  const uint y = fast_div(idx, pc.quads_magic);
  const uint q = idx - y * quads;
  const uint plane = gl_WorkGroupID.z;
  const uint hw4 = pc.h * quads;  // one small plane, in vec4
  // In vec4 units: small (plane·R² + i·R + j, y, q); big row y·R + i, quads q·R ...
  const uint small0 = plane * R * R * hw4 + y * quads + q;
  const uint big0 = (plane * pc.h * R + y * R) * quads * R + q * R;
  [[unroll]] for (uint i = 0u; i < R; ++i) {
    float seg[4u * R];  // the big row's 4·R values: seg[p·R + j] = small phase (i, j), pixel p
    const uint big_row = big0 + i * quads * R;
    if (UNSHUFFLE == 0u) {
      [[unroll]] for (uint j = 0u; j < R; ++j) {
        const vec4 a = texelFetch(src, int(small0 + (i * R + j) * hw4));
        [[unroll]] for (uint p = 0u; p < 4u; ++p) seg[p * R + j] = a[p];
      }
      [[unroll]] for (uint k = 0u; k < R; ++k) {
        dst4[big_row + k] = vec4(seg[4u * k], seg[4u * k + 1u], seg[4u * k + 2u], seg[4u * k + 3u]);
      }
    } else {
      [[unroll]] for (uint k = 0u; k < R; ++k) {
        const vec4 a = texelFetch(src, int(big_row + k));
        [[unroll]] for (uint e = 0u; e < 4u; ++e) seg[4u * k + e] = a[e];
      }
      [[unroll]] for (uint j = 0u; j < R; ++j) {
        dst4[small0 + (i * R + j) * hw4] =
            vec4(seg[j], seg[R + j], seg[2u * R + j], seg[3u * R + j]);
      }
    }
  }
}

void main() {
  if (VEC4 != 0u) {
    vec4_path();
  } else {
    scalar_path();
  }
}
