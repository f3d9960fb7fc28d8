// TinyFaceDetector against face-api itself: the references written by
// tests/parity/face_api_reference.mjs (scripts/setup) hold, per sample photo,
// the decoded pixels, the 416×416 network input, the raw 13×13×25 output and
// the candidate boxes before and after NMS.
#include <vkjr2/nets/tfjs_weights.hpp>
#include <vkjr2/nets/tiny_face_detector.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/npy.hpp>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <support/parity.hpp>
#include <support/test_device.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace vkjr2::nets {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const TinyFaceDetector& net() {
  static const auto n = TinyFaceDetector::load(test::device());
  return *n;
}

FaceBox box_of(const json& b) {
  return FaceBox{b.at("x").get<double>(), b.at("y").get<double>(), b.at("width").get<double>(),
                 b.at("height").get<double>()};
}

// face-api's raw output is NHWC [cells, cells, 25]; ours NCHW [25, cells, cells].
std::vector<float> hwc_to_chw(const HostTensor& t) {
  const auto h = std::size_t(t.shape.at(0)), w = std::size_t(t.shape.at(1)),
             c = std::size_t(t.shape.at(2));
  std::vector<float> out(t.values.size());
  for (std::size_t y = 0; y < h; ++y)
    for (std::size_t x = 0; x < w; ++x)
      for (std::size_t k = 0; k < c; ++k) out[(k * h + y) * w + x] = t.values[(y * w + x) * c + k];
  return out;
}

// Same count, and each reference box matched by the one at the same position.
void expect_same_boxes(const std::vector<FaceBox>& got, const std::vector<double>& got_scores,
                       const json& want, double& min_iou, double& max_score, const char* what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const double iou = box_iou(got[i], box_of(want[i].at("box")));
    const double ds = std::abs(got_scores[i] - want[i].at("score").get<double>());
    min_iou = std::min(min_iou, iou);
    max_score = std::max(max_score, ds);
    EXPECT_GE(iou, 0.99) << what << " box " << i;
    EXPECT_LE(ds, 1e-3) << what << " score " << i;
  }
}

TEST(TinyFaceDetector, LoadsEveryManifestWeightOnce) {
  const TfjsWeights w =
      load_tfjs_weights(face_api_manifest("tiny_face_detector_model-weights_manifest.json"));
  const TinyFaceDetector n(test::device(), w);
  const auto params = n.named_parameters();
  EXPECT_EQ(params.size(), w.size());
  std::int64_t count = 0;
  for (const auto& [name, p] : params) count += p.numel();
  EXPECT_EQ(count, w.parameter_count());
  EXPECT_EQ(count, TinyFaceDetector::kParameterCount);

  auto entries = w.entries();
  entries.emplace_back("conv6/bias", HostTensor{{2}, {0, 0}});
  try {
    TinyFaceDetector bad(test::device(), TfjsWeights(entries, "extra.json"));
    ADD_FAILURE() << "an unused weight was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("conv6/bias"), std::string::npos) << e.what();
  }
  entries = w.entries();
  entries.pop_back();  // conv8/bias
  EXPECT_THROW(TinyFaceDetector(test::device(), TfjsWeights(entries, "missing.json")),
               InvalidArgument);
}

