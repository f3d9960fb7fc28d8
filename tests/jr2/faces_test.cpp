// The face pipeline on face-api's sample photos: end-to-end agreement with
// face-api, 1:N identification of mildly blurred probes, and gradients from
// the descriptor back to the frame's pixels through the alignment.
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/runtime/npy.hpp>

#include <gtest/gtest.h>

#include <cmath>

#include "support/gradcheck.hpp"
#include "support/parity.hpp"
#include "support/test_device.hpp"

namespace vkjr2::jr2 {
namespace {

// Flat index of an int index expression (test shapes are small).
std::size_t flat(std::int64_t i) { return static_cast<std::size_t>(i); }

namespace fs = std::filesystem;
using vkjr2::HostTensor;

const FaceAnalyzer& analyzer() {
  static const FaceAnalyzer a(test::device());
  return a;
}

// Separable Gaussian blur of an H×W×3 image (σ in pixels, radius 3σ, edges
// clamped): the "mildly blurred probe" of the identification criterion.
HostTensor gaussian_blur(const HostTensor& img, double sigma) {
  const int h = int(img.shape[0]), w = int(img.shape[1]);
  const int r = int(std::ceil(3 * sigma));
  std::vector<double> k(std::size_t(2 * r + 1));
  double sum = 0;
  for (int i = -r; i <= r; ++i) sum += k[flat(i + r)] = std::exp(-i * i / (2 * sigma * sigma));
  for (double& v : k) v /= sum;
  HostTensor tmp = img, out = img;
  const auto at = [&](const HostTensor& t, int y, int x, int c) {
    y = std::clamp(y, 0, h - 1);
    x = std::clamp(x, 0, w - 1);
    return double(t.values[flat((y * w + x) * 3 + c)]);
  };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        double s = 0;
        for (int i = -r; i <= r; ++i) s += k[flat(i + r)] * at(img, y, x + i, c);
        tmp.values[flat((y * w + x) * 3 + c)] = float(s);
      }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        double s = 0;
        for (int i = -r; i <= r; ++i) s += k[flat(i + r)] * at(tmp, y + i, x, c);
        out.values[flat((y * w + x) * 3 + c)] = float(s);
      }
  return out;
}

TEST(Jr2Faces, BlurredProbesFindTheirFaceAtRankOne) {
  const auto index = test::parity_index();
  ASSERT_TRUE(index.contains("images"));
  std::vector<GalleryEntry> gallery;
  std::vector<std::pair<std::string, HostTensor>> probes;
  Stream s(test::device());
  for (const auto& im : index["images"]) {
    int k = 0;
    for (const auto& det : im["detections"]) {
      const std::string id = im["name"].get<std::string>() + "_f" + std::to_string(k++);
      const HostTensor chip =
          vkjr2::read_npy(test::parity_dir() / det["recognition_150"].get<std::string>());
      gallery.push_back(
          {id, id, analyzer().describe_chip(s, nets::image_to_device(test::device(), chip))});
      probes.emplace_back(id, gaussian_blur(chip, 1.0));
    }
  }
  ASSERT_GE(gallery.size(), 20u) << "the tiny detector finds 20 faces in the 6 sample photos";
  int rank1 = 0;
  for (const auto& [id, probe] : probes) {
    const auto d = analyzer().describe_chip(s, nets::image_to_device(test::device(), probe));
    const auto ranked = rank_identities(gallery, d);
    EXPECT_EQ(ranked.front().identity, id)
        << "probe " << id << ": nearest " << ranked.front().identity << " at "
        << ranked.front().distance;
    rank1 += ranked.front().identity == id;
  }
  RecordProperty("rank1", rank1);
}

TEST(Jr2Faces, PipelineAgreesWithFaceApiOnSample1) {
  const auto index = test::parity_index();
  ASSERT_TRUE(index.contains("images"));
  const auto& im = index["images"][0];
  const HostTensor pixels = vkjr2::read_npy(test::parity_dir() / im["pixels"].get<std::string>());
  Stream s(test::device());
  const auto faces = analyzer().analyze(s, nets::image_to_device(test::device(), pixels), {});
  const auto& ref = im["detections"];
  ASSERT_EQ(faces.size(), ref.size());
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const auto& r = ref[i];
    const nets::FaceBox rb{r["box"]["x"], r["box"]["y"], r["box"]["width"], r["box"]["height"]};
    EXPECT_GE(nets::box_iou(faces[i].box, rb), 0.99) << "face " << i;
    double worst = 0;
    for (std::size_t p = 0; p < 68; ++p) {
      worst =
          std::max({worst, std::abs(faces[i].landmarks[2 * p] - r["landmarks"][p][0].get<double>()),
                    std::abs(faces[i].landmarks[2 * p + 1] - r["landmarks"][p][1].get<double>())});
    }
    EXPECT_LE(worst, 0.5) << "face " << i << " landmarks (px)";
    const std::vector<float> want = r["descriptor"].get<std::vector<float>>();
    EXPECT_LT(descriptor_distance(faces[i].descriptor, want), 0.02) << "face " << i;
  }
}

TEST(Jr2Faces, EmbeddingGradientReachesTheFramePixels) {
  const auto index = test::parity_index();
  ASSERT_TRUE(index.contains("images"));
  const auto& det = index["images"][0]["detections"][0];
  const HostTensor frame = vkjr2::read_npy(test::parity_dir() / det["chip"].get<std::string>());
  // Landmarks in the chip's own coordinates.
  const double ox = det["chip_box"]["x"], oy = det["chip_box"]["y"];
  std::vector<float> lm;
  for (const auto& p : det["landmarks"]) {
    lm.push_back(float(p[0].get<double>() - ox));
    lm.push_back(float(p[1].get<double>() - oy));
  }
  const Device& d = test::device();
  const auto& net = analyzer().recognition_net();
  const std::vector<float> w = test::random_floats(128, 77);
  const auto loss_of = [&](nets::Tape& t, const nets::Var& image) {
    const nets::Var desc = net.forward(t, align_face(t, image, lm, 150));
    return nets::sum_all(t, nets::mul(t, desc, nets::Var(Tensor::from(d, desc.shape(), w))));
  };
  Stream s(d);
  nets::Tape t(s);
  const Tensor image = nets::image_to_device(d, frame);
  const nets::Var x(image, true);
  t.backward(loss_of(t, x));
  s.run();
  ASSERT_TRUE(x.has_grad());
  const std::vector<float> analytic = x.grad().download();
  double norm = 0;
  for (float g : analytic) norm += double(g) * g;
  EXPECT_GT(norm, 0) << "no gradient reached the pixels";

  const std::vector<float> base = image.download();
  test::GradCheckOptions o;
  o.step = 1.0;  // pixel units (0..255): large enough above fp32 noise of the 128-d loss
  o.samples = 10;
  o.rtol = 0.1;
  o.atol = 2e-5;
  test::expect_gradient_matches(
      [&](std::span<const float> probe) {
        Stream s2(d);
        nets::Tape t2(s2, false);
        const nets::Var l = loss_of(t2, nets::Var(Tensor::from(d, image.shape(), probe)));
        s2.run();
        return double(l.value().download()[0]);
      },
      base, analytic, "d loss(descriptor) / d frame pixel", o);
}

}  // namespace
}  // namespace vkjr2::jr2
