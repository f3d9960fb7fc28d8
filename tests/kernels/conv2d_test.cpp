#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/kernels/ref/conv2d_ref.hpp>

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <random>
#include <sstream>
#include <string>

#include "support/expect_error.hpp"
#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using kernels::Activation;
using kernels::Conv2dAlgo;
using kernels::Conv2dParams;

struct Case {
  ref::Conv2dDims d;
  Conv2dParams p;
};

std::string describe(const Case& c) {
  std::ostringstream s;
  s << "x [" << c.d.n << "," << c.d.cin << "," << c.d.h << "," << c.d.w << "] w [" << c.d.cout
    << "," << c.d.cin / c.p.groups << "," << c.d.kh << "," << c.d.kw << "] stride (" << c.p.stride_y
    << "," << c.p.stride_x << ") dil (" << c.p.dilation_y << "," << c.p.dilation_x << ") pad (t"
    << c.p.pad.top << " b" << c.p.pad.bottom << " l" << c.p.pad.left << " r" << c.p.pad.right
    << ") groups " << c.p.groups << " act " << int(c.p.activation)
    << (c.p.relu_input ? " relu_input" : "");
  return s.str();
}

Shape x_shape(const ref::Conv2dDims& d) { return {d.n, d.cin, d.h, d.w}; }
Shape w_shape(const ref::Conv2dDims& d, int groups) { return {d.cout, d.cin / groups, d.kh, d.kw}; }
Shape y_shape(const Case& c) {
  return {c.d.n, c.d.cout, ref::conv2d_out_h(c.d, c.p), ref::conv2d_out_w(c.d, c.p)};
}

bool valid(const Case& c) {
  const std::int64_t hout = ref::conv2d_out_h(c.d, c.p), wout = ref::conv2d_out_w(c.d, c.p);
  return c.d.h + c.p.pad.top + c.p.pad.bottom >= (c.d.kh - 1) * c.p.dilation_y + 1 &&
         c.d.w + c.p.pad.left + c.p.pad.right >= (c.d.kw - 1) * c.p.dilation_x + 1 && hout >= 1 &&
         wout >= 1;
}

// Random convolutions over the shapes real networks use, sized so the
// reference stays fast: channels 1..64 (incl. not multiples of 8), odd and even
// sizes incl. 1×1, kernels 1/3/5/7, stride 1/2, dilation 1/2, asymmetric
// padding, dense/grouped/depthwise, every activation.
Case random_case(std::mt19937& rng) {
  auto pick = [&](std::initializer_list<int> v) {
    return *(v.begin() + std::uniform_int_distribution<int>(0, int(v.size()) - 1)(rng));
  };
  auto uni = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  while (true) {
    Case c;
    c.d.n = pick({1, 2});
    c.d.cin = pick({1, 3, 8, 16, 32, 64});
    c.d.cout = pick({1, 3, 8, 13, 16, 32, 64});
    c.d.h = pick({1, 2, 5, 8, 11, 16, 19});
    c.d.w = pick({1, 3, 6, 9, 16, 17, 23});
    c.d.kh = pick({1, 3, 5, 7});
    c.d.kw = uni(0, 3) == 0 ? pick({1, 3, 5, 7}) : c.d.kh;
    c.p.stride_y = pick({1, 2});
    c.p.stride_x = uni(0, 3) == 0 ? pick({1, 2}) : c.p.stride_y;
    c.p.dilation_y = pick({1, 1, 2});
    c.p.dilation_x = pick({1, 1, 2});
    c.p.pad = {uni(0, 3), uni(0, 3), uni(0, 3), uni(0, 3)};
    const int g = uni(0, 3);
    if (g == 1) {  // depthwise, sometimes with a channel multiplier and an input ReLU
      c.p.groups = int(c.d.cin);
      c.d.cout = c.d.cin * pick({1, 1, 2});
      c.p.relu_input = (c.d.h + c.d.w) % 2 == 0;
    } else if (g == 2 && c.d.cin % 2 == 0 && c.d.cout % 2 == 0) {
      c.p.groups = 2;
    }
    c.p.activation = Activation(uni(0, 2));
    c.p.leaky_slope = 0.1f;
    if (!valid(c)) continue;
    const std::int64_t macs = c.d.n * c.d.cout * ref::conv2d_out_h(c.d, c.p) *
                              ref::conv2d_out_w(c.d, c.p) * (c.d.cin / c.p.groups) * c.d.kh *
                              c.d.kw;
    if (macs > 4'000'000) continue;
    return c;
  }
}