// Per sample photo: pixels → 416² input → raw output → boxes before and after
// NMS, each step compared with face-api's, plus the decoding alone on
// face-api's own raw output (exact up to float64 rounding).
TEST(TinyFaceDetector, MatchesFaceApiOnTheSamplePhotos) {
  const json index = test::parity_index();
  ASSERT_FALSE(index.is_null());
  Stream stream(test::device());
  double max_input = 0, max_out = 0, min_iou = 1, max_score = 0;
  int images = 0;
  for (const json& image : index.at("images")) {
    const std::string name = image.at("name").get<std::string>();
    SCOPED_TRACE(name);
    const json& raw = image.at("detector_raw");
    const int input_size = raw.at("input_size").get<int>();
    const double threshold = raw.at("score_threshold").get<double>();
    const int w = image.at("width").get<int>(), h = image.at("height").get<int>();
    const Tensor pixels = image_to_device(
        test::device(), read_npy(test::parity_dir() / image.at("pixels").get<std::string>()));

    // Pad + resize.
    const Tensor input = net().preprocess(stream, pixels, input_size);
    stream.run();
    const HostTensor want_in = read_npy(test::parity_dir() / raw.at("input").get<std::string>());
    const std::vector<float> got_in = image_to_host(input).values;
    ASSERT_EQ(got_in.size(), want_in.values.size());
    for (std::size_t i = 0; i < got_in.size(); ++i) {
      max_input = std::max(max_input, double(std::abs(got_in[i] - want_in.values[i])));
    }

    // The network on face-api's own input.
    Tape tape(stream, /*recording=*/false);
    const Var out = net().forward(tape, Var(image_to_device(test::device(), want_in)));
    stream.run();
    const std::vector<float> got_out = out.value().download();
    const std::vector<float> want_out =
        hwc_to_chw(read_npy(test::parity_dir() / raw.at("output").get<std::string>()));
    ASSERT_EQ(got_out.size(), want_out.size());
    for (std::size_t i = 0; i < got_out.size(); ++i) {
      const double d = std::abs(got_out[i] - want_out[i]);
      max_out = std::max(max_out, d);
      EXPECT_LE(d, 1e-3 * std::max(1.0, double(std::abs(want_out[i])))) << "raw output " << i;
    }

    // Decoding + NMS alone on face-api's raw output reproduce its lists.
    const int cells = input_size / 32;
    const auto reshaped = tiny_yolo_reshaped_size(w, h, input_size);
    EXPECT_EQ(reshaped[0], raw.at("reshaped_width").get<int>());
    EXPECT_EQ(reshaped[1], raw.at("reshaped_height").get<int>());
    const auto exact = decode_tiny_yolo(want_out, cells, reshaped, threshold);
    ASSERT_EQ(exact.size(), raw.at("before_nms").size());
    std::vector<FaceBox> scaled;
    std::vector<double> scores;
    for (std::size_t i = 0; i < exact.size(); ++i) {
      const json& want = raw.at("before_nms")[i];
      EXPECT_EQ(exact[i].row, want.at("row").get<int>());
      EXPECT_EQ(exact[i].col, want.at("col").get<int>());
      EXPECT_EQ(exact[i].anchor, want.at("anchor").get<int>());
      EXPECT_NEAR(exact[i].score, want.at("score").get<double>(), 1e-12);
      const FaceBox rb = box_of(want.at("box_relative"));
      EXPECT_NEAR(exact[i].relative.x, rb.x, 1e-12);
      EXPECT_NEAR(exact[i].relative.y, rb.y, 1e-12);
      EXPECT_NEAR(exact[i].relative.width, rb.width, 1e-12);
      EXPECT_NEAR(exact[i].relative.height, rb.height, 1e-12);
      const FaceBox& r = exact[i].relative;
      scaled.push_back(
          FaceBox{r.x * input_size, r.y * input_size, r.width * input_size, r.height * input_size});
      scores.push_back(exact[i].score);
    }
    const auto kept = non_max_suppression(scaled, scores, raw.at("iou_threshold").get<double>());
    EXPECT_EQ(std::vector<std::size_t>(kept.begin(), kept.end()),
              raw.at("kept").get<std::vector<std::size_t>>());

    // Our whole pipeline from the pixels: candidates before NMS from our
    // output, then detect().
    const Var ours = net().forward(tape, Var(input));
    stream.run();
    const auto before = decode_tiny_yolo(ours.value().download(), cells, reshaped, threshold);
    std::vector<FaceBox> before_boxes;
    std::vector<double> before_scores;
    for (const auto& c : before) {
      before_boxes.push_back(
          FaceBox{c.relative.x * w, c.relative.y * h, c.relative.width * w, c.relative.height * h});
      before_scores.push_back(c.score);
    }
    expect_same_boxes(before_boxes, before_scores, raw.at("before_nms"), min_iou, max_score,
                      "before NMS");
    const auto dets = net().detect(stream, pixels, input_size, float(threshold));
    std::vector<FaceBox> after_boxes;
    std::vector<double> after_scores;
    for (const auto& d : dets) {
      after_boxes.push_back(d.box);
      after_scores.push_back(d.score);
    }
    expect_same_boxes(after_boxes, after_scores, raw.at("after_nms"), min_iou, max_score,
                      "after NMS");
    ++images;
  }
  EXPECT_GE(images, 1);
  EXPECT_LE(max_input, 2e-3) << "416² input (pixel values 0..255)";
  std::printf(
      "[ parity   ] %d images: input max |Δ| %.3g, raw output max |Δ| %.3g, "
      "box IoU min %.6f, score max |Δ| %.3g\n",
      images, max_input, max_out, min_iou, max_score);
}

