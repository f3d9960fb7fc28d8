#version 450
// AdaFace margin scaler (Kim et al. 2022, kernels/adaface.hpp), one workgroup:
//   n_b = clip(norm_b, 0.001, 100)
//   UPDATE: μ ← α·mean(n) + (1 − α)·μ, σ ← α·std(n) + (1 − α)·σ (unbiased std)
//   scaler_b = clip(h·(n_b − μ)/(σ + eps), −1, 1)
// B is a batch size (small): one group of 64 strides over it; sums are a
// fixed shared-memory tree (deterministic), two passes for the variance.
#include "common.glsl"
layout(local_size_x = 64) in;
layout(binding = 0) uniform samplerBuffer norms;
layout(std430, binding = 1) buffer RunningMean { float running_mean; };
layout(std430, binding = 2) buffer RunningStd { float running_std; };
layout(std430, binding = 3) writeonly buffer Scaler { float scaler[]; };
layout(push_constant) uniform Push {
  uint rows;
  uint update;
  float h;
  float eps;
  float alpha;
} pc;

shared float part[64];
shared float stats[2];

// NaN passes through (clamp of NaN is undefined in SPIR-V).
float safe_norm(uint i) {
  const float x = texelFetch(norms, int(i)).r;
  return isnan(x) ? x : clamp(x, 0.001, 100.0);
}

float workgroup_sum(float v) {
  const uint lid = gl_LocalInvocationID.x;
  part[lid] = v;
  barrier();
  [[unroll]] for (uint half_size = 32u; half_size > 0u; half_size >>= 1u) {
    if (lid < half_size) part[lid] += part[lid + half_size];
    barrier();
  }
  const float total = part[0];
  barrier();
  return total;
}

void main() {
  const uint lid = gl_LocalInvocationID.x;
  if (pc.update != 0u) {
    float s = 0.0;
    for (uint i = lid; i < pc.rows; i += 64u) s += safe_norm(i);
    const float mean = workgroup_sum(s) / float(pc.rows);
    float ss = 0.0;
    for (uint i = lid; i < pc.rows; i += 64u) {
      const float d = safe_norm(i) - mean;
      ss += d * d;
    }
    const float std_dev = sqrt(workgroup_sum(ss) / float(pc.rows - 1u));
    // Only invocation 0 touches the running statistics: no race on them.
    if (lid == 0u) {
      const float mu = pc.alpha * mean + (1.0 - pc.alpha) * running_mean;
      const float sigma = pc.alpha * std_dev + (1.0 - pc.alpha) * running_std;
      running_mean = mu;
      running_std = sigma;
      stats[0] = mu;
      stats[1] = sigma;
    }
  } else if (lid == 0u) {
    stats[0] = running_mean;
    stats[1] = running_std;
  }
  barrier();
  const float mu = stats[0];
  const float inv = pc.h / (stats[1] + pc.eps);
  for (uint i = lid; i < pc.rows; i += 64u) {
    const float z = (safe_norm(i) - mu) * inv;
    scaler[i] = isnan(z) ? z : clamp(z, -1.0, 1.0);
  }
}
