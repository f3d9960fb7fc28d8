// FaceLandmark68Net against face-api itself: the references written by
// tests/parity/face_api_reference.mjs (scripts/setup) hold, per detected face,
// the crop face-api fed the net, its 112×112 input, the raw 136 outputs, the
// relative landmarks and the landmarks in image pixels.
#include <vkjr2/nets/face_landmarks.hpp>
#include <vkjr2/nets/tfjs_weights.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/npy.hpp>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <support/parity.hpp>
#include <support/test_device.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace vkjr2::nets {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const FaceLandmark68Net& net() {
  static const auto n = FaceLandmark68Net::load(test::device());
  return *n;
}

Tensor npy_image(const std::string& name) {
  return image_to_device(test::device(), read_npy(test::parity_dir() / name));
}

TEST(FaceLandmark68Net, LoadsEveryManifestWeightOnce) {
  const TfjsWeights w =
      load_tfjs_weights(face_api_manifest("face_landmark_68_model-weights_manifest.json"));
  const FaceLandmark68Net n(test::device(), w);
  const auto params = n.named_parameters();
  EXPECT_EQ(params.size(), w.size());
  std::int64_t count = 0;
  for (const auto& [name, p] : params) count += p.numel();
  EXPECT_EQ(count, w.parameter_count());
  EXPECT_EQ(count, FaceLandmark68Net::kParameterCount);
  const auto has = [&](const std::string& name) {
    return std::any_of(params.begin(), params.end(),
                       [&](const auto& p) { return p.first == name; });
  };
  EXPECT_TRUE(has("dense0.conv0.filters"));
  EXPECT_TRUE(has("dense3.conv3.pointwise_filter"));
  EXPECT_TRUE(has("fc.bias"));

  // A weight the network does not use, and a missing one, are named.
  auto entries = w.entries();
  entries.emplace_back("dense4/conv0/bias", HostTensor{{4}, {0, 0, 0, 0}});
  try {
    FaceLandmark68Net bad(test::device(), TfjsWeights(entries, "extra.json"));
    ADD_FAILURE() << "an unused weight was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("dense4/conv0/bias"), std::string::npos) << e.what();
  }
  entries = w.entries();
  entries.erase(entries.begin() + 5);  // dense0/conv2/depthwise_filter
  EXPECT_THROW(FaceLandmark68Net(test::device(), TfjsWeights(entries, "missing.json")),
               InvalidArgument);
  entries = w.entries();
  entries.back().second.shape = {68, 2};  // fc/bias with the right count, wrong shape
  EXPECT_THROW(FaceLandmark68Net(test::device(), TfjsWeights(entries, "shape.json")),
               InvalidArgument);
}

// Same 112×112 input → raw outputs; same crop → 112 input and landmarks.
TEST(FaceLandmark68Net, MatchesFaceApiGivenTheSameCrop) {
  const json index = test::parity_index();
  ASSERT_FALSE(index.is_null());
  Stream stream(test::device());
  double max_raw = 0, max_input = 0, max_px = 0, max_fused = 0;
  int faces = 0;
  for (const json& image : index.at("images")) {
    for (const json& det : image.at("detections")) {
      const std::string face = det.at("landmarks_112").get<std::string>();
      SCOPED_TRACE(face);
      const auto want_raw = det.at("landmarks_raw").get<std::vector<double>>();
      const auto want_rel = det.at("landmarks_relative").get<std::vector<double>>();
      ASSERT_EQ(want_raw.size(), 136u);

      Tape tape(stream, /*recording=*/false);
      const Tensor want_x112 = npy_image(face);
      const Var raw = net().forward(tape, Var(want_x112));
      const Tensor crop = npy_image(det.at("landmarks_input").get<std::string>());
      const Var x112 = to_landmark_input(tape, Var(crop));
      stream.run();
      const std::vector<float> got_raw = raw.value().download();
      for (std::size_t i = 0; i < 136; ++i) {
        const double d = std::abs(got_raw[i] - want_raw[i]);
        max_raw = std::max(max_raw, d);
        EXPECT_LE(d, 1e-4 * std::max(1.0, std::abs(want_raw[i]))) << "raw output " << i;
      }
      const std::vector<float> got_x = x112.value().download(), want_x = want_x112.download();
      ASSERT_EQ(got_x.size(), want_x.size());
      for (std::size_t i = 0; i < got_x.size(); ++i) {
        max_input = std::max(max_input, double(std::abs(got_x[i] - want_x[i])));
      }
      EXPECT_LE(max_input, 2e-3) << "112×112 input (pixel values 0..255)";

      const std::vector<float> xy = net().detect_landmarks(stream, crop);
      const auto w = double(crop.shape()[3]), h = double(crop.shape()[2]);
      for (std::size_t i = 0; i < 136; ++i) {
        const double want = want_rel[i] * (i % 2 == 0 ? w : h);
        const double d = std::abs(xy[i] - want);
        max_px = std::max(max_px, d);
        EXPECT_LE(d, 0.5) << "landmark coordinate " << i;
      }
      // detect_landmarks goes from the crop to conv0's padded input in one
      // pass (resize_into_padded): the same values as the separate resize,
      // normalization and padding that forward() runs, so the same result.
      const Var raw_composed = net().forward(tape, x112);
      stream.run();
      const auto rel = landmarks_relative_to_crop(raw_composed.value().download().data(), w, h);
      for (std::size_t i = 0; i < 136; ++i) {
        const float composed = rel[i] * float(i % 2 == 0 ? w : h);  // as detect_landmarks
        max_fused = std::max(max_fused, std::abs(double(xy[i]) - composed));
      }
      ++faces;
    }
  }
  EXPECT_GE(faces, 1);
  EXPECT_EQ(max_fused, 0.0) << "detect_landmarks vs to_landmark_input + forward, crop px";
  std::printf(
      "[ parity   ] %d faces: raw max |Δ| %.3g, 112² input max |Δ| %.3g, crop px max |Δ| %.3g, "
      "fused input pass vs composed %.3g\n",
      faces, max_raw, max_input, max_px, max_fused);
}

