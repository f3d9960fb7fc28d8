#include <vkjr2/kernels/ref/warp_ref.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/simulator.hpp>
#include <vkjr2/sim/tilt.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <vector>

#include "support/frame_gradcheck.hpp"
#include "support/host_vulkan.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2::sim {
namespace {

Params frame_params(int batch, int channels, int height, int width,
                    const char* strength = "strong") {
  Params p = preset(strength);
  p.image = {height, width, channels, batch};
  return p;
}

// A smooth test scene with detail at several scales, values in [0, 1].
std::vector<float> scene(const ImageShape& im) {
  std::vector<float> v(std::size_t(im.batch) * im.channels * im.height * im.width);
  std::size_t i = 0;
  for (int b = 0; b < im.batch; ++b)
    for (int c = 0; c < im.channels; ++c)
      for (int y = 0; y < im.height; ++y)
        for (int x = 0; x < im.width; ++x)
          v[i++] = 0.5f + 0.25f * std::sin(0.31f * x + 0.7f * c + b) * std::cos(0.17f * y) +
                   0.2f * ((x / 8 + y / 8) % 2);
  return v;
}

SimOptions tilt_only() {
  SimOptions o;
  o.blur = false;
  return o;
}

// Tilt only: the frame is the input warped by the interpolated tilt field,
// and the flow is minus the field's tilt where grid points fall on pixels.
TEST(Simulator, TiltFrameIsTheWarpOfTheField) {
  Device& dev = test::device();
  const Params p = frame_params(2, 3, 40, 56);
  Simulator sim(dev, p, nullptr, tilt_only());
  const auto xs = scene(p.image);
  Tensor x = Tensor::from(dev, {2, 3, 40, 56}, xs);
  Tensor y = Tensor::empty(dev, x.shape());
  sim.reset(3);
  Stream s(dev);
  sim.frame(s, x, y);
  s.run();
  const auto flow = sim.flow().download();
  const auto want = ref::warp(xs, flow, 2, 3, 40, 56, kernels::SamplePadding::border);
  test::expect_all_close("y", y.download(), want, {1e-5, 1e-5});
  // Corner grid points sit on corner pixels.
  const auto tilt = sim.field().tilt_px().download();
  const int gh = sim.field().grid_h(), gw = sim.field().grid_w();
  EXPECT_NEAR(flow[0], -tilt[0], 1e-5);
  EXPECT_NEAR(flow[std::size_t(39 * 56 + 55)], -tilt[std::size_t((gh - 1) * gw + gw - 1)], 1e-5);
  // Strong turbulence moves the image by pixels, not by nothing.
  double rms = 0;
  for (float f : flow) rms += double(f) * f;
  EXPECT_GT(std::sqrt(rms / double(flow.size())), 0.3);
}

// Two simulators of the same parameters reset to the same seed, one input
// scene and an output each.
struct Twins {
  Twins(const Params& p, const SimOptions& o,
        const std::vector<std::shared_ptr<const BlurModel>>& m, std::uint64_t seed)
      : a(test::device(), p, m, o),
        b(test::device(), p, m, o),
        x(Tensor::from(test::device(), {1, p.image.channels, p.image.height, p.image.width},
                       scene(p.image))),
        ya(Tensor::empty(test::device(), x.shape())),
        yb(Tensor::empty(test::device(), x.shape())) {
    a.reset(seed);
    b.reset(seed);
  }
  Simulator a, b;
  Tensor x, ya, yb;
  Stream s{test::device()};
};

TEST(Simulator, SameSeedSameFramesAndVideoEvolves) {
  SimOptions o = tilt_only();
  o.field.tilt_rho = 0.95;
  o.noise.read_std = 0.01;
  Twins sims(frame_params(1, 1, 32, 48), o, {}, 77);
  std::vector<float> prev;
  for (int t = 0; t < 3; ++t) {
    sims.a.frame(sims.s, sims.x, sims.ya);
    sims.b.frame(sims.s, sims.x, sims.yb);
    sims.s.run();
    const auto va = sims.ya.download();
    EXPECT_EQ(va, sims.yb.download()) << "frame " << t;
    EXPECT_NE(va, prev) << "frame " << t;
    prev = va;
  }
}

// The profiling frame() makes the same frames and times each stage (RGB,
// the shipped blur models, sensor noise: every stage does work).
TEST(Simulator, StagedFrameIsTheSameFrameAndTimesEveryStage) {
  SimOptions o;
  o.noise.read_std = 0.01;
  Twins sims(frame_params(1, 3, 48, 64, "moderate"), o, load_shipped_blur_models(test::device()),
             5);
  FrameStages st;
  double after_first = 0;
  for (int t = 0; t < 2; ++t) {
    sims.a.frame(sims.s, sims.x, sims.ya);
    sims.b.frame(sims.s, sims.x, sims.yb, st);
    sims.s.run();
    EXPECT_EQ(sims.ya.download(), sims.yb.download()) << "frame " << t;
    if (t == 0) after_first = st.total();
  }
  EXPECT_GT(st.fields, 0);
  EXPECT_GT(st.warp, 0);
  EXPECT_GT(st.p2s, 0);
  EXPECT_GT(st.blur, 0);
  EXPECT_GT(st.noise, 0);
  EXPECT_GT(st.total(), after_first);  // accumulated over the frames
}

// Embedding: the simulator on a host application's device, reading and
// writing the host's buffers and recording into the host's command buffer,
// makes the frames it makes on vkjr2's own device and stream.
TEST(Simulator, RecordsIntoAHostCommandBufferOnAnAdoptedDevice) {
  const Params p = frame_params(1, 3, 64, 80, "moderate");
  const Shape shape{1, 3, 64, 80};
  const auto xs = scene(p.image);
  std::vector<float> want;
  {
    Device& dev = test::device();
    Simulator sim(dev, p, load_default_blur_model(dev));
    sim.reset(5);
    const Tensor x = Tensor::from(dev, shape, xs);
    const Tensor y = Tensor::empty(dev, shape);
    Stream s(dev);
    for (int t = 0; t < 2; ++t) sim.frame(s, x, y);  // the second frame of a video
    s.run();
    want = y.download();
  }
  test::HostVulkan host;
  ASSERT_NE(host.device, VK_NULL_HANDLE);
  const VkDeviceSize bytes = xs.size() * sizeof(float);
  test::HostBuffer xb(host, bytes), yb(host, bytes);
  std::memcpy(xb.mapped, xs.data(), bytes);
  test::HostQueue commands(host);
  {
    Device adopted(test::adopt(host), test::options());
    Simulator sim(adopted, p, load_default_blur_model(adopted));
    sim.reset(5);
    const Tensor x = Tensor::wrap(adopted, xb.buffer, 0, shape);
    const Tensor y = Tensor::wrap(adopted, yb.buffer, 0, shape);
    Stream s(adopted, commands);
    for (int t = 0; t < 2; ++t) sim.frame(s, x, y);
    s.run();
    EXPECT_EQ(commands.submits, 1);  // the whole frame pair is one host submission
  }
  const auto got = yb.floats();
  test::expect_all_close("got", std::vector<float>(got.begin(), got.end()), want, {1e-5, 1e-5});
  EXPECT_EQ(host.messages, 0);
}

// Noise only (no tilt, no blur): y − x has variance x/photons + read².
// Bound 4σ of the variance estimator (σ ≈ var·√(2/n)).
TEST(Simulator, SensorNoiseStatistics) {
  Device& dev = test::device();
  const Params p = frame_params(1, 1, 256, 256);
  SimOptions o = tilt_only();
  o.tilt = false;
  o.noise.photons_per_unit = 400;
  o.noise.read_std = 0.02;
  Simulator sim(dev, p, nullptr, o);
  std::vector<float> xs(256 * 256, 0.25f);
  Tensor x = Tensor::from(dev, {1, 1, 256, 256}, xs);
  Tensor y = Tensor::empty(dev, x.shape());
  sim.reset(9);
  Stream s(dev);
  sim.frame(s, x, y);
  s.run();
  const auto ys = y.download();
  double m = 0, v = 0;
  for (float e : ys) m += e - 0.25;
  m /= double(ys.size());
  for (float e : ys) v += (e - 0.25 - m) * (e - 0.25 - m);
  v /= double(ys.size());
  const double want = 0.25 / 400 + 0.02 * 0.02;
  EXPECT_NEAR(m, 0.0, 4 * std::sqrt(want / double(ys.size())));
  EXPECT_NEAR(v, want, 4 * want * std::sqrt(2.0 / double(ys.size())));
}

// The frame is linear in x for fixed turbulence; frame_backward is checked
// by central differences of L = Σ w ⊙ frame(x) with the same seed each time.
TEST(Simulator, TiltBackwardMatchesFiniteDifferences) {
  Device& dev = test::device();
  const Params p = frame_params(1, 2, 12, 17);
  Simulator sim(dev, p, nullptr, tilt_only());
  test::expect_frame_gradient(sim, scene(p.image), 5, 21, "simulator tilt d/dx");
}

TEST(Simulator, BadInputsAreClearErrors) {
  Device& dev = test::device();
  const Params p = frame_params(1, 1, 16, 16);
  EXPECT_THROW(Simulator(dev, p, nullptr, SimOptions{}), InvalidArgument);  // blur on, no model
  Simulator sim(dev, p, nullptr, tilt_only());
  Tensor wrong = Tensor::empty(dev, {1, 1, 16, 15});
  Tensor y = Tensor::empty(dev, {1, 1, 16, 16});
  Stream s(dev);
  sim.reset(1);
  EXPECT_THROW(sim.frame(s, wrong, y), InvalidArgument);
  EXPECT_THROW(sim.frame_backward(s, y, y), InvalidArgument);  // no frame yet
}

}  // namespace
}  // namespace vkjr2::sim