// Hand-picked edges: pointwise with h·w a multiple of 8 or not, 1×1 images, TF
// "same" stride 2 on even sizes, Cout not a multiple of the 8-channel block.
std::vector<Case> edge_cases() {
  std::vector<Case> cases;
  Case c;
  c.d = {1, 16, 5, 7, 13, 1, 1};
  cases.push_back(c);
  c.d = {2, 3, 1, 1, 8, 1, 1};
  cases.push_back(c);
  c.d = {2, 5, 3, 4, 9, 1, 1};  // h·w = 12: vec4 reads, a last block of 4 pixels
  cases.push_back(c);
  c.d = {2, 6, 4, 8, 11, 1, 1};  // the weight gradient on flat planes, rows of whole blocks
  cases.push_back(c);
  c.d = {3, 7, 4, 6, 17, 1, 1};  // flat planes of 24 pixels, rows of 6
  cases.push_back(c);
  c.d = {1, 8, 1, 1, 16, 3, 3};
  c.p.pad = {1, 1, 1, 1};
  cases.push_back(c);
  c.d = {2, 16, 12, 10, 24, 3, 3};
  c.p.stride_y = c.p.stride_x = 2;
  c.p.pad = kernels::same_padding(12, 10, 3, 3, 2, 2);
  c.p.activation = Activation::leaky_relu;
  cases.push_back(c);
  c.d = {1, 64, 4, 4, 72, 3, 3};  // the ResNet's 4×4 stage: 4-pixel blocks
  c.p = {};
  c.p.pad = kernels::same_padding(4, 4, 3, 3, 1, 1);
  c.p.activation = Activation::relu;
  cases.push_back(c);
  c.d = {2, 24, 17, 17, 40, 3, 3};  // 17 wide: a partial last 8-pixel block
  c.p.stride_y = c.p.stride_x = 2;
  c.p.pad = {};
  cases.push_back(c);
  c.d = {1, 5, 7, 46, 11, 3, 3};  // rows wider than one pixel block, 2 pixels of the last unused
  c.p = {};
  c.p.pad = kernels::same_padding(7, 46, 3, 3, 1, 1);
  cases.push_back(c);
  c.d = {1, 3, 9, 61, 16, 7, 7};  // strided wide rows: 4-pixel blocks, 8 channels
  c.p.stride_y = c.p.stride_x = 2;
  c.p.pad = {};
  c.p.activation = Activation::relu;
  cases.push_back(c);
  c.d = {1, 32, 9, 9, 32, 3, 3};
  c.p = {};
  c.p.groups = 32;
  c.p.pad = kernels::same_padding(9, 9, 3, 3, 1, 1);
  c.p.activation = Activation::relu;
  cases.push_back(c);
  c.d = {1, 8, 56, 56, 8, 3, 3};  // depthwise, wide rows: 8..16-pixel blocks × 4 rows
  c.p.groups = 8;
  c.p.pad = kernels::same_padding(56, 56, 3, 3, 1, 1);
  c.p.relu_input = true;
  cases.push_back(c);
  c.d = {2, 6, 28, 27, 6, 3, 3};  // depthwise, strided wide rows: 8-pixel blocks, 1 row
  c.p.groups = 6;
  c.p.stride_y = c.p.stride_x = 2;
  c.p.pad = kernels::same_padding(28, 27, 3, 3, 2, 2);
  c.p.activation = Activation::none;
  cases.push_back(c);
  c.d = {2, 5, 14, 14, 5, 3, 3};  // depthwise, blocks of 2 whole 14-pixel rows: vec4 stores
  c.p.groups = 5;
  c.p.stride_y = c.p.stride_x = 1;
  c.p.pad = kernels::same_padding(14, 14, 3, 3, 1, 1);
  c.p.activation = Activation::relu;
  cases.push_back(c);
  c.d = {1, 3, 4, 6, 6, 3, 3};  // depthwise ×2 channels, blocks of 4 whole 6-pixel rows
  c.p.groups = 3;
  c.p.activation = Activation::none;
  c.p.pad = kernels::same_padding(4, 6, 3, 3, 1, 1);
  cases.push_back(c);
  c.d = {1, 16, 7, 7, 24, 1, 1};  // pointwise, 49 pixels: scalar reads, channel blocks flattened
  c.p = {};
  cases.push_back(c);
  c.d = {2, 6, 6, 6, 12, 1, 1};  // pointwise, vec4 stores of quads that cross a row end
  cases.push_back(c);
  // Pointwise, 16 output channels per invocation (Cout % 16 == 0) and the
  // channel loop unrolled by 4, 2 or not at all (Cin % 4, % 2).
  c.d = {1, 12, 7, 7, 32, 1, 1};  // scalar reads (49 pixels), unrolled by 4
  cases.push_back(c);
  c.d = {2, 6, 6, 6, 16, 1, 1};  // quads across a row end, unrolled by 2
  cases.push_back(c);
  c.d = {1, 20, 8, 10, 48, 1, 1};  // vec4 reads, three 16-channel blocks
  c.p.activation = Activation::relu;
  cases.push_back(c);
  c.d = {2, 5, 4, 4, 16, 1, 1};  // not unrolled, one 16-channel block
  c.p.activation = Activation::leaky_relu;
  cases.push_back(c);
  // Pointwise, 16 pixels per invocation (planes of 512 pixels or more).
  c.d = {1, 8, 23, 23, 16, 1, 1};  // 529 pixels: scalar reads, a last block of 1 pixel
  c.p.activation = Activation::none;
  cases.push_back(c);
  c.d = {2, 12, 20, 26, 24, 1, 1};  // 520: vec4 reads and stores, a last block of 8 pixels
  cases.push_back(c);
  // Strided backward-data by phases (conv2d_backward.cpp): stride 3 with a
  // kernel not a multiple of it and uneven padding; stride 2 with Cout·Cin
  // past one dispatch's workgroup rows (the weight rearranged in chunks).
  c.d = {2, 4, 10, 11, 5, 4, 4};
  c.p = {};
  c.p.stride_y = c.p.stride_x = 3;
  c.p.pad = {1, 2, 0, 1};
  cases.push_back(c);
  c.d = {1, 260, 3, 3, 256, 3, 3};
  c.p = {};
  c.p.stride_y = c.p.stride_x = 2;
  c.p.pad = {1, 1, 1, 1};
  cases.push_back(c);
  // Rows of whole quads (w a multiple of 4) padded by 0..3: the padding
  // pass reads x by quads, shifted by each offset mod 4 (conv2d_pad.comp).
  for (int k = 0; k < 4; ++k) {
    c.d = {1, 4, 5, 8, k % 2 == 0 ? 4 : 6, 3, 3};
    c.p = {};
    c.p.pad = {k, k, k, k};
    if (k % 2 == 0) c.p.groups = 4;  // depthwise
    cases.push_back(c);
  }
  return cases;
}

// Every output: |got − want| ≤ 1e-4·(1 + |want|).
constexpr test::Tol kTol{1e-4, 1e-4};

// The hand-picked edges first, then random convolutions.
Case draw_case(test::OpCase& c, const std::vector<Case>& edges) {
  if (c.index < int(edges.size())) return edges[std::size_t(c.index)];
  return random_case(c.rng());
}