// The inference path (running sums in padded tensors, ReLU on read, adds in
// the pointwise epilogues) against the taped path the training runs (a
// recording tape whose parameters need gradients), on every reference face
// and on a batch of two.
TEST(FaceLandmark68Net, InferenceMatchesTheTapedPath) {
  const json index = test::parity_index();
  ASSERT_FALSE(index.is_null());
  std::vector<float> pixels;
  int faces = 0;
  for (const json& image : index.at("images")) {
    for (const json& det : image.at("detections")) {
      const std::vector<float> v = npy_image(det.at("landmarks_112").get<std::string>()).download();
      pixels.insert(pixels.end(), v.begin(), v.end());
      ++faces;
    }
  }
  ASSERT_GE(faces, 2);
  const Tensor batch = Tensor::from(test::device(), Shape{faces, 3, 112, 112}, pixels);
  const auto run = [&](const Tensor& x, bool recording) {
    Stream stream(test::device());
    Tape tape(stream, recording);
    const Var raw = net().forward(tape, Var(x));
    stream.run();
    return raw.value().download();
  };
  const std::vector<float> taped = run(batch, true), inferred = run(batch, false);
  ASSERT_EQ(taped.size(), inferred.size());
  double worst = 0;
  for (std::size_t i = 0; i < taped.size(); ++i) {
    worst = std::max(worst, std::fabs(double(taped[i]) - inferred[i]));
  }
  // The same operations, the sums associated alike: float rounding only.
  EXPECT_LT(worst, 1e-5);
  const Tensor two =
      Tensor::from(test::device(), Shape{2, 3, 112, 112},
                   std::vector<float>(pixels.begin(), pixels.begin() + 2 * 3 * 112 * 112));
  const std::vector<float> pair = run(two, false);
  for (std::size_t i = 0; i < pair.size(); ++i) EXPECT_NEAR(pair[i], inferred[i], 1e-5) << i;
}

// to_landmark_input without gradients (one pass over the virtual square)
// against the taped pad + resize, on crops padded across or down, down- and
// upscaled, and one already 112 on its long side.
TEST(FaceLandmark68Net, LandmarkInputWithoutGradientsMatchesPadThenResize) {
  const std::array<std::array<std::int64_t, 2>, 5> sizes = {
      {{255, 312}, {312, 255}, {60, 90}, {97, 41}, {112, 80}}};
  for (const auto& [h, w] : sizes) {
    SCOPED_TRACE(std::to_string(h) + "×" + std::to_string(w));
    const auto values =
        test::random_floats(std::size_t(2 * 3 * h * w), std::uint32_t(h * w), 0.f, 255.f);
    const Tensor crops = Tensor::from(test::device(), Shape{2, 3, h, w}, values);
    const auto run = [&](bool with_grad) {
      Stream stream(test::device());
      Tape tape(stream, true);
      const Var x112 = to_landmark_input(tape, Var(crops, with_grad));
      stream.run();
      EXPECT_EQ(x112.shape(), (Shape{2, 3, 112, 112}));
      return x112.value().download();
    };
    const std::vector<float> fused = run(false), taped = run(true);
    ASSERT_EQ(fused.size(), taped.size());
    for (std::size_t i = 0; i < fused.size(); ++i) ASSERT_NEAR(fused[i], taped[i], 1e-4) << i;
  }
}

