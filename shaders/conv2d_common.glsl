// Shared by the conv2d*.comp shaders: the push constants (mirror of
// ConvPush in kernels/conv2d.cpp) and the fused activation.
#ifndef VKJR2_CONV2D_COMMON_GLSL
#define VKJR2_CONV2D_COMMON_GLSL

layout(push_constant) uniform Push {
  uint n, cin, h, w;          // input [n, cin, h, w]
  uint cout, hout, wout, kh;  // output [n, cout, hout, wout]; kernel kh × kw
  uint kw, sy, sx, dy;        // stride (sy, sx), dilation (dy, dx)
  uint dx;
  int pt, pl;                 // padding top, left
  uint groups;
  uint act;                   // 0 none, 1 ReLU, 2 LeakyReLU
  float slope;                // LeakyReLU slope
  uint has_bias;
  uint hp, wp;                // zero-padded input planes (blocked, depthwise)
  uint wblocks;               // output pixel blocks per row (blocked, depthwise)
  uint cin_g, cout_g;         // channels per group
  uint has_res;               // residual added before the activation (forward)
  uint cres;                  // its channels (<= cout; channels past it get none)
  uint yh, yw;                // y's planes (blocked: hout × wout, or a padded tensor's)
  uint ytop, yleft;           // where the output sits in them
  uint xrelu;                 // ReLU on x as it is read (direct, depthwise)
} pc;

// The forward shaders that take a residual declare it as binding 4
// (`res`, [n, cres, hout, wout]) and add it with conv_residual() before
// conv_act(): y = act(conv + bias + residual).
#ifdef CONV2D_RESIDUAL
layout(binding = 4) uniform samplerBuffer res;
// pc.has_res as specialization constant 8: llvmpipe runs both sides of a
// branch on a push constant (masked, not skipped), so a runtime flag would
// fetch the residual for every output even when there is none.
layout(constant_id = 8) const uint HAS_RES = 0u;
// The residual at output channel co, flat pixel pix (oy·wout + ox) of image n.
float conv_residual(uint n, uint co, uint pix) {
  if (HAS_RES == 0u || co >= pc.cres) return 0.0;
  return texelFetch(res, int((n * pc.cres + co) * pc.hout * pc.wout + pix)).r;
}
// Also has_res == 2: the residual in a padded layout (planes hp × wp, at
// (pt, pl)): blocked, this conv's own padded input (a stride-1 'same' conv's);
// pointwise (no padding of its own), the padded tensor's.
float conv_residual_at(uint n, uint co, uint oy, uint ox) {
  if (HAS_RES != 2u) return conv_residual(n, co, oy * pc.wout + ox);
  if (co >= pc.cres) return 0.0;
  const int row = int((n * pc.cres + co) * pc.hp + oy) + pc.pt;
  return texelFetch(res, row * int(pc.wp) + int(ox) + pc.pl).r;
}
#endif

float conv_act(float v) {
  if (pc.act == 1u) return max(v, 0.0);
  if (pc.act == 2u) return v < 0.0 ? v * pc.slope : v;
  return v;
}

#endif