// The variants that can run a case (direct always can).
std::vector<Conv2dAlgo> runnable(const Device& dev, const Case& c) {
  std::vector<Conv2dAlgo> algos;
  for (Conv2dAlgo a :
       {Conv2dAlgo::direct, Conv2dAlgo::blocked, Conv2dAlgo::pointwise, Conv2dAlgo::depthwise}) {
    Conv2dParams p = c.p;
    p.algo = a;
    try {
      const kernels::Conv2dPlan plan(dev, x_shape(c.d), w_shape(c.d, c.p.groups), p);
      algos.push_back(a);
    } catch (const InvalidArgument&) {
    }
  }
  return algos;
}

void check_forward(test::OpCase& t, const Case& c) {
  Device& dev = t.device;
  t.describe(describe(c));
  const Shape ws = w_shape(c.d, c.p.groups);
  const auto xs = t.floats(x_shape(c.d).numel());
  const auto wv = t.floats(ws.numel());
  const auto bv = t.floats(c.d.cout);
  const auto want = ref::conv2d(xs, wv, bv, c.d, c.p);
  const auto want_nobias = ref::conv2d(xs, wv, {}, c.d, c.p);
  // A residual with all of y's channels or (every other case) fewer: the channels
  // past it get none, as in a shortcut zero-padded in channels.
  const std::int64_t cres = t.index % 2 == 0 ? c.d.cout : (c.d.cout + 1) / 2;
  Shape rs = y_shape(c);
  rs = Shape{rs[0], cres, rs[2], rs[3]};
  const auto rv = t.floats(rs.numel());
  const auto want_res = ref::conv2d(xs, wv, bv, c.d, c.p, rv, cres);
  Tensor x = Tensor::from(dev, x_shape(c.d), xs);
  Tensor w = Tensor::from(dev, ws, wv);
  Tensor b = Tensor::from(dev, {c.d.cout}, bv);
  Tensor r = Tensor::from(dev, rs, rv);
  EXPECT_EQ(kernels::conv2d_output_shape(x.shape(), w.shape(), c.p), y_shape(c));
  for (Conv2dAlgo a : runnable(dev, c)) {
    Conv2dParams p = c.p;
    p.algo = a;
    Tensor y = Tensor::empty(dev, y_shape(c));
    Tensor y2 = Tensor::empty(dev, y_shape(c));
    Tensor y3 = Tensor::empty(dev, y_shape(c));
    Tensor y4 = Tensor::empty(dev, y_shape(c));
    Stream s(dev);
    // NaN first: pooled memory may still hold another variant's right answer,
    // which would hide outputs a variant never writes.
    for (const Tensor* o : {&y, &y2, &y3, &y4}) s.fill(*o, std::numeric_limits<float>::quiet_NaN());
    kernels::conv2d(s, x, w, &b, y, p);
    kernels::conv2d(s, x, w, nullptr, y2, p);
    // A plan made once, its weights packed ahead of the calls (what layers do).
    kernels::Conv2dPlan plan(dev, x.shape(), w.shape(), p);
    EXPECT_EQ(plan.algo(), a);
    plan.pack(s, w);
    const kernels::Planes rp = kernels::Planes::of(r);
    plan.run(s, kernels::Planes::of(x), w, &b, kernels::Planes::of(y3));
    plan.run(s, kernels::Planes::of(x), w, &b, kernels::Planes::of(y4), &rp);
    s.run();
    const std::string algo = kernels::conv2d_algo_name(a);
    t.expect("forward " + algo, y, want, kTol);
    t.expect("forward without bias " + algo, y2, want_nobias, kTol);
    t.expect("forward, packed weight " + algo, y3, want, kTol);
    t.expect("forward with a residual of " + std::to_string(cres) + " channels " + algo, y4,
             want_res, kTol);
  }
}

void check_backward(test::OpCase& t, const Case& c) {
  Device& dev = t.device;
  t.describe(describe(c));
  const Shape ws = w_shape(c.d, c.p.groups);
  const auto xs = t.floats(x_shape(c.d).numel());
  const auto wv = t.floats(ws.numel());
  const auto dys = t.floats(y_shape(c).numel());
  Tensor x = Tensor::from(dev, x_shape(c.d), xs);
  Tensor w = Tensor::from(dev, ws, wv);
  Tensor dy = Tensor::from(dev, y_shape(c), dys);
  Tensor dw = Tensor::empty(dev, ws);
  Tensor db = Tensor::empty(dev, {c.d.cout});
  Tensor dx_direct = Tensor::empty(dev, x_shape(c.d));
  Tensor dx_auto = Tensor::empty(dev, x_shape(c.d));
  Conv2dParams p = c.p;
  p.activation = Activation::none;
  p.relu_input = false;  // forward only
  Stream s(dev);
  kernels::conv2d_backward_weight(s, x, dy, dw, &db, p);
  kernels::conv2d_backward_data(s, dy, w, dx_auto, p);
  p.algo = Conv2dAlgo::direct;
  kernels::conv2d_backward_data(s, dy, w, dx_direct, p);
  Tensor dw_direct = Tensor::empty(dev, ws);
  kernels::conv2d_backward_weight(s, x, dy, dw_direct, nullptr, p);
  s.run();
  const auto want_dx = ref::conv2d_backward_data(dys, wv, c.d, p);
  t.expect("backward data (auto)", dx_auto, want_dx, kTol);
  t.expect("backward data (direct)", dx_direct, want_dx, kTol);
  const auto want_dw = ref::conv2d_backward_weight(xs, dys, c.d, p);
  t.expect("backward weight (auto)", dw, want_dw, kTol);
  t.expect("backward weight (direct)", dw_direct, want_dw, kTol);
  t.expect("backward bias", db, ref::conv2d_backward_bias(dys, c.d, p), kTol);
}

