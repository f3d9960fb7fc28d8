// The probe-video pipeline on a real face: every sampled frame of a still
// face clip is tracked and its template is the gallery descriptor's; a clip
// without a face yields no template; only the sampled frames are decoded.
#include <vkjr2/jr2/protocol.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/npy.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "support/parity.hpp"
#include "support/test_device.hpp"

namespace vkjr2::jr2 {
namespace {

const FaceAnalyzer& analyzer() {
  static const FaceAnalyzer a(test::device());
  return a;
}

// A square crop of twice the face box around its centre (edges clamped),
// the way a benchmark clip holds its face.
HostTensor face_clip(const HostTensor& img, const nets::FaceBox& box) {
  const auto h = img.shape[0], w = img.shape[1];
  const auto side = std::int64_t(2 * std::max(box.width, box.height));
  const auto x0 = std::int64_t(box.x + box.width / 2) - side / 2;
  const auto y0 = std::int64_t(box.y + box.height / 2) - side / 2;
  HostTensor out;
  out.shape = {side, side, 3};
  out.values.resize(std::size_t(side * side * 3));
  for (std::int64_t y = 0; y < side; ++y) {
    for (std::int64_t x = 0; x < side; ++x) {
      const auto sy = std::clamp<std::int64_t>(y0 + y, 0, h - 1);
      const auto sx = std::clamp<std::int64_t>(x0 + x, 0, w - 1);
      for (int c = 0; c < 3; ++c) {
        out.values[std::size_t((y * side + x) * 3 + c)] =
            img.values[std::size_t((sy * w + sx) * 3 + c)];
      }
    }
  }
  return out;
}

TEST(ProbePipeline, TracksAStillFaceAndMatchesItsGalleryDescriptor) {
  const auto index = test::parity_index();
  const HostTensor photo =
      vkjr2::read_npy(test::parity_dir() / index["images"][0]["pixels"].get<std::string>());
  Stream s(test::device());
  FaceOptions fo;
  fo.descriptors = false;
  const auto faces = analyzer().analyze(s, nets::image_to_device(test::device(), photo), fo);
  ASSERT_FALSE(faces.empty());
  Tensor clip = nets::image_to_device(test::device(), face_clip(photo, faces[0].box));

  ProtocolOptions o;
  o.sampler = parse_frame_sampler("uniform:3");
  const ProbePipeline pipeline(analyzer(), o);
  int asked = 0;
  const ProbeOutcome po = pipeline.run(
      s, 10,
      [&](int) {
        ++asked;
        return clip;
      },
      1);
  EXPECT_EQ(asked, 3);  // only the sampled frames
  ASSERT_EQ(po.frames.size(), 3u);
  for (const FrameOutcome& f : po.frames) {
    EXPECT_TRUE(f.multi_scale);
    EXPECT_TRUE(f.tracked);
    EXPECT_GE(f.score, o.score_threshold);
  }
  const auto gallery = pipeline.describe_gallery(s, clip);
  ASSERT_EQ(po.templates.size(), 2u);  // face_api, similarity
  ASSERT_EQ(gallery.size(), 2u);
  for (std::size_t a = 0; a < 2; ++a) {
    ASSERT_EQ(po.templates[a].size(), 128u);
    EXPECT_EQ(po.descriptors[a].size(), 3u);
    // The same pixels: the template is the gallery's descriptor.
    EXPECT_GT(cosine_similarity(po.templates[a], gallery[a]), 0.9999)
        << align_mode_name(o.aligns[a]);
  }
}

TEST(ProbePipeline, BatchedDescriptorsEqualOneAtATime) {
  const auto index = test::parity_index();
  const HostTensor photo =
      vkjr2::read_npy(test::parity_dir() / index["images"][0]["pixels"].get<std::string>());
  Stream s(test::device());
  const Tensor image = nets::image_to_device(test::device(), photo);
  FaceOptions fo;
  fo.descriptors = false;
  std::vector<Face> faces = analyzer().analyze(s, image, fo);
  ASSERT_GE(faces.size(), 2u);
  const std::vector<Tensor> images(faces.size(), image);
  for (AlignMode align : {AlignMode::face_api, AlignMode::similarity}) {
    std::vector<Face> batch = faces;
    const std::vector<bool> ok = analyzer().embed_batch(s, images, align, batch);
    for (std::size_t i = 0; i < faces.size(); ++i) {
      Face one = faces[i];
      ASSERT_EQ(analyzer().embed(s, image, align, one), bool(ok[i]));
      ASSERT_EQ(one.descriptor.size(), batch[i].descriptor.size());
      for (std::size_t k = 0; k < one.descriptor.size(); ++k) {
        EXPECT_NEAR(batch[i].descriptor[k], one.descriptor[k], 1e-5)
            << align_mode_name(align) << " face " << i;
      }
    }
  }
}

HostTensor noise_image(std::int64_t side) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.f, 255.f);
  HostTensor noise;
  noise.shape = {side, side, 3};
  noise.values.resize(std::size_t(side * side * 3));
  for (float& v : noise.values) v = u(rng);
  return noise;
}

TEST(ProbePipeline, NoFaceNoTemplate) {
  Tensor img = nets::image_to_device(test::device(), noise_image(160));
  Stream s(test::device());
  const ProbePipeline pipeline(analyzer(), ProtocolOptions{});
  const ProbeOutcome po = pipeline.run(
      s, 4, [&](int) { return img; }, 3);
  ASSERT_EQ(po.frames.size(), 4u);  // segments:4x2 of 4 frames: one each
  for (const FrameOutcome& f : po.frames) EXPECT_FALSE(f.tracked);
  for (const auto& t : po.templates) EXPECT_TRUE(t.empty());
  // The gallery falls back to the centred box and still gives a descriptor.
  const auto g = pipeline.describe_gallery(s, img);
  EXPECT_EQ(g[0].size(), 128u);
}

TEST(ProbePipeline, ClipQualityIsTheMeanOverFrames) {
  HostTensor clean;
  clean.shape = {24, 20, 3};
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(20.f, 230.f);
  for (int i = 0; i < 24 * 20 * 3; ++i) clean.values.push_back(std::round(u(rng)));
  HostTensor shifted = clean;
  for (float& v : shifted.values) v += 5.f;  // MSE 25: PSNR 10·log10(255²/25) = 34.15 dB
  Stream s(test::device());
  const Tensor c = nets::image_to_device(test::device(), clean);
  const std::vector<Tensor> frames = {nets::image_to_device(test::device(), shifted),
                                      nets::image_to_device(test::device(), shifted)};
  const ClipQuality q = clip_quality(s, frames, c);
  EXPECT_NEAR(q.psnr_db, 10 * std::log10(255.0 * 255.0 / 25.0), 1e-3);
  EXPECT_GT(q.ssim, 0.9);  // a brightness shift of 5 barely changes the structure
  EXPECT_LT(q.ssim, 1.0);
  const std::vector<Tensor> wrong = {nets::image_to_device(test::device(), noise_image(10))};
  EXPECT_THROW(clip_quality(s, wrong, c), InvalidArgument);
}

TEST(ProbePipeline, ChecksItsOptions) {
  ProtocolOptions o;
  o.input_sizes = {416, 100};
  EXPECT_THROW(ProbePipeline(analyzer(), o), InvalidArgument);
  o = ProtocolOptions{};
  o.track_threshold = 0.6f;  // above the score threshold
  EXPECT_THROW(ProbePipeline(analyzer(), o), InvalidArgument);
  o = ProtocolOptions{};
  o.aligns.clear();
  EXPECT_THROW(ProbePipeline(analyzer(), o), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::jr2