// The full step: detection box → crop → landmarks in image pixels.
TEST(FaceLandmark68Net, LandmarksInImageMatchFaceApi) {
  const json index = test::parity_index();
  ASSERT_FALSE(index.is_null());
  Stream stream(test::device());
  double max_px = 0;
  int faces = 0;
  for (const json& image : index.at("images")) {
    const Tensor pixels = npy_image(image.at("pixels").get<std::string>());
    for (const json& det : image.at("detections")) {
      SCOPED_TRACE(det.at("landmarks_input").get<std::string>());
      const json& b = det.at("box");
      const FaceBox box{b.at("x").get<double>(), b.at("y").get<double>(),
                        b.at("width").get<double>(), b.at("height").get<double>()};
      const std::vector<double> got = net().landmarks_in_image(stream, pixels, box);
      const auto want = det.at("landmarks").get<std::vector<std::array<double, 2>>>();
      ASSERT_EQ(got.size(), 2 * want.size());
      for (std::size_t i = 0; i < want.size(); ++i) {
        for (std::size_t a = 0; a < 2; ++a) {
          const double d = std::abs(got[2 * i + a] - want[i][a]);
          max_px = std::max(max_px, d);
          EXPECT_LE(d, 0.5) << "landmark " << i << (a == 0 ? " x" : " y");
        }
      }
      ++faces;
    }
  }
  EXPECT_GE(faces, 1);
  std::printf("[ parity   ] %d faces: landmarks in image max |Δ| %.3g px\n", faces, max_px);
}

// postProcess undoes face-api's padding estimate: a point at the centre of
// the padded square maps to the centre of any crop, the square's left edge
// maps to −pad/scaled width for a tall crop.
TEST(FaceLandmark68Net, PostProcessMapsThePaddedSquareBackToTheCrop) {
  std::array<float, 136> raw{};
  raw.fill(0.5f);
  raw[0] = 0.f;                                                      // x0 at the square's left edge
  const auto rel = landmarks_relative_to_crop(raw.data(), 50, 100);  // tall: 56 wide in 112
  EXPECT_NEAR(rel[0], -28.0 / 56.0, 1e-6);
  EXPECT_NEAR(rel[1], 0.5, 1e-6);
  EXPECT_NEAR(rel[2], 0.5, 1e-6);
  const auto wide = landmarks_relative_to_crop(raw.data(), 200, 100);
  EXPECT_NEAR(wide[0], 0.0, 1e-6);  // no padding along x for a wide crop
  EXPECT_NEAR(wide[3], 0.5, 1e-6);
  EXPECT_THROW(landmarks_relative_to_crop(raw.data(), 0, 10), InvalidArgument);
}

TEST(FaceLandmark68Net, RejectsBadInputsWithClearErrors) {
  Stream stream(test::device());
  Tape tape(stream, /*recording=*/false);
  const Device& d = test::device();
  // Wrong network input size.
  EXPECT_THROW(net().forward(tape, Var(Tensor::empty(d, Shape{1, 3, 96, 96}))), InvalidArgument);
  EXPECT_THROW(net().forward(tape, Var(Tensor::empty(d, Shape{1, 1, 112, 112}))), InvalidArgument);
  EXPECT_THROW(net().forward(tape, Var()), InvalidArgument);
  // Not one RGB crop.
  EXPECT_THROW(net().detect_landmarks(stream, Tensor()), InvalidArgument);
  EXPECT_THROW(net().detect_landmarks(stream, Tensor::empty(d, Shape{1, 1, 20, 20})),
               InvalidArgument);
  EXPECT_THROW(net().detect_landmarks(stream, Tensor::empty(d, Shape{2, 3, 20, 20})),
               InvalidArgument);
  // A box outside the image.
  const Tensor img = Tensor::from(d, Shape{1, 3, 8, 8}, std::vector<float>(192, 128.f));
  try {
    (void)net().landmarks_in_image(stream, img, FaceBox{20, 20, 5, 5});
    ADD_FAILURE() << "a box outside the image was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("outside"), std::string::npos) << e.what();
  }
  // NaN pixels.
  std::vector<float> nan_pixels(3 * 30 * 20, 100.f);
  nan_pixels[7] = std::nanf("");
  EXPECT_THROW(net().detect_landmarks(stream, Tensor::from(d, Shape{1, 3, 30, 20}, nan_pixels)),
               InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::nets