TEST(Conv2d, ForwardMatchesReferenceEveryVariant) {
  const std::vector<Case> edges = edge_cases();
  test::check_op("conv2d", {.seed = 2024, .cases = int(edges.size()) + 28},
                 [&](test::OpCase& t) { check_forward(t, draw_case(t, edges)); });
}

TEST(Conv2d, BackwardMatchesReference) {
  const std::vector<Case> edges = edge_cases();
  test::check_op("conv2d backward", {.seed = 77, .cases = int(edges.size()) + 16},
                 [&](test::OpCase& t) { check_backward(t, draw_case(t, edges)); });
}

// A blocked conv writing straight into the zero-padded input of the next
// one (planes in the consumer's Conv2dPlan::input_layout), which reads it
// with no padding pass: the two match the reference chained on the host.
// Returns whether the pair could be chained (a 'same' consumer reads plain input).
bool check_padded_chain(test::OpCase& t, const Case& c) {
  Device& dev = t.device;
  t.describe(describe(c));
  auto uni = [&](int lo, int hi) { return t.uniform(lo, hi); };
  const Shape ys = y_shape(c);
  ref::Conv2dDims d2{ys[0], ys[1], ys[2], ys[3], std::int64_t(uni(1, 20)), 3, 3};
  Conv2dParams p2;
  p2.stride_y = uni(1, 2);
  p2.stride_x = uni(1, 2);
  p2.pad = {uni(0, 2), uni(0, 2), uni(0, 2), uni(0, 2)};
  p2.activation = Activation::relu;
  const Case c2{d2, p2};
  if (!valid(c2)) return false;
  Conv2dParams p1 = c.p;
  p1.algo = Conv2dAlgo::blocked;
  const Shape ws = w_shape(c.d, 1), ws2 = w_shape(d2, 1);
  const auto xs = t.floats(x_shape(c.d).numel());
  const auto wv = t.floats(ws.numel());
  const auto bv = t.floats(c.d.cout);
  const auto wv2 = t.floats(ws2.numel());
  const auto rv = t.floats(y_shape(c2).numel());
  const auto mid = ref::conv2d(xs, wv, bv, c.d, c.p);
  const auto want = ref::conv2d(mid, wv2, {}, d2, p2, rv, d2.cout);
  Stream s(dev);
  const kernels::Conv2dPlan plan2(dev, ys, ws2, p2);
  if (plan2.input_layout().plain()) {  // the consumer reads x plain (not blocked or depthwise)
    EXPECT_NE(plan2.algo(), Conv2dAlgo::blocked);
    return false;
  }
  const kernels::Planes xp = kernels::Planes::make(s, ys, plan2.input_layout());
  Tensor x = Tensor::from(dev, x_shape(c.d), xs);
  Tensor w = Tensor::from(dev, ws, wv);
  Tensor b = Tensor::from(dev, {c.d.cout}, bv);
  Tensor w2 = Tensor::from(dev, ws2, wv2);
  Tensor r = Tensor::from(dev, y_shape(c2), rv);
  Tensor y = Tensor::empty(dev, y_shape(c2));
  const kernels::Planes rp = kernels::Planes::of(r);
  kernels::Conv2dPlan(dev, x.shape(), ws, p1).run(s, kernels::Planes::of(x), w, &b, xp);
  plan2.run(s, xp, w2, nullptr, kernels::Planes::of(y), &rp);
  s.run();
  t.expect("conv into padded, conv from padded", y, want, kTol);
  return true;
}

TEST(Conv2d, ChainsThroughPaddedTensors) {
  int checked = 0;
  test::check_op("conv2d into padded planes", {.seed = 404, .cases = 40, .cases_on_every_path = 2},
                 [&](test::OpCase& t) {
                   const Case c = random_case(t.rng());
                   if (c.p.groups != 1) return;
                   checked += check_padded_chain(t, c) ? 1 : 0;
                 });
  EXPECT_GE(checked, 10);
}

// A residual block's second conv reading its input and its shortcut from
// one padded tensor (a stride-1 'same' conv: the shortcut has the input's
// layout), the shortcut with fewer channels than y; x, y: 2 images.
TEST(Conv2d, ResidualInThePaddedInputLayout) {
  Device& dev = test::device();
  const ref::Conv2dDims d0{2, 5, 9, 11, 8, 3, 3}, d1{2, 8, 9, 11, 12, 3, 3};
  Conv2dParams p;
  p.pad = {1, 1, 1, 1};
  p.activation = Activation::relu;
  const auto x0 = test::random_floats(std::size_t(x_shape(d0).numel()), 1);
  const auto w0 = test::random_floats(std::size_t(w_shape(d0, 1).numel()), 2);
  const auto w1 = test::random_floats(std::size_t(w_shape(d1, 1).numel()), 3);
  const auto b1 = test::random_floats(std::size_t(d1.cout), 4);
  const auto mid = ref::conv2d(x0, w0, {}, d0, p);
  const auto want = ref::conv2d(mid, w1, b1, d1, p, mid, d1.cin);
  Stream s(dev);
  const kernels::Conv2dPlan plan1(dev, x_shape(d1), w_shape(d1, 1), p);
  ASSERT_FALSE(plan1.input_layout().plain());
  const kernels::Planes xp = kernels::Planes::make(s, x_shape(d1), plan1.input_layout());
  Tensor x = Tensor::from(dev, x_shape(d0), x0);
  Tensor tw0 = Tensor::from(dev, w_shape(d0, 1), w0);
  Tensor tw1 = Tensor::from(dev, w_shape(d1, 1), w1);
  Tensor tb1 = Tensor::from(dev, {d1.cout}, b1);
  Tensor y = Tensor::empty(dev, {2, 12, 9, 11});
  kernels::Conv2dPlan(dev, x_shape(d0), w_shape(d0, 1), p)
      .run(s, kernels::Planes::of(x), tw0, nullptr, xp);
  EXPECT_EQ(plan1.residual_misfit(xp), "");
  plan1.run(s, xp, tw1, &tb1, kernels::Planes::of(y), &xp);
  s.run();
  test::expect_all_close("residual from the padded input", y.download(), want, kTol);
  Conv2dParams strided = p;  // output smaller than x: no shortcut in x's layout
  strided.stride_y = strided.stride_x = 2;
  Tensor y2 = Tensor::empty(dev, {2, 12, 5, 6});
  Tensor x1 = Tensor::empty(dev, x_shape(d1));
  const kernels::Conv2dPlan strided_plan(dev, x_shape(d1), w_shape(d1, 1), strided);
  EXPECT_NE(strided_plan.residual_misfit(xp), "");
  EXPECT_THROW(
      strided_plan.run(s, kernels::Planes::of(x1), tw1, nullptr, kernels::Planes::of(y2), &xp),
      InvalidArgument);
}

