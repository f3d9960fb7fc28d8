#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/nets/optimizer.hpp>
#include <vkjr2/nets/safetensors.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/temp_dir.hpp"
#include "support/test_device.hpp"

namespace vkjr2::jr2 {
namespace {

// Made by `tools/restorer_torch.py fixture` (PyTorch, float64): a tiny
// restorer's weights, an input and target, the output, the Charbonnier loss's
// gradient of every parameter and the weights after one Adam step.
const char* kFixture = VKJR2_RESTORER_FIXTURE;

Tensor to_device(Device& dev, const nets::SafetensorsRecord& r) {
  return Tensor::from(dev, Shape(r.shape), r.to_float());
}

TEST(Restorer, MatchesPyTorchOutputGradientsAndAdamStep) {
  Device& dev = test::device();
  const nets::SafetensorsFile f = nets::read_safetensors(kFixture);
  const RestorerConfig config = RestorerConfig::from_metadata(f.metadata, kFixture);
  Restorer net(dev, config, 1);
  const auto params = net.named_parameters();
  std::size_t in_file = 0;
  for (const auto& r : f.tensors) in_file += r.name.rfind("model.", 0) == 0 ? 1 : 0;
  ASSERT_EQ(params.size(), in_file) << "the fixture's network has other parameters";
  for (const auto& [name, v] : params) v.set_value(to_device(dev, f.at("model." + name)));

  Stream st(dev);
  nets::Tape tape(st);
  const nets::Var x(to_device(dev, f.at("input"))), target(to_device(dev, f.at("target")));
  const nets::Var out = net.forward(tape, x);
  const nets::Var loss = nets::charbonnier_loss(tape, out, target, 1e-3f);
  tape.backward(loss);
  st.run();
  const std::vector<float> want_out = f.at("output").to_float();
  test::expect_all_close("output", out.value().download(), want_out,
                         test::peak_relative(want_out, 1e-4));
  EXPECT_NEAR(loss.value().download()[0], f.at("loss").to_float()[0], 1e-5);
  for (const auto& [name, v] : params) {
    ASSERT_TRUE(v.has_grad()) << name;
    const std::vector<float> want = f.at("grad." + name).to_float();
    test::expect_all_close("grad." + name, v.grad().download(), want,
                           test::peak_relative(want, 1e-4));
  }
  nets::Adam adam(params, {.lr = 1e-3f});
  adam.step(st);
  st.run();
  // One step moves every weight by ≈ lr; 1e-6 is 0.1 % of that.
  for (const auto& [name, v] : params) {
    test::expect_all_close("adam." + name, v.value().download(), f.at("adam." + name).to_float(),
                           {1e-6, 1e-6});
  }
}

TEST(Restorer, CountsItsParametersAndStaysInBudget) {
  Device& dev = test::device();
  for (const RestorerConfig& c : {RestorerConfig{}, RestorerConfig{1, 8, {2}, 0, {1}},
                                  RestorerConfig{3, 6, {0, 2}, 2, {1, 0}}}) {
    Restorer net(dev, c, 3);
    std::int64_t n = 0;
    for (const auto& [name, v] : net.named_parameters()) n += v.numel();
    EXPECT_EQ(c.parameter_count(), n) << c.metadata().at("enc_blocks");
  }
  // The shipped configuration's budget (docs/restoration.md): ≤ 1 M
  // parameters and ≤ 2 GFLOP per restored 160² frame.
  const RestorerConfig shipped;
  EXPECT_LE(shipped.parameter_count(), 1'000'000);
  EXPECT_LE(shipped.flops(160, 160), 2e9);
  EXPECT_GT(shipped.flops(160, 160), 0.5e9);
}

TEST(Restorer, SavesLoadsAndRestoresAnySize) {
  Device& dev = test::device();
  const RestorerConfig c{3, 4, {1, 1}, 1, {1, 1}};
  Restorer net(dev, c, 7);
  // Non-zero β and γ, so that every block contributes.
  for (const auto& [name, v] : net.named_parameters()) {
    if (name.ends_with("beta") || name.ends_with("gamma")) {
      v.set_value(Tensor::from(dev, v.shape(), test::random_floats(std::size_t(v.numel()), 9)));
    }
  }
  test::TempDir dir;
  const auto path = dir.path / "r.safetensors";
  net.save(path, {{"note", "test"}});
  const auto loaded = Restorer::load(dev, path);
  EXPECT_EQ(loaded->config().metadata(), c.metadata());
  // 13×10 is padded to 16×12 inside and cropped back.
  const Shape s{2, 9, 13, 10};
  const nets::Var x(
      Tensor::from(dev, s, test::random_floats(std::size_t(s.numel()), 10, 0.f, 1.f)));
  Stream st(dev);
  nets::Tape tape(st, false);
  const nets::Var a = net.forward(tape, x), b = loaded->forward(tape, x);
  st.run();
  EXPECT_EQ(a.shape(), (Shape{2, 3, 13, 10}));
  test::expect_all_close("loaded", b.value().download(), a.value().download(), test::kExact);

  test::expect_invalid_argument(
      [&] {
        nets::Tape t2(st, false);
        (void)net.forward(t2, nets::Var(Tensor::empty(dev, {1, 6, 8, 8})));
      },
      "9");
  test::expect_invalid_argument([&] { (void)RestorerConfig{0}.parameter_count(); }, "frames");
  test::expect_invalid_argument(
      [&] {
        (void)RestorerConfig{8, 16, {1, 1}, 1, {1}}.parameter_count();
      },
      "decoder");
  test::expect_invalid_argument([&] { (void)parse_block_list("1,x", "--enc-blocks"); },
                                "--enc-blocks");
  // A checkpoint of another network is refused by name.
  const auto other = dir.path / "o.safetensors";
  const std::vector<nets::SafetensorsRecord> records = {
      nets::SafetensorsRecord::f32("w", {1}, std::vector<float>{1})};
  nets::write_safetensors(other, records, {{"format", "vkjr2-checkpoint-1"}});
  test::expect_invalid_argument([&] { (void)Restorer::load(dev, other); }, "o.safetensors");
}

// Face regions: square, a multiple of the restorer's step, inside the image;
// the same face from another frame adds none.
TEST(FaceRegions, SquareAlignedInsideAndOncePerFace) {
  using nets::FaceBox;
  const std::vector<FaceBox> boxes = {{50, 40, 20, 30},  // the face
                                      {52, 42, 20, 28},  // it again, a frame later
                                      {2, 90, 10, 10},   // another, at the border
                                      {0, 0, 0, 10}};    // empty: skipped
  const auto r = face_regions(boxes, 100, 120, 0.5, 8);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_EQ(r[0].width, 64);  // 30 × 2 = 60 → 64
  EXPECT_EQ(r[0].height, 64);
  EXPECT_EQ(r[0].x, 60 - 32);
  EXPECT_EQ(r[0].y, 55 - 32);
  EXPECT_EQ(r[1], (Region{0, 100 - 24, 24, 24}));         // 20 → 24, moved inside
  const std::vector<FaceBox> wide = {{10, 10, 400, 10}};  // wider than the image
  EXPECT_EQ(face_regions(wide, 100, 120, 0.5, 8), (std::vector<Region>{{0, 0, 120, 100}}));
  test::expect_invalid_argument([&] { (void)face_regions(boxes, 0, 10); }, "face_regions");
}

// Pasting: the patch inside, the frame outside, a ramp between, and no ramp
// along the image's own edges.
TEST(FaceRegions, PasteBlendsWithAFeatheredEdge) {
  const int h = 20, w = 30;
  std::vector<float> frame(3 * h * w, 0.f);
  const Region r{0, 4, 16, 12};
  const std::vector<float> patch(3 * 16 * 12, 1.f);
  paste_region(frame, h, w, patch, r, 4);
  auto at = [&](int c, int y, int x) { return frame[(std::size_t(c) * h + y) * w + x]; };
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(at(c, 10, 8), 1.f);   // inside
    EXPECT_EQ(at(c, 10, 0), 1.f);   // the image's left edge: not feathered
    EXPECT_EQ(at(c, 2, 8), 0.f);    // above the region
    EXPECT_EQ(at(c, 10, 20), 0.f);  // right of it
    EXPECT_GT(at(c, 4, 8), 0.f);    // the top ramp
    EXPECT_LT(at(c, 4, 8), at(c, 6, 8));
    EXPECT_LT(at(c, 10, 15), 0.5f);  // the right ramp's last pixel
  }
  test::expect_invalid_argument(
      [&] {
        paste_region(frame, h, w, patch, Region{20, 4, 16, 12}, 4);
      },
      "paste_region");
}

}  // namespace
}  // namespace vkjr2::jr2
