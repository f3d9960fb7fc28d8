#version 450
// Lucas–Kanade terms (kernels/flow.cpp): for every pixel, the reference's
// gradient g (central differences, the border row repeated) and the
// residual e = warped − ref, written as the planes gx², gx·gy, gy², gx·e,
// gy·e of an N×5×H×W tensor; zero where x + flow(x) lies outside the image
// (the warped value there is a clamped guess). One pixel per invocation.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer ref;     // R×H×W, R = 1 or N
layout(binding = 1) uniform samplerBuffer warped;  // N×H×W: img(x + flow(x))
layout(binding = 2) uniform samplerBuffer flow;    // N×2×H×W
layout(std430, binding = 3) writeonly buffer Terms { float terms[]; };
layout(push_constant) uniform Push {
  uint n; int h; int w; uint ref_per_image;
  uvec2 plane_magic; uvec2 row_magic;  // divisors h·w and w
} pc;

void main() {
  const uint plane = uint(pc.h * pc.w);
  const uint item = linear_group() * 256u + gl_LocalInvocationID.x;
  if (item >= pc.n * plane) return;
  const uint b = fast_div(item, pc.plane_magic);
  const uint p = item - b * plane;
  const int y = int(fast_div(p, pc.row_magic));
  const int x = int(p) - y * pc.w;
  const int base = pc.ref_per_image != 0u ? int(b * plane) : 0;
  const int row = base + y * pc.w;
  const float r = texelFetch(ref, row + x).r;
  const float gx = 0.5 * (texelFetch(ref, row + min(x + 1, pc.w - 1)).r -
                          texelFetch(ref, row + max(x - 1, 0)).r);
  const float gy = 0.5 * (texelFetch(ref, base + min(y + 1, pc.h - 1) * pc.w + x).r -
                          texelFetch(ref, base + max(y - 1, 0) * pc.w + x).r);
  const float e = texelFetch(warped, int(item)).r - r;
  const vec2 pos = vec2(float(x) + texelFetch(flow, int(2u * b * plane + p)).r,
                        float(y) + texelFetch(flow, int((2u * b + 1u) * plane + p)).r);
  // NaN compares false: a non-finite position counts as outside.
  const bool inside = pos.x >= 0.0 && pos.x <= float(pc.w - 1) && pos.y >= 0.0 &&
                      pos.y <= float(pc.h - 1);
  const float m = inside ? 1.0 : 0.0;
  const uint o = b * 5u * plane + p;
  terms[o] = m * gx * gx;
  terms[o + plane] = m * gx * gy;
  terms[o + 2u * plane] = m * gy * gy;
  terms[o + 3u * plane] = inside ? gx * e : 0.0;
  terms[o + 4u * plane] = inside ? gy * e : 0.0;
}