// The separable residual chain the landmark net runs in inference, on random
// shapes, against the reference chained on the host:
//   a = pw0(x) + b0                  written into P, dw1's padded input
//   m = dw1(relu(a))                 read from P, ReLU as it is read
//   s = pw1(m) + b1 + a              a read from P; s written into Q (dw2's)
//   u = relu(dw2(relu(s)) + b2)      stride 2, read from Q; written into R
//   y = conv3(u)                     blocked 3×3, read from R.
TEST(Conv2d, SeparableChainThroughPaddedTensors) {
  Device& dev = test::device();
  std::mt19937 rng(99);
  auto pick = [&](std::initializer_list<int> v) {
    return *(v.begin() + std::uniform_int_distribution<int>(0, int(v.size()) - 1)(rng));
  };
  for (int trial = 0; trial < 6; ++trial) {
    const ref::Conv2dDims d0{pick({1, 2}),
                             pick({3, 8}),
                             pick({1, 5, 8, 14, 19}),
                             pick({2, 7, 9, 16, 23}),
                             pick({5, 8, 16, 32}),
                             1,
                             1};
    SCOPED_TRACE("trial " + std::to_string(trial) + ": x [" + std::to_string(d0.n) + "," +
                 std::to_string(d0.cin) + "," + std::to_string(d0.h) + "," + std::to_string(d0.w) +
                 "], " + std::to_string(d0.cout) + " channels");
    const std::int64_t c = d0.cout;
    const ref::Conv2dDims d1{d0.n, c, d0.h, d0.w, c, 3, 3}, dp1{d0.n, c, d0.h, d0.w, c, 1, 1};
    const ref::Conv2dDims d2{d0.n, c, d0.h, d0.w, c, 3, 3};
    Conv2dParams pw, dw1, dw2, p3;
    dw1.groups = dw2.groups = int(c);
    dw1.pad = kernels::same_padding(d0.h, d0.w, 3, 3, 1, 1);
    dw1.relu_input = dw2.relu_input = true;
    dw2.stride_y = dw2.stride_x = 2;
    dw2.pad = kernels::same_padding(d0.h, d0.w, 3, 3, 2, 2);
    dw2.activation = Activation::relu;
    const ref::Conv2dDims d3{d0.n, c, ref::conv2d_out_h(d2, dw2), ref::conv2d_out_w(d2, dw2), 4,
                             3,    3};
    p3.pad = {1, 1, 1, 1};
    const auto xv = test::random_floats(std::size_t(x_shape(d0).numel()), 10 + trial);
    const auto w0 = test::random_floats(std::size_t(c * d0.cin), 20 + trial);
    const auto b0 = test::random_floats(std::size_t(c), 30 + trial);
    const auto wd1 = test::random_floats(std::size_t(c * 9), 40 + trial);
    const auto w1 = test::random_floats(std::size_t(c * c), 50 + trial);
    const auto b1 = test::random_floats(std::size_t(c), 60 + trial);
    const auto wd2 = test::random_floats(std::size_t(c * 9), 70 + trial);
    const auto b2 = test::random_floats(std::size_t(c), 80 + trial);
    const auto w3 = test::random_floats(std::size_t(4 * c * 9), 90 + trial);
    const auto a = ref::conv2d(xv, w0, b0, d0, pw);
    const auto m = ref::conv2d(a, wd1, {}, d1, dw1);
    const auto sum = ref::conv2d(m, w1, b1, dp1, pw, a, c);
    const auto u = ref::conv2d(sum, wd2, b2, d2, dw2);
    const auto want = ref::conv2d(u, w3, {}, d3, p3);

    Stream s(dev);
    const Shape ys = x_shape(d1), us = x_shape(d3);
    const kernels::Conv2dPlan plan_pw0(dev, x_shape(d0), {c, d0.cin, 1, 1}, pw);
    const kernels::Conv2dPlan plan_dw1(dev, ys, {c, 1, 3, 3}, dw1);
    const kernels::Conv2dPlan plan_pw1(dev, ys, {c, c, 1, 1}, pw);
    const kernels::Conv2dPlan plan_dw2(dev, ys, {c, 1, 3, 3}, dw2);
    const kernels::Conv2dPlan plan3(dev, us, {4, c, 3, 3}, p3);
    ASSERT_FALSE(plan_dw1.input_layout().plain() || plan_dw2.input_layout().plain() ||
                 plan3.input_layout().plain());
    const kernels::Planes P = kernels::Planes::make(s, ys, plan_dw1.input_layout());
    const kernels::Planes Q = kernels::Planes::make(s, ys, plan_dw2.input_layout());
    const kernels::Planes R = kernels::Planes::make(s, us, plan3.input_layout());
    Tensor x = Tensor::from(dev, x_shape(d0), xv);
    Tensor tw0 = Tensor::from(dev, {c, d0.cin, 1, 1}, w0), tb0 = Tensor::from(dev, {c}, b0);
    Tensor twd1 = Tensor::from(dev, {c, 1, 3, 3}, wd1);
    Tensor tw1 = Tensor::from(dev, {c, c, 1, 1}, w1), tb1 = Tensor::from(dev, {c}, b1);
    Tensor twd2 = Tensor::from(dev, {c, 1, 3, 3}, wd2), tb2 = Tensor::from(dev, {c}, b2);
    Tensor tw3 = Tensor::from(dev, {4, c, 3, 3}, w3);
    Tensor tm = Tensor::empty(dev, ys);
    Tensor y = Tensor::empty(dev, Shape{d0.n, 4, d3.h, d3.w});
    using kernels::Planes;
    plan_pw0.run(s, Planes::of(x), tw0, &tb0, P);
    plan_dw1.run(s, P, twd1, nullptr, Planes::of(tm));
    plan_pw1.run(s, Planes::of(tm), tw1, &tb1, Q, &P);
    plan_dw2.run(s, Q, twd2, &tb2, R);
    plan3.run(s, R, tw3, nullptr, Planes::of(y));
    s.run();
    test::expect_all_close("separable chain through padded tensors", y.download(), want, kTol);
  }
}

