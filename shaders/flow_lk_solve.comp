#version 450
// Lucas–Kanade update (kernels/flow.cpp): from the window means of the five
// terms (N×5×H×W: ⟨gx²⟩, ⟨gx·gy⟩, ⟨gy²⟩, ⟨gx·e⟩, ⟨gy·e⟩), the Gauss–Newton
// step flow_out = flow_in − S⁻¹ b where the smaller eigenvalue of S reaches
// the threshold, and that eigenvalue. One pixel per invocation.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer sums;     // N×5×H×W
layout(binding = 1) uniform samplerBuffer flow_in;  // N×2×H×W
layout(std430, binding = 2) writeonly buffer FlowOut { float flow_out[]; };
layout(std430, binding = 3) writeonly buffer MinEig { float min_eig[]; };
layout(push_constant) uniform Push {
  uint n; uint plane; float min_eigenvalue; uint pad0;
  uvec2 plane_magic;
} pc;

void main() {
  const uint item = linear_group() * 256u + gl_LocalInvocationID.x;
  if (item >= pc.n * pc.plane) return;
  const uint b = fast_div(item, pc.plane_magic);
  const uint p = item - b * pc.plane;
  const int s = int(b * 5u * pc.plane + p);
  const int stride = int(pc.plane);
  const float a = texelFetch(sums, s).r;
  const float c = texelFetch(sums, s + stride).r;
  const float d = texelFetch(sums, s + 2 * stride).r;
  const float bx = texelFetch(sums, s + 3 * stride).r;
  const float by = texelFetch(sums, s + 4 * stride).r;
  const float half_diff = 0.5 * (a - d);
  const float lmin = 0.5 * (a + d) - sqrt(half_diff * half_diff + c * c);
  const uint f = 2u * b * pc.plane + p;
  float dx = texelFetch(flow_in, int(f)).r;
  float dy = texelFetch(flow_in, int(f + pc.plane)).r;
  if (lmin >= pc.min_eigenvalue) {
    const float inv_det = 1.0 / (a * d - c * c);
    dx -= (d * bx - c * by) * inv_det;
    dy -= (a * by - c * bx) * inv_det;
  }
  flow_out[f] = dx;
  flow_out[f + pc.plane] = dy;
  min_eig[item] = lmin;
}
