#include "nets_dnn_peer.hpp"

#include <string>
#include <vector>

namespace vkjr2::bench {
namespace {

kernels::Padding2d same3(const DnnBuilder::Blob& x, int stride) {
  return kernels::same_padding(x.h, x.w, 3, 3, stride, stride);
}

kernels::Padding2d pool_pads(const kernels::Pool2d& p) {
  return {p.pad_top, p.pad_bottom, p.pad_left, p.pad_right};
}

}  // namespace

// FaceRecognitionNet (faceRecognitionNet/*.ts): see nets/face_recognition.cpp.

DnnBuilder build_recognition(const nets::TfjsWeights& w) {
  DnnBuilder b(w, 3, 150, 150);
  using Act = DnnBuilder::Act;
  const auto conv_layer = [&](const DnnBuilder::Blob& x, const std::string& name, bool down,
                              bool relu) {
    const kernels::Padding2d pad =
        down ? kernels::Padding2d{} : kernels::same_padding(x.h, x.w, 3, 3, 1, 1);
    DnnBuilder::Blob y =
        b.conv(x, name + "/conv/filters", name + "/conv/bias", down ? 2 : 1, pad, false, Act::none);
    y = b.scale(y, name + "/scale/weights", name + "/scale/biases");
    return b.activation(y, relu ? Act::relu : Act::none);
  };
  DnnBuilder::Blob x = b.normalize(b.input(), kFaceMeanRgb);
  x = conv_layer(x, "conv32_down", true, true);  // 7×7/2 valid
  x = b.pool(x, true, 3, 2, {});
  const std::array<std::pair<const char*, bool>, 14> blocks = {{
      {"conv32_1", false},
      {"conv32_2", false},
      {"conv32_3", false},
      {"conv64_down", true},
      {"conv64_1", false},
      {"conv64_2", false},
      {"conv64_3", false},
      {"conv128_down", true},
      {"conv128_1", false},
      {"conv128_2", false},
      {"conv256_down", true},
      {"conv256_1", false},
      {"conv256_2", false},
      {"conv256_down_out", true},
  }};
  for (const auto& [name, down] : blocks) {
    DnnBuilder::Blob out = conv_layer(x, std::string(name) + "/conv1", down, true);
    out = conv_layer(out, std::string(name) + "/conv2", false, false);
    DnnBuilder::Blob shortcut = x;
    if (down) {
      shortcut = b.pool(x, false, 2, 2, {});
      if (shortcut.h != out.h || shortcut.w != out.w) {
        out = b.zero_pad(out, {0, shortcut.h - out.h, 0, shortcut.w - out.w});
      }
    }
    x = b.activation(b.add(out, shortcut), Act::relu);
  }
  x = b.global_average(x);
  b.fc(x, "fc", "");
  return b;
}

namespace {

// Depthwise 3×3 (no bias) + pointwise 1×1 + bias + activation.
DnnBuilder::Blob separable(DnnBuilder& b, const DnnBuilder::Blob& x, const std::string& name,
                           int stride, const kernels::Padding2d& pad, DnnBuilder::Act act) {
  const DnnBuilder::Blob mid =
      b.conv(x, name + "/depthwise_filter", "", stride, pad, true, DnnBuilder::Act::none);
  return b.conv(mid, name + "/pointwise_filter", name + "/bias", 1, {}, false, act);
}

}  // namespace

// FaceLandmark68Net (faceFeatureExtractor/denseBlock.ts): see nets/face_landmarks.cpp.

DnnBuilder build_landmarks(const nets::TfjsWeights& w) {
  DnnBuilder b(w, 3, 112, 112);
  using Act = DnnBuilder::Act;
  DnnBuilder::Blob x = b.normalize(b.input(), kFaceMeanRgb);
  for (int i = 0; i < 4; ++i) {
    const std::string name = "dense" + std::to_string(i);
    const DnnBuilder::Blob out1 = i == 0
                                      ? b.conv(x, name + "/conv0/filters", name + "/conv0/bias", 2,
                                               same3(x, 2), false, Act::relu)
                                      : separable(b, x, name + "/conv0", 2, same3(x, 2), Act::relu);
    DnnBuilder::Blob sum = out1;
    for (int k = 1; k <= 3; ++k) {
      const DnnBuilder::Blob in = k == 1 ? out1 : b.activation(sum, Act::relu);
      sum = b.add(sum,
                  separable(b, in, name + "/conv" + std::to_string(k), 1, same3(in, 1), Act::none));
    }
    x = b.activation(sum, Act::relu);
  }
  x = b.pool(x, false, 7, 2, {});
  b.fc(x, "fc/weights", "fc/bias");
  return b;
}

// TinyFaceDetector (tinyYolov2/TinyYolov2Base.ts runMobilenet): see nets/tiny_face_detector.cpp.

DnnBuilder build_detector(const nets::TfjsWeights& w, int size) {
  DnnBuilder b(w, 3, size, size);
  using Act = DnnBuilder::Act;
  DnnBuilder::Blob x = b.normalize(b.input(), kDetectorMeanRgb);
  x = b.conv(x, "conv0/filters", "conv0/bias", 1, {}, false, Act::leaky);
  for (int i = 1; i <= 5; ++i) {
    x = b.pool(x, true, 2, 2, pool_pads(kernels::pool_same(2, 2, 2, 2, x.h, x.w)));
    x = separable(b, x, "conv" + std::to_string(i), 1, {1, 1, 1, 1}, Act::leaky);
  }
  x = b.pool(x, true, 2, 1, pool_pads(kernels::pool_same(2, 2, 1, 1, x.h, x.w)));
  b.conv(x, "conv8/filters", "conv8/bias", 1, {}, false, Act::none);
  return b;
}

std::vector<float> mat_values(const cv::Mat& m) {
  const cv::Mat c = m.isContinuous() ? m : m.clone();
  return {c.ptr<float>(), c.ptr<float>() + c.total()};
}

void prepare(cv::dnn::Net& net) {
  net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
}

std::vector<float> dnn_forward(cv::dnn::Net& net, const cv::Mat& blob) {
  net.setInput(blob);
  return mat_values(net.forward());
}

}  // namespace vkjr2::bench
