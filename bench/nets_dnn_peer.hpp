// nets_bench's OpenCV peer: face-api's three networks built layer by layer
// through the cv::dnn API from the same TF.js weights, so that OpenCV DNN
// runs exactly the network vkjr2 runs (nets_bench checks the outputs agree
// before timing).
#pragma once

#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/kernels/pool.hpp>
#include <vkjr2/nets/tfjs_weights.hpp>

#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>

#include <array>
#include <string>
#include <vector>

namespace vkjr2::bench {

// face-api's input means: landmarks and recognition; the tiny detector.
inline constexpr std::array<float, 3> kFaceMeanRgb = {122.782f, 117.001f, 104.298f};
inline constexpr std::array<float, 3> kDetectorMeanRgb = {117.001f, 114.697f, 97.404f};
inline constexpr float kLeakySlope = 0.1f;

// Builds a cv::dnn::Net layer by layer from TF.js weights (HWIO → OIHW), tracks
// each output's shape, and counts the FLOPs (2·MACs) of convolutions and FC.
class DnnBuilder {
 public:
  struct Blob {
    int layer = 0;
    int c = 0, h = 0, w = 0;
  };
  enum class Act { none, relu, leaky };

  DnnBuilder(const nets::TfjsWeights& weights, int c, int h, int w)
      : weights_(weights), input_{0, c, h, w} {}

  Blob input() const { return input_; }
  cv::dnn::Net& net() { return net_; }
  double flops() const { return flops_; }

  // (x − mean) / 255 as a Scale layer with bias.
  Blob normalize(const Blob& x, const std::array<float, 3>& mean) {
    cv::Mat scale(1, 3, CV_32F), shift(1, 3, CV_32F);
    for (int c = 0; c < 3; ++c) {
      scale.at<float>(c) = 1.f / 255.f;
      shift.at<float>(c) = -mean[std::size_t(c)] / 255.f;
    }
    return scale_layer(x, scale, shift);
  }

  Blob scale(const Blob& x, const std::string& weights, const std::string& biases) {
    return scale_layer(x, row(take(weights, {x.c})), row(take(biases, {x.c})));
  }

  // Convolution from a TF.js filter [kh, kw, cin, cout] (or a depthwise one
  // [kh, kw, C, 1] when depthwise), optional bias, explicit asymmetric pads.
  Blob conv(const Blob& x, const std::string& filter, const std::string& bias, int stride,
            const kernels::Padding2d& pad, bool depthwise, Act act) {
    const HostTensor& f = weights_.at(filter);
    const int kh = int(f.shape.at(0)), kw = int(f.shape.at(1));
    const int cin = int(f.shape.at(2));
    const int cout = depthwise ? cin * int(f.shape.at(3)) : int(f.shape.at(3));
    const int group = depthwise ? cin : 1;
    require(cin == x.c, filter + " expects " + std::to_string(cin) + " input channels, got " +
                            std::to_string(x.c));
    const int per_group = cin / group;
    const int oihw_shape[] = {cout, per_group, kh, kw};
    cv::Mat oihw(4, oihw_shape, CV_32F);
    auto* o = oihw.ptr<float>();
    for (int oc = 0; oc < cout; ++oc)
      for (int ic = 0; ic < per_group; ++ic)
        for (int y = 0; y < kh; ++y)
          for (int xx = 0; xx < kw; ++xx) {
            // Depthwise: output channel oc reads input channel oc (multiplier 1).
            const std::size_t tap = std::size_t(y) * std::size_t(kw) + std::size_t(xx);
            const std::size_t src =
                depthwise ? tap * std::size_t(cin) + std::size_t(oc)
                          : (tap * std::size_t(cin) + std::size_t(ic)) * std::size_t(cout) +
                                std::size_t(oc);
            o[((oc * per_group + ic) * kh + y) * kw + xx] = f.values[src];
          }
    // OpenCV 4.6's Convolution rejects asymmetric pads ("Unsupported asymmetric
    // padding"): pad with a Padding layer first, then convolve unpadded.
    Blob in = x;
    kernels::Padding2d conv_pad = pad;
    if (pad.top != pad.bottom || pad.left != pad.right) {
      in = zero_pad(x, pad);
      conv_pad = {};
    }
    cv::dnn::LayerParams lp;
    lp.set("kernel_h", kh);
    lp.set("kernel_w", kw);
    lp.set("stride", stride);
    set_pads(lp, conv_pad);
    lp.set("num_output", cout);
    lp.set("group", group);
    lp.set("bias_term", !bias.empty());
    lp.blobs.push_back(oihw);
    if (!bias.empty()) lp.blobs.push_back(row(take(bias, {cout})));
    const int oh = (x.h + pad.top + pad.bottom - kh) / stride + 1;
    const int ow = (x.w + pad.left + pad.right - kw) / stride + 1;
    flops_ += 2.0 * double(cout) * per_group * kh * kw * oh * ow;
    Blob y = add_layer("Convolution", lp, {in}, cout, oh, ow);
    return activation(y, act);
  }

  Blob activation(const Blob& x, Act act) {
    if (act == Act::none) return x;
    cv::dnn::LayerParams lp;
    if (act == Act::leaky) lp.set("negative_slope", kLeakySlope);
    return add_layer("ReLU", lp, {x}, x.c, x.h, x.w);
  }