// Central differences of L = Σ g ⊙ conv(x, w, b) against dX, dW, dbias.
void gradcheck(const Case& c, std::uint32_t seed) {
  Device& dev = test::device();
  SCOPED_TRACE(describe(c) + " seed " + std::to_string(seed));
  const Shape ws = w_shape(c.d, c.p.groups);
  const auto xs = test::random_floats(std::size_t(x_shape(c.d).numel()), seed);
  const auto wv = test::random_floats(std::size_t(ws.numel()), seed + 1);
  const auto bv = test::random_floats(std::size_t(c.d.cout), seed + 2);
  const auto g = test::random_floats(std::size_t(y_shape(c).numel()), seed + 3);
  auto loss = [&](std::span<const float> xv, std::span<const float> wvv,
                  std::span<const float> bvv) {
    Tensor x = Tensor::from(dev, x_shape(c.d), xv);
    Tensor w = Tensor::from(dev, ws, wvv);
    Tensor b = Tensor::from(dev, {c.d.cout}, bvv);
    Tensor y = Tensor::empty(dev, y_shape(c));
    Stream s(dev);
    kernels::conv2d(s, x, w, &b, y, c.p);
    s.run();
    return test::weighted_sum(y.download(), g);
  };
  Tensor x = Tensor::from(dev, x_shape(c.d), xs);
  Tensor w = Tensor::from(dev, ws, wv);
  Tensor dy = Tensor::from(dev, y_shape(c), g);
  Tensor dx = Tensor::empty(dev, x_shape(c.d));
  Tensor dw = Tensor::empty(dev, ws);
  Tensor db = Tensor::empty(dev, {c.d.cout});
  Stream s(dev);
  kernels::conv2d_backward_data(s, dy, w, dx, c.p);
  kernels::conv2d_backward_weight(s, x, dy, dw, &db, c.p);
  s.run();
  test::GradCheckOptions o;
  o.samples = 24;
  o.seed = seed;
  test::expect_gradient_matches([&](std::span<const float> v) { return loss(v, wv, bv); }, xs,
                                dx.download(), "dX", o);
  test::expect_gradient_matches([&](std::span<const float> v) { return loss(xs, v, bv); }, wv,
                                dw.download(), "dW", o);
  test::expect_gradient_matches([&](std::span<const float> v) { return loss(xs, wv, v); }, bv,
                                db.download(), "dbias", o);
}

TEST(Conv2d, GradientsMatchFiniteDifferences) {
  Case dense;
  dense.d = {2, 3, 6, 7, 5, 3, 3};
  dense.p.stride_y = 2;
  dense.p.dilation_x = 2;
  dense.p.pad = {1, 0, 2, 1};
  gradcheck(dense, 5);
  Case same;  // stride 1: backward-data takes the blocked (transposed) path
  same.d = {1, 4, 5, 6, 3, 3, 3};
  same.p.pad = {1, 1, 1, 1};
  gradcheck(same, 6);
  Case depthwise;
  depthwise.d = {1, 4, 7, 5, 4, 3, 3};
  depthwise.p.groups = 4;
  depthwise.p.pad = {0, 2, 1, 1};
  gradcheck(depthwise, 7);
}

TEST(Conv2d, SamePaddingFollowsTensorFlow) {
  // Stride 2 on even sizes: total 1, all of it after (bottom/right).
  const kernels::Padding2d p = kernels::same_padding(128, 64, 3, 3, 2, 2);
  EXPECT_EQ(p.top, 0);
  EXPECT_EQ(p.bottom, 1);
  EXPECT_EQ(p.left, 0);
  EXPECT_EQ(p.right, 1);
  const kernels::Padding2d q = kernels::same_padding(7, 9, 5, 3, 1, 1);
  EXPECT_EQ(q.top, 2);
  EXPECT_EQ(q.bottom, 2);
  EXPECT_EQ(q.left, 1);
  EXPECT_EQ(q.right, 1);
  const kernels::Padding2d r = kernels::same_padding(6, 6, 1, 1, 2, 2);  // 1×1 stride 2: none
  EXPECT_EQ(r.top + r.bottom + r.left + r.right, 0);
  Conv2dParams cp;
  cp.stride_y = cp.stride_x = 2;
  cp.pad = p;
  EXPECT_EQ(kernels::conv2d_output_shape({1, 8, 128, 64}, {16, 8, 3, 3}, cp),
            Shape({1, 16, 64, 32}));
}

