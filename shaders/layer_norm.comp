#version 450
// Layer norm over the channels of each pixel (NAFNet's LayerNorm2d) on NCHW:
//   mu = mean_c x, var = mean_c (x - mu)^2, xhat = (x - mu) / sqrt(var + eps),
//   forward  (GRAD = 0): y[c] = gamma[c] * xhat[c] + beta[c];
//   backward (GRAD = 1): g[c] = dy[c] * gamma[c],
//                        dx[c] = (g[c] - mean_c g - xhat[c] * mean_c(g * xhat)) / sqrt(var + eps),
//                        and xhat is written for the parameter gradients.
// One invocation per pixel, the channel loop inside (reads stride H*W apart
// through texel buffers); grid: x = 256-pixel chunks of one image, y = image.
// mu and var come from two passes over the channels (no E[x^2] - mu^2
// cancellation).
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint GRAD = 0u;
layout(binding = 0) uniform samplerBuffer x;
layout(binding = 1) uniform samplerBuffer gamma;
layout(binding = 2) uniform samplerBuffer beta_or_dy;  // beta (forward) or dy (backward)
layout(std430, binding = 3) writeonly buffer Y { float y[]; };        // y or dx
layout(std430, binding = 4) writeonly buffer Xhat { float xhat[]; };  // backward only
layout(push_constant) uniform Push { uint hw; uint channels; float eps; } pc;

void main() {
  const uint p = gl_WorkGroupID.x * 256u + gl_LocalInvocationID.x;
  if (p >= pc.hw) return;
  const uint base = gl_WorkGroupID.y * pc.channels * pc.hw + p;
  const float inv_c = 1.0 / float(pc.channels);
  float sum = 0.0;
  for (uint c = 0u; c < pc.channels; ++c) sum += texelFetch(x, int(base + c * pc.hw)).r;
  const float mu = sum * inv_c;
  float sq = 0.0;
  for (uint c = 0u; c < pc.channels; ++c) {
    const float d = texelFetch(x, int(base + c * pc.hw)).r - mu;
    sq = fma(d, d, sq);
  }
  const float rstd = inversesqrt(sq * inv_c + pc.eps);
  if (GRAD == 0u) {
    for (uint c = 0u; c < pc.channels; ++c) {
      const uint i = base + c * pc.hw;
      const float xh = (texelFetch(x, int(i)).r - mu) * rstd;
      y[i] = fma(texelFetch(gamma, int(c)).r, xh, texelFetch(beta_or_dy, int(c)).r);
    }
    return;
  }
  float mean_g = 0.0, mean_gx = 0.0;
  for (uint c = 0u; c < pc.channels; ++c) {
    const uint i = base + c * pc.hw;
    const float xh = (texelFetch(x, int(i)).r - mu) * rstd;
    const float g = texelFetch(beta_or_dy, int(i)).r * texelFetch(gamma, int(c)).r;
    mean_g += g;
    mean_gx = fma(g, xh, mean_gx);
  }
  mean_g *= inv_c;
  mean_gx *= inv_c;
  for (uint c = 0u; c < pc.channels; ++c) {
    const uint i = base + c * pc.hw;
    const float xh = (texelFetch(x, int(i)).r - mu) * rstd;
    const float g = texelFetch(beta_or_dy, int(i)).r * texelFetch(gamma, int(c)).r;
    y[i] = (g - mean_g - xh * mean_gx) * rstd;
    xhat[i] = xh;
  }
}