// preprocess never builds the full padded square; it must equal the plain
// recipe (pad bottom/right to a square, one legacy bilinear resize) for
// landscape, portrait and square images, down- and upscaled.
TEST(TinyFaceDetector, PreprocessEqualsPadThenResize) {
  Stream stream(test::device());
  const std::uint32_t seed = 20261122;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const std::array<std::array<int, 3>, 6> cases = {
      {{70, 150, 64}, {150, 70, 64}, {96, 96, 64}, {37, 53, 128}, {53, 37, 128}, {64, 40, 64}}};
  for (const auto& [h, w, size] : cases) {
    SCOPED_TRACE(std::to_string(w) + "×" + std::to_string(h) + " → " + std::to_string(size));
    const auto values =
        test::random_floats(std::size_t(3) * std::size_t(h) * std::size_t(w), seed, 0.f, 255.f);
    const Tensor img = Tensor::from(test::device(), Shape{1, 3, h, w}, values);
    const Tensor got = net().preprocess(stream, img, size);
    Tape tape(stream, /*recording=*/false);
    const int side = std::max(h, w);
    Var square = pad(tape, Var(img), kernels::Pad2d{0, side - h, 0, side - w}, 0.f);
    if (side != size)
      square = resize(tape, square, kernels::ResizeMode::bilinear_legacy, size, size);
    stream.run();
    ASSERT_EQ(got.shape(), (Shape{1, 3, size, size}));
    const std::vector<float> a = got.download(), b = square.value().download();
    for (std::size_t i = 0; i < a.size(); ++i) ASSERT_NEAR(a[i], b[i], 1e-4) << "at " << i;
  }
}

// The inference path (each max pool writing into the next depthwise conv's
// padded input) against the taped path the training runs (a recording tape
// whose parameters need gradients), on random images of two sizes, batch 2.
TEST(TinyFaceDetector, InferenceMatchesTheTapedPath) {
  for (const int size : {64, 96}) {
    SCOPED_TRACE("input " + std::to_string(size));
    const auto values = test::random_floats(std::size_t(6) * std::size_t(size) * std::size_t(size),
                                            std::uint32_t(size), 0.f, 255.f);
    const Tensor x = Tensor::from(test::device(), Shape{2, 3, size, size}, values);
    const auto run = [&](bool recording) {
      Stream stream(test::device());
      Tape tape(stream, recording);
      const Var out = net().forward(tape, Var(x));
      stream.run();
      return out.value().download();
    };
    const std::vector<float> taped = run(true), inferred = run(false);
    ASSERT_EQ(taped.size(), inferred.size());
    double worst = 0;
    for (std::size_t i = 0; i < taped.size(); ++i) {
      worst = std::max(worst, std::fabs(double(taped[i]) - inferred[i]));
    }
    EXPECT_LT(worst, 1e-4);  // the same operations in the same order: rounding only
  }
}

TEST(TinyFaceDetector, FindsNoFaceInAFlatGreyImage) {
  Stream stream(test::device());
  const Tensor grey =
      Tensor::from(test::device(), Shape{1, 3, 240, 320}, std::vector<float>(3 * 240 * 320, 128.f));
  EXPECT_TRUE(net().detect(stream, grey, 320).empty());
  EXPECT_TRUE(net().detect(stream, grey, 416, 0.3f).empty());
}

TEST(TinyFaceDetector, NmsKeepsTheBestOfOverlappingBoxes) {
  // 0 and 1 overlap with IoU 81/119 > 0.4; 2 is apart; 3 touches 0 at IoU 1/3.
  const std::vector<FaceBox> boxes = {
      {0, 0, 10, 10}, {1, 1, 10, 10}, {50, 50, 10, 10}, {5, 0, 10, 10}};
  EXPECT_NEAR(box_iou(boxes[0], boxes[1]), 81.0 / 119.0, 1e-12);
  EXPECT_NEAR(box_iou(boxes[0], boxes[3]), 50.0 / 150.0, 1e-12);
  EXPECT_EQ(box_iou(boxes[0], boxes[2]), 0.0);
  const std::vector<double> scores = {0.6, 0.9, 0.7, 0.8};
  EXPECT_EQ(non_max_suppression(boxes, scores, 0.4), (std::vector<std::size_t>{1, 3, 2}));
  // Equal scores: the later index is picked first (ascending sort + pop).
  const std::vector<double> ties = {0.5, 0.5, 0.5, 0.5};
  EXPECT_EQ(non_max_suppression(boxes, ties, 0.4), (std::vector<std::size_t>{3, 2, 1}));
  EXPECT_THROW(non_max_suppression(boxes, std::vector<double>{0.5}, 0.4), InvalidArgument);
}

