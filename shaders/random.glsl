// Counter-based random numbers shared by shaders (kernels/random.hpp has the
// contract; kernels/ref/random_ref.cpp is the same arithmetic in C++).
#ifndef VKJR2_RANDOM_GLSL
#define VKJR2_RANDOM_GLSL

// pcg4d (Jarzynski & Olano, "Hash Functions for GPU Rendering", JCGT 2020).
uvec4 pcg4d(uvec4 v) {
  v = v * 1664525u + 1013904223u;
  v.x += v.y * v.w;
  v.y += v.z * v.x;
  v.z += v.x * v.y;
  v.w += v.y * v.z;
  v ^= v >> 16u;
  v.x += v.y * v.w;
  v.y += v.z * v.x;
  v.z += v.x * v.y;
  v.w += v.y * v.z;
  return v;
}

// sin and cos of 2π·t for t in [0, 1), by quadrant reduction and Taylor
// polynomials on [−π/4, π/4] (|error| < 4e-8; the driver's sin/cos can be
// 1e-4 off on lavapipe).
vec2 sincos_2pi(float t) {
  const float q = floor(t * 4.0 + 0.5);       // nearest quadrant 0..4
  const float r = (t - q * 0.25) * 6.2831853;  // in [−π/4, π/4]
  const float r2 = r * r;
  const float s = r * (1.0 + r2 * (-1.0 / 6.0 + r2 * (1.0 / 120.0 + r2 * (-1.0 / 5040.0 + r2 * (1.0 / 362880.0)))));
  const float c = 1.0 + r2 * (-0.5 + r2 * (1.0 / 24.0 + r2 * (-1.0 / 720.0 + r2 * (1.0 / 40320.0))));
  const uint quadrant = uint(q) & 3u;
  if (quadrant == 0u) return vec2(s, c);
  if (quadrant == 1u) return vec2(c, -s);
  if (quadrant == 2u) return vec2(-s, -c);
  return vec2(-c, s);
}

// −2 ln u for u in (0, 1]. Near 1 the driver's log loses all relative
// precision (lavapipe: 1e-4 absolute in a normal), so there ln u =
// 2 atanh(z), z = (u − 1)/(u + 1) in [−1/3, 0], summed to z^15 (< 2e-9).
float neg2log(float u) {
  if (u <= 0.5) return -2.0 * log(u);
  const float z = (u - 1.0) / (u + 1.0);
  const float z2 = z * z;
  const float series = 1.0 + z2 * (1.0 / 3.0 + z2 * (1.0 / 5.0 + z2 * (1.0 / 7.0 + z2 * (1.0 / 9.0 + z2 * (1.0 / 11.0 + z2 * (1.0 / 13.0 + z2 * (1.0 / 15.0)))))));
  return -4.0 * z * series;
}

// Four standard normals from one hash: two Box–Muller pairs. u1 in (0, 1]
// (24 bits, never 0), t in [0, 1).
vec4 gaussian4(uvec4 key) {
  const uvec4 h = pcg4d(key);
  const vec4 u = vec4(h >> 8u) * (1.0 / 16777216.0);
  const float r0 = sqrt(neg2log(u.x + 1.0 / 16777216.0));
  const float r1 = sqrt(neg2log(u.z + 1.0 / 16777216.0));
  const vec2 sc0 = sincos_2pi(u.y);
  const vec2 sc1 = sincos_2pi(u.w);
  return vec4(r0 * sc0.y, r0 * sc0.x, r1 * sc1.y, r1 * sc1.x);
}

#endif