TEST(Conv2d, SelectsTheSpecializedVariants) {
  const Device& device = test::device();
  Conv2dParams p;
  EXPECT_EQ(kernels::Conv2dPlan(device, {1, 64, 32, 32}, {64, 64, 1, 1}, p).algo(),
            Conv2dAlgo::pointwise);
  p.pad = {1, 1, 1, 1};
  EXPECT_EQ(kernels::Conv2dPlan(device, {1, 64, 32, 32}, {64, 64, 3, 3}, p).algo(),
            Conv2dAlgo::blocked);
  p.groups = 64;
  EXPECT_EQ(kernels::Conv2dPlan(device, {1, 64, 32, 32}, {64, 1, 3, 3}, p).algo(),
            Conv2dAlgo::depthwise);
  p.relu_input = true;
  p.groups = 64;
  EXPECT_EQ(kernels::Conv2dPlan(device, {1, 64, 32, 32}, {64, 1, 3, 3}, p).algo(),
            Conv2dAlgo::depthwise);
  p.groups = 1;  // only the direct and depthwise variants take an input ReLU
  EXPECT_EQ(kernels::Conv2dPlan(device, {1, 64, 32, 32}, {64, 64, 3, 3}, p).algo(),
            Conv2dAlgo::direct);
  p.relu_input = false;
  p.groups = 2;
  EXPECT_EQ(kernels::Conv2dPlan(device, {1, 64, 32, 32}, {64, 32, 3, 3}, p).algo(),
            Conv2dAlgo::direct);
}

TEST(Conv2d, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor x = Tensor::empty(dev, {1, 4, 8, 8});
  Tensor w = Tensor::empty(dev, {8, 4, 3, 3});
  Tensor y = Tensor::empty(dev, {1, 8, 6, 6});
  Conv2dParams p;
  Tensor w_bad = Tensor::empty(dev, {8, 3, 3, 3});
  test::expect_invalid_argument([&] { kernels::conv2d(s, x, w_bad, nullptr, y, p); },
                                "input channels");
  Tensor y_bad = Tensor::empty(dev, {1, 8, 8, 8});
  test::expect_invalid_argument([&] { kernels::conv2d(s, x, w, nullptr, y_bad, p); }, "expected");
  Tensor b_bad = Tensor::empty(dev, {7});
  test::expect_invalid_argument([&] { kernels::conv2d(s, x, w, &b_bad, y, p); }, "bias");
  Tensor w_other = Tensor::empty(dev, {8, 4, 1, 1});
  kernels::Conv2dPlan plan(dev, x.shape(), w.shape(), p);
  test::expect_invalid_argument([&] { plan.pack(s, w_other); }, "weight");
  Tensor w_3d = Tensor::empty(dev, {8, 4, 9});
  test::expect_invalid_argument([&] { plan.pack(s, w_3d); }, "weight");
  test::expect_invalid_argument(
      [&] { plan.run(s, kernels::Planes::of(x), w_other, nullptr, kernels::Planes::of(y)); },
      "weight");
  Tensor empty = Tensor::empty(dev, {0, 4, 8, 8});
  test::expect_invalid_argument([&] { kernels::conv2d(s, empty, w, nullptr, y, p); }, "empty");
  Conv2dParams g3 = p;
  g3.groups = 3;
  test::expect_invalid_argument([&] { kernels::conv2d(s, x, w, nullptr, y, g3); }, "groups");
  Conv2dParams s0 = p;
  s0.stride_x = 0;
  test::expect_invalid_argument([&] { kernels::conv2d(s, x, w, nullptr, y, s0); }, "stride");
  Conv2dParams forced = p;
  forced.algo = Conv2dAlgo::pointwise;
  test::expect_invalid_argument([&] { kernels::conv2d(s, x, w, nullptr, y, forced); }, "pointwise");
  Tensor big_w = Tensor::empty(dev, {8, 4, 11, 11});
  test::expect_invalid_argument([&] { kernels::conv2d_output_shape(x.shape(), big_w.shape(), p); },
                                "exceeds");
  Tensor res_wide = Tensor::empty(dev, {1, 9, 6, 6});
  test::expect_invalid_argument([&] { kernels::conv2d(s, x, w, nullptr, y, p, &res_wide); },
                                "residual");
  Tensor res_small = Tensor::empty(dev, {1, 8, 5, 6});
  test::expect_invalid_argument([&] { kernels::conv2d(s, x, w, nullptr, y, p, &res_small); },
                                "residual");
  Conv2dParams same = p;
  same.pad = {1, 1, 1, 1};
  using kernels::Planes;
  const Planes xp = Planes::make(
      s, x.shape(), kernels::Conv2dPlan(dev, x.shape(), w.shape(), same).input_layout());
  ASSERT_TRUE(xp.padded());
  // Padded for another convolution (p pads nothing: another geometry).
  test::expect_invalid_argument([&] { plan.run(s, xp, w, nullptr, Planes::of(y)); },
                                "padded input");
  const Planes y_too_small{xp.data, y.shape(), xp.layout};  // 4 planes for y's 8
  test::expect_invalid_argument([&] { plan.run(s, Planes::of(x), w, nullptr, y_too_small); },
                                "padded output");
  Tensor w1x1 = Tensor::empty(dev, {8, 4, 1, 1});
  Tensor y8 = Tensor::empty(dev, {1, 8, 8, 8});
  const kernels::Conv2dPlan pointwise(dev, x.shape(), w1x1.shape(), p);
  ASSERT_EQ(pointwise.algo(), Conv2dAlgo::pointwise);
  ASSERT_TRUE(pointwise.input_layout().plain());  // a 1×1 conv reads no padded input
  test::expect_invalid_argument([&] { pointwise.run(s, xp, w1x1, nullptr, Planes::of(y8)); },
                                "padded input");
  // xp holds [1, 4, 8, 8]: no residual for a y of 8 channels at 6×6.
  test::expect_invalid_argument([&] { plan.run(s, Planes::of(x), w, nullptr, Planes::of(y), &xp); },
                                "residual");
  Tensor w_dw = Tensor::empty(dev, {4, 1, 3, 3});
  Tensor y_dw = Tensor::empty(dev, {1, 4, 8, 8});
  Conv2dParams dwp = same;
  dwp.groups = 4;  // a depthwise conv takes no padded residual
  const kernels::Conv2dPlan depthwise(dev, x.shape(), w_dw.shape(), dwp);
  ASSERT_EQ(depthwise.algo(), Conv2dAlgo::depthwise);
  test::expect_invalid_argument(
      [&] { depthwise.run(s, Planes::of(x), w_dw, nullptr, Planes::of(y_dw), &xp); },
      "plain residuals");
  const kernels::Conv2dPlan empty_plan;
  test::expect_invalid_argument(
      [&] { empty_plan.run(s, Planes::of(x), w, nullptr, Planes::of(y)); }, "empty");
  Conv2dParams relu_in = p;
  relu_in.relu_input = true;
  relu_in.algo = Conv2dAlgo::blocked;
  test::expect_invalid_argument([&] { kernels::conv2d(s, x, w, nullptr, y, relu_in); },
                                "input ReLU");
  relu_in.algo = Conv2dAlgo::auto_select;
  test::expect_invalid_argument([&] { kernels::conv2d_backward_data(s, y, w, x, relu_in); },
                                "forward only");
  test::expect_invalid_argument(
      [&] { kernels::conv2d_backward_weight(s, x, y, w, nullptr, relu_in); }, "forward only");
  Tensor dy_bad = Tensor::empty(dev, {1, 8, 5, 6});
  test::expect_invalid_argument([&] { kernels::conv2d_backward_data(s, dy_bad, w, x, p); }, "dy");
  test::expect_invalid_argument(
      [&] { kernels::conv2d_backward_weight(s, x, dy_bad, w, nullptr, p); }, "dy");
}