TEST(TinyFaceDetector, DecodesCellsAnchorsAndThePadding) {
  // One cell grid of 2×2; only anchor 1 at row 1, col 0 scores: t = 0 puts the
  // centre in the middle of the cell, size = anchor / cells.
  const int cells = 2;
  std::vector<float> out(std::size_t(25 * cells * cells), 0.f);
  // Objectness (channel a·5 + 4) off everywhere but anchor 1 at cell index 2
  // (row 1, col 0).
  for (std::size_t a = 0; a < 5; ++a) {
    for (std::size_t cell = 0; cell < 4; ++cell) {
      out[(a * 5 + 4) * 4 + cell] = a == 1 && cell == 2 ? 3.f : -20.f;
    }
  }
  // A 64-wide, 32-high image at input 64: reshaped 64×32, so y is stretched ×2.
  const auto c = decode_tiny_yolo(out, cells, {64, 32}, 0.5);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].row, 1);
  EXPECT_EQ(c[0].col, 0);
  EXPECT_EQ(c[0].anchor, 1);
  EXPECT_NEAR(c[0].score, 1 / (1 + std::exp(-3.0)), 1e-12);
  const double bw = kTinyFaceAnchors[1][0] / cells, bh = kTinyFaceAnchors[1][1] / cells * 2;
  EXPECT_NEAR(c[0].relative.width, bw, 1e-12);
  EXPECT_NEAR(c[0].relative.height, bh, 1e-12);
  EXPECT_NEAR(c[0].relative.x, 0.25 - bw / 2, 1e-12);
  EXPECT_NEAR(c[0].relative.y, 0.75 * 2 - bh / 2, 1e-12);
  EXPECT_EQ(tiny_yolo_reshaped_size(1920, 1280, 416), (std::array<int, 2>{416, 277}));
  EXPECT_THROW(decode_tiny_yolo(out, 3, {64, 32}, 0.5), InvalidArgument);
}

TEST(TinyFaceDetector, RejectsBadInputsWithClearErrors) {
  Stream stream(test::device());
  const Device& d = test::device();
  const Tensor img = Tensor::from(d, Shape{1, 3, 40, 50}, std::vector<float>(6000, 90.f));
  try {
    (void)net().detect(stream, img, 100);
    ADD_FAILURE() << "input size 100 was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("multiple of 32"), std::string::npos) << e.what();
  }
  EXPECT_THROW(net().detect(stream, img, 0), InvalidArgument);
  EXPECT_THROW(net().detect(stream, img, -32), InvalidArgument);
  EXPECT_THROW(net().detect(stream, img, 416, 0.f), InvalidArgument);
  EXPECT_THROW(net().detect(stream, img, 416, 1.f), InvalidArgument);
  EXPECT_THROW(net().detect(stream, img, 416, std::nanf("")), InvalidArgument);
  // Empty / wrong images.
  EXPECT_THROW(net().detect(stream, Tensor()), InvalidArgument);
  EXPECT_THROW(net().detect(stream, Tensor::empty(d, Shape{1, 1, 40, 50})), InvalidArgument);
  EXPECT_THROW(net().detect(stream, Tensor::empty(d, Shape{2, 3, 40, 50})), InvalidArgument);
  EXPECT_THROW(tiny_yolo_reshaped_size(0, 10, 416), InvalidArgument);
  // The network itself wants a square multiple of 32.
  Tape tape(stream, /*recording=*/false);
  EXPECT_THROW(net().forward(tape, Var(Tensor::empty(d, Shape{1, 3, 40, 40}))), InvalidArgument);
  EXPECT_THROW(net().forward(tape, Var(Tensor::empty(d, Shape{1, 3, 64, 32}))), InvalidArgument);
  // NaN pixels.
  std::vector<float> nan_pixels(6000, 90.f);
  nan_pixels[100] = std::nanf("");
  EXPECT_THROW(net().detect(stream, Tensor::from(d, Shape{1, 3, 40, 50}, nan_pixels), 64),
               InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::nets