  Blob pool(const Blob& x, bool max, int kernel, int stride, const kernels::Padding2d& pad) {
    cv::dnn::LayerParams lp;
    lp.set("pool", max ? "MAX" : "AVE");
    lp.set("kernel_size", kernel);
    lp.set("stride", stride);
    set_pads(lp, pad);
    lp.set("ceil_mode", false);  // Caffe's default is ceil; TF uses floor
    return add_layer("Pooling", lp, {x}, x.c, (x.h + pad.top + pad.bottom - kernel) / stride + 1,
                     (x.w + pad.left + pad.right - kernel) / stride + 1);
  }

  Blob global_average(const Blob& x) {
    cv::dnn::LayerParams lp;
    lp.set("pool", "AVE");
    lp.set("global_pooling", true);
    return add_layer("Pooling", lp, {x}, x.c, 1, 1);
  }

  // Zero rows and columns around the image (a Padding layer).
  Blob zero_pad(const Blob& x, const kernels::Padding2d& p) {
    cv::dnn::LayerParams lp;
    const int paddings[] = {0, 0, 0, 0, p.top, p.bottom, p.left, p.right};
    lp.set("paddings", cv::dnn::DictValue::arrayInt(paddings, 8));
    lp.set("value", 0.f);
    return add_layer("Padding", lp, {x}, x.c, x.h + p.top + p.bottom, x.w + p.left + p.right);
  }

  // a + b. When b has fewer channels it is added to a's first channels, i.e.
  // b is zero-extended (face-api's concat with zeros in residualDown).
  Blob add(const Blob& a, const Blob& b) {
    require(a.h == b.h && a.w == b.w && a.c >= b.c, "add: shapes differ");
    cv::dnn::LayerParams lp;
    lp.set("operation", "sum");
    if (a.c != b.c) lp.set("output_channels_mode", "input_0");
    return add_layer("Eltwise", lp, {a, b}, a.c, a.h, a.w);
  }

  // y = x · W (+ b) with TF.js's W [in, out].
  Blob fc(const Blob& x, const std::string& weights, const std::string& bias) {
    const HostTensor& w = weights_.at(weights);
    const int in = int(w.shape.at(0)), out = int(w.shape.at(1));
    require(in == x.c * x.h * x.w, weights + ": input size mismatch");
    cv::Mat wt(out, in, CV_32F);
    for (int i = 0; i < in; ++i)
      for (int o = 0; o < out; ++o)
        wt.at<float>(o, i) = w.values[std::size_t(i) * std::size_t(out) + std::size_t(o)];
    cv::dnn::LayerParams lp;
    lp.set("num_output", out);
    lp.set("bias_term", !bias.empty());
    lp.set("axis", 1);
    lp.blobs.push_back(wt);
    if (!bias.empty()) lp.blobs.push_back(row(take(bias, {out})));
    flops_ += 2.0 * in * out;
    return add_layer("InnerProduct", lp, {x}, out, 1, 1);
  }

 private:
  static void require(bool ok, const std::string& what) {
    if (!ok) throw Error("nets_bench", "OpenCV DNN graph: " + what, "fix the graph builder");
  }

  const HostTensor& take(const std::string& name, const std::vector<std::int64_t>& shape) {
    const HostTensor& t = weights_.at(name);
    require(t.shape == shape, name + " has shape " + vkjr2::shape_str(t.shape) + ", expected " +
                                  vkjr2::shape_str(shape));
    return t;
  }

  static cv::Mat row(const HostTensor& t) {
    return cv::Mat(1, int(t.values.size()), CV_32F, const_cast<float*>(t.values.data())).clone();
  }

  static void set_pads(cv::dnn::LayerParams& lp, const kernels::Padding2d& p) {
    lp.set("pad_t", p.top);
    lp.set("pad_b", p.bottom);
    lp.set("pad_l", p.left);
    lp.set("pad_r", p.right);
  }

  Blob scale_layer(const Blob& x, const cv::Mat& scale, const cv::Mat& shift) {
    cv::dnn::LayerParams lp;
    lp.set("bias_term", true);
    lp.set("axis", 1);
    lp.blobs = {scale, shift};
    return add_layer("Scale", lp, {x}, x.c, x.h, x.w);
  }

  Blob add_layer(const std::string& type, cv::dnn::LayerParams& lp, const std::vector<Blob>& inputs,
                 int c, int h, int w) {
    lp.type = type;
    lp.name = type + "_" + std::to_string(++count_);
    const int id = net_.addLayer(lp.name, lp.type, lp);
    for (std::size_t i = 0; i < inputs.size(); ++i) net_.connect(inputs[i].layer, 0, id, int(i));
    require(h > 0 && w > 0, lp.name + " has an empty output");
    return Blob{id, c, h, w};
  }

  const nets::TfjsWeights& weights_;
  Blob input_;
  cv::dnn::Net net_;
  double flops_ = 0;
  int count_ = 0;
};

// FaceRecognitionNet at 150², FaceLandmark68Net at 112², TinyFaceDetector at size².
DnnBuilder build_recognition(const nets::TfjsWeights& w);
DnnBuilder build_landmarks(const nets::TfjsWeights& w);
DnnBuilder build_detector(const nets::TfjsWeights& w, int size);
// CPU target, OpenCV's own backend; one warm-up forward happens in the first timed run.
void prepare(cv::dnn::Net& net);
// A float Mat's values in memory order.
std::vector<float> mat_values(const cv::Mat& m);
// One forward of blob (NCHW) → the output's values.
std::vector<float> dnn_forward(cv::dnn::Net& net, const cv::Mat& blob);

}  // namespace vkjr2::bench