TEST(Conv2d, NaNPropagates) {
  Device& dev = test::device();
  std::vector<float> xs(1 * 8 * 4 * 4, 1.f);
  xs[5] = NAN;
  Tensor x = Tensor::from(dev, {1, 8, 4, 4}, xs);
  Tensor w = Tensor::from(dev, {8, 8, 3, 3}, test::random_floats(8 * 8 * 9, 3));
  Tensor y = Tensor::empty(dev, {1, 8, 4, 4});
  Conv2dParams p;
  p.pad = {1, 1, 1, 1};
  Stream s(dev);
  kernels::conv2d(s, x, w, nullptr, y, p);
  s.run();
  const auto ys = y.download();
  EXPECT_TRUE(std::isnan(ys[0])) << "pixel (0,0) sees the NaN at (1,1)";
  EXPECT_FALSE(std::isnan(ys[15])) << "pixel (3,3) does not";
}

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec) + double(u.ru_stime.tv_sec) +
         1e-6 * double(u.ru_stime.tv_usec);
}

// Throughput of the reference case (3×3, 64→64, 128×128, N = 1).
// Prints, does not assert; run with --gtest_also_run_disabled_tests and
// VKJR2_VALIDATION=0.
TEST(Conv2dBench, DISABLED_Forward3x3_64x64_128) {
  Device dev(DeviceOptions{});
  const std::int64_t c = 64, hw = 128;
  Tensor x = Tensor::from(dev, {1, c, hw, hw}, test::random_floats(std::size_t(c * hw * hw), 1));
  Tensor w = Tensor::from(dev, {c, c, 3, 3}, test::random_floats(std::size_t(c * c * 9), 2));
  Tensor b = Tensor::from(dev, {c}, test::random_floats(std::size_t(c), 3));
  Tensor y = Tensor::empty(dev, {1, c, hw, hw});
  Tensor dx = Tensor::empty(dev, {1, c, hw, hw});
  Tensor dw = Tensor::empty(dev, {c, c, 3, 3});
  Tensor db = Tensor::empty(dev, {c});
  const double gflop = 2.0 * c * hw * hw * c * 9 * 1e-9;
  auto time = [&](const char* what, int iters, const std::function<void(Stream&)>& op) {
    Stream s(dev);
    op(s);  // warm-up (pipeline JIT)
    s.run();
    const double cpu0 = cpu_seconds();
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < iters; ++i) op(s);
    s.run();
    const double sec =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / iters;
    const double cpu = (cpu_seconds() - cpu0) / iters;
    // The machine is shared: GFLOP per CPU-second of this process shows the
    // kernel's efficiency independent of how many cores it got.
    std::printf("conv2d 3x3 64->64 128x128 %-22s %9.3f ms %7.2f GFLOP/s %7.2f GFLOP/cpu-s (%s)\n",
                what, sec * 1e3, gflop / sec, gflop / cpu, dev.info().name.c_str());
  };
  Conv2dParams p;
  p.pad = {1, 1, 1, 1};
  p.activation = Activation::relu;
  for (Conv2dAlgo a : {Conv2dAlgo::blocked, Conv2dAlgo::direct}) {
    p.algo = a;
    time((std::string("forward ") + kernels::conv2d_algo_name(a)).c_str(),
         a == Conv2dAlgo::direct ? 2 : 10, [&](Stream& s) { kernels::conv2d(s, x, w, &b, y, p); });
  }
  p.activation = Activation::none;
  for (Conv2dAlgo a : {Conv2dAlgo::blocked, Conv2dAlgo::direct}) {
    p.algo = a;
    time((std::string("backward-data ") + kernels::conv2d_algo_name(a)).c_str(),
         a == Conv2dAlgo::direct ? 2 : 10,
         [&](Stream& s) { kernels::conv2d_backward_data(s, y, w, dx, p); });
  }
  p.algo = Conv2dAlgo::auto_select;
  time("backward-weight+bias", 2,
       [&](Stream& s) { kernels::conv2d_backward_weight(s, x, y, dw, &db, p); });
}

}  // namespace
}  // namespace vkjr2
