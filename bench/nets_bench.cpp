// nets_bench: face-api's three networks (FaceRecognitionNet 150×150,
// FaceLandmark68Net 112×112, TinyFaceDetector at 416) on vkjr2, each timed in
// the same run against
//   - face-api itself on TF.js WASM (bench/faceapi_bench.mjs, run through node),
//   - OpenCV DNN running the same network with the same weights, built layer by
//     layer through the cv::dnn API (checked to reproduce our output first).
// Prints a table and writes JSON (issue 4, section Benchmark).
#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/kernels/pool.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/nets/face_landmarks.hpp>
#include <vkjr2/nets/face_recognition.hpp>
#include <vkjr2/nets/npy.hpp>
#include <vkjr2/nets/tfjs_weights.hpp>
#include <vkjr2/nets/tiny_face_detector.hpp>

#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "harness.hpp"

#ifndef VKJR2_SOURCE_DIR
#define VKJR2_SOURCE_DIR "."
#endif

namespace vkjr2 {
namespace {

namespace fs = std::filesystem;
using nets::HostTensor;

constexpr std::array<float, 3> kFaceMeanRgb = {122.782f, 117.001f,
                                               104.298f};  // landmarks, recognition
constexpr std::array<float, 3> kDetectorMeanRgb = {117.001f, 114.697f, 97.404f};
constexpr float kLeakySlope = 0.1f;
constexpr int kBatch = 8;

struct Options {
  std::string json_path = "nets_bench.json";
  int runs = 7;
  int warmup = 2;
  bool tfjs = true;
  bool profile = false;
  std::string faceapi_script = std::string(VKJR2_SOURCE_DIR) + "/bench/faceapi_bench.mjs";
};

std::string load_average() {
  std::ifstream f("/proc/loadavg");
  std::string a, b, c;
  f >> a >> b >> c;
  return f ? a + " " + b + " " + c : std::string("unknown");
}

fs::path parity_dir() {
  if (const char* d = std::getenv("VKJR2_PARITY_DIR"); d != nullptr && *d != '\0') return d;
  if (const char* c = std::getenv("VKJR2_CACHE_DIR"); c != nullptr && *c != '\0') {
    return fs::path(c) / "parity";
  }
  const char* home = std::getenv("HOME");
  return fs::path(home != nullptr ? home : ".") / ".cache" / "vkjr2" / "parity";
}

HostTensor read_parity(const fs::path& dir, const std::string& file) {
  const fs::path p = dir / file;
  if (!fs::exists(p)) {
    throw InvalidArgument("nets_bench", "parity reference " + p.string() + " is missing",
                          "run scripts/setup (it writes the face-api references), or point "
                          "VKJR2_PARITY_DIR at a reference directory");
  }
  return nets::read_npy(p);
}

// HWC images of one size → NCHW floats, batch in order.
std::vector<float> hwc_to_nchw(const std::vector<const HostTensor*>& images) {
  std::vector<float> out;
  for (const HostTensor* img : images) {
    const auto h = std::size_t(img->shape[0]), w = std::size_t(img->shape[1]),
               c = std::size_t(img->shape[2]);
    const std::size_t base = out.size();
    out.resize(base + c * h * w);
    for (std::size_t y = 0; y < h; ++y)
      for (std::size_t x = 0; x < w; ++x)
        for (std::size_t k = 0; k < c; ++k)
          out[base + (k * h + y) * w + x] = img->values[(y * w + x) * c + k];
  }
  return out;
}

cv::Mat hwc_mat(const HostTensor& img) {
  return cv::Mat(int(img.shape[0]), int(img.shape[1]), CV_32FC3,
                 const_cast<float*>(img.values.data()))
      .clone();
}

cv::Mat nchw_blob(const std::vector<float>& v, int n, int c, int h, int w) {
  const int shape[] = {n, c, h, w};
  return cv::Mat(4, shape, CV_32F, const_cast<float*>(v.data())).clone();
}

double max_abs_diff(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size()) return INFINITY;
  double m = 0;
  for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, double(std::abs(a[i] - b[i])));
  return m;
}

std::vector<float> mat_values(const cv::Mat& m) {
  const cv::Mat c = m.isContinuous() ? m : m.clone();
  return {c.ptr<float>(), c.ptr<float>() + c.total()};
}

// One timed run: the seconds it took.
using Timed = std::function<double()>;

Timed wall(std::function<void()> fn) {
  return [fn = std::move(fn)] { return bench::seconds_of(fn); };
}

// Seconds of each run of each function, their runs interleaved (f0, f1, …,
// f0, f1, …) so that all see the same load on this shared machine; in run order.
std::vector<std::vector<double>> time_interleaved(const std::vector<Timed>& fns, int reps,
                                                  int warmup) {
  for (int i = 0; i < warmup; ++i) {
    for (const Timed& f : fns) f();
  }
  std::vector<std::vector<double>> t(fns.size());
  for (int i = 0; i < reps; ++i) {
    for (std::size_t k = 0; k < fns.size(); ++k) t[k].push_back(fns[k]());
  }
  return t;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 == 1 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

// ---- the same networks through the cv::dnn API ------------------------------------

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
    require(t.shape == shape, name + " has shape " + nets::shape_str(t.shape) + ", expected " +
                                  nets::shape_str(shape));
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

kernels::Padding2d same3(const DnnBuilder::Blob& x, int stride) {
  return kernels::same_padding(x.h, x.w, 3, 3, stride, stride);
}

kernels::Padding2d pool_pads(const kernels::Pool2d& p) {
  return {p.pad_top, p.pad_bottom, p.pad_left, p.pad_right};
}

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

// Depthwise 3×3 (no bias) + pointwise 1×1 + bias + activation.
DnnBuilder::Blob separable(DnnBuilder& b, const DnnBuilder::Blob& x, const std::string& name,
                           int stride, const kernels::Padding2d& pad, DnnBuilder::Act act) {
  const DnnBuilder::Blob mid =
      b.conv(x, name + "/depthwise_filter", "", stride, pad, true, DnnBuilder::Act::none);
  return b.conv(mid, name + "/pointwise_filter", name + "/bias", 1, {}, false, act);
}

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

void prepare(cv::dnn::Net& net) {
  net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
}

std::vector<float> dnn_forward(cv::dnn::Net& net, const cv::Mat& blob) {
  net.setInput(blob);
  return mat_values(net.forward());
}

// ---- the TF.js peer ------------------------------------------------------------------

// face-api on TF.js in a node process (faceapi_bench.mjs --serve) that times
// one run per request, so that its runs interleave with ours and both see
// the same load on this shared machine (its speed drifts up to 2× within
// minutes). Unavailable (reason() says why) when node, the script or its
// packages are missing, or the process dies.
class TfjsServer {
 public:
  explicit TfjsServer(const Options& o) {
    if (!o.tfjs) {
      reason_ = "skipped (--no-tfjs)";
      return;
    }
    if (std::system("command -v node > /dev/null 2>&1") != 0) {
      reason_ = "node is not installed (apt-get install nodejs, then scripts/setup)";
      return;
    }
    if (!fs::exists(o.faceapi_script)) {
      reason_ = o.faceapi_script + " not found (pass --faceapi-script PATH)";
      return;
    }
    std::signal(SIGPIPE, SIG_IGN);  // a dead server is an error below, not a signal
    int to_child[2], from_child[2];
    if (::pipe(to_child) != 0) {
      reason_ = "cannot make pipes to node";
      return;
    }
    if (::pipe(from_child) != 0) {
      ::close(to_child[0]);
      ::close(to_child[1]);
      reason_ = "cannot make pipes to node";
      return;
    }
    // No warm-ups at start: time_interleaved warms every peer up, this one too.
    std::fprintf(stderr, "nets_bench: node %s --serve --warmup 0\n", o.faceapi_script.c_str());
    std::fflush(stdout);  // the child must not inherit unwritten output
    std::fflush(stderr);
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(to_child[0], 0);
      ::dup2(from_child[1], 1);
      ::dup2(from_child[1], 2);  // its errors come back as lines too
      ::close(to_child[1]);
      ::close(from_child[0]);
      ::execlp("node", "node", o.faceapi_script.c_str(), "--serve", "--warmup", "0",
               static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(to_child[0]);
    ::close(from_child[1]);
    if (pid_ < 0) {
      ::close(to_child[1]);
      ::close(from_child[0]);
      reason_ = "cannot start node";
      return;
    }
    to_ = ::fdopen(to_child[1], "w");
    from_ = ::fdopen(from_child[0], "r");
    try {
      const nlohmann::json ready = read_reply("ready");
      about_ = ready;
      about_.erase("ready");
      peer_ = ready.at("peer").get<std::string>();
    } catch (const std::exception& e) {
      reason_ = std::string(e.what()) + " (scripts/setup installs node and face-api's packages)";
      stop();
    }
  }
  ~TfjsServer() { stop(); }
  TfjsServer(const TfjsServer&) = delete;
  TfjsServer& operator=(const TfjsServer&) = delete;

  bool available() const { return !peer_.empty(); }
  const std::string& reason() const { return reason_; }
  const std::string& peer() const { return peer_; }  // "face-api 1.7.15 / TF.js 4.22.0 wasm …"
  const nlohmann::json& about() const { return about_; }  // backend, SIMD, threads, node, machine

  // Seconds of one run of the script's benchmark `name`, as node timed it
  // (the pipe's round trip is not counted).
  double run(const std::string& name) {
    if (!available()) throw InvalidArgument("nets_bench", "the TF.js peer is unavailable");
    if (std::fprintf(to_, "%s\n", name.c_str()) < 0 || std::fflush(to_) != 0) {
      throw InvalidArgument("nets_bench", "the TF.js peer (node) stopped reading requests");
    }
    try {
      return read_reply("name").at("ms").get<double>() * 1e-3;
    } catch (const std::exception& e) {
      throw InvalidArgument("nets_bench", "the TF.js peer failed timing " + name + ": " + e.what(),
                            "run node bench/faceapi_bench.mjs alone to see why, or pass --no-tfjs");
    }
  }

 private:
  // The next JSON reply holding `key`; other lines (node's own messages)
  // are echoed. Throws (std::runtime_error) with the last line seen when
  // the process ends, or with its error reply.
  nlohmann::json read_reply(const char* key) {
    std::string last;
    char* line = nullptr;
    std::size_t cap = 0;
    ssize_t n = 0;
    while ((n = ::getline(&line, &cap, from_)) > 0) {
      std::string text(line, std::size_t(n));
      while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
      nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
      if (j.is_object() && j.contains(key)) {
        std::free(line);
        return j;
      }
      if (j.is_object() && j.contains("error")) {
        std::free(line);
        throw std::runtime_error("faceapi_bench.mjs: " + j.at("error").get<std::string>());
      }
      std::fprintf(stderr, "  | %s\n", text.c_str());
      if (!text.empty()) last = text;
    }
    std::free(line);
    throw std::runtime_error("faceapi_bench.mjs ended" + (last.empty() ? "" : ": " + last));
  }

  void stop() {
    if (to_ != nullptr) {
      std::fputs("quit\n", to_);
      std::fclose(to_);
      to_ = nullptr;
    }
    if (from_ != nullptr) {
      std::fclose(from_);
      from_ = nullptr;
    }
    if (pid_ > 0) {
      ::waitpid(pid_, nullptr, 0);
      pid_ = -1;
    }
  }

  pid_t pid_ = -1;
  FILE* to_ = nullptr;
  FILE* from_ = nullptr;
  std::string reason_, peer_;
  nlohmann::json about_;
};

// ---- the benchmark -------------------------------------------------------------------

struct NetReport {
  std::string net;
  double flops = 0;         // per face (per image for the detector)
  double opencv_flops = 0;  // cv::dnn::Net::getFLOPS, all layers (cross-check)
  double vk_ms = 0, cv_ms = 0;
  double tf_ms = 0;                // 0: the TF.js peer is unavailable
  std::vector<double> tf_over_vk;  // per interleaved run, TF.js time / vkjr2 time
  double vk_batch_fps = 0, cv_batch_fps = 0;
  double tf_batch_fps = 0;               // 0: the TF.js peer is unavailable
  std::vector<double> tf_over_vk_batch;  // per interleaved batch run, TF.js time / vkjr2 time
  double check_vk_vs_cv = 0;             // max abs diff, same input
  double check_vk_vs_faceapi = 0;        // max abs diff vs face-api's reference output
  double check_batch = 0;                // batch item 0 vs the single run
  std::string note;
};

bench::Result ms_row(const std::string& name, double vk_ms, const std::string& peer, double peer_ms,
                     double flops, double peak_gflops) {
  bench::Result r{name, vk_ms, "ms", peer, peer_ms};
  r.higher_is_better = false;
  if (flops > 0) r.fraction_of_device_peak = flops / (vk_ms * 1e-3) * 1e-9 / peak_gflops;
  return r;
}

// Median seconds of vkjr2, OpenCV and, when it is available, the TF.js
// peer's benchmark `tf_name` (0 when not), their runs interleaved, and each
// run's TF.js / vkjr2 time ratio.
struct PeerTimes {
  double vk = 0, cv = 0, tf = 0;
  std::vector<double> tf_over_vk;
};

PeerTimes time_peers(const std::function<void()>& vk, const std::function<void()>& cv,
                     TfjsServer& tf, const std::string& tf_name, const Options& o) {
  std::vector<Timed> fns = {wall(vk), wall(cv)};
  if (tf.available()) fns.emplace_back([&] { return tf.run(tf_name); });
  const auto t = time_interleaved(fns, o.runs, o.warmup);
  PeerTimes p{median(t[0]), median(t[1])};
  if (t.size() > 2) {
    p.tf = median(t[2]);
    for (std::size_t i = 0; i < t[0].size(); ++i) p.tf_over_vk.push_back(t[2][i] / t[0][i]);
  }
  return p;
}

// The single-face timing, in ms.
void time_single(NetReport& r, const std::function<void()>& vk, const std::function<void()>& cv,
                 TfjsServer& tf, const std::string& tf_name, const Options& o) {
  PeerTimes p = time_peers(vk, cv, tf, tf_name, o);
  r.vk_ms = p.vk * 1e3;
  r.cv_ms = p.cv * 1e3;
  r.tf_ms = p.tf * 1e3;
  r.tf_over_vk = std::move(p.tf_over_vk);
}

// The batch timing (kBatch faces, net only), in faces per second.
void time_batch(NetReport& r, const std::function<void()>& vk, const std::function<void()>& cv,
                TfjsServer& tf, const std::string& tf_name, const Options& o) {
  PeerTimes p = time_peers(vk, cv, tf, tf_name, o);
  r.vk_batch_fps = kBatch / p.vk;
  r.cv_batch_fps = kBatch / p.cv;
  r.tf_batch_fps = p.tf > 0 ? kBatch / p.tf : 0;
  r.tf_over_vk_batch = std::move(p.tf_over_vk);
}

std::vector<const HostTensor*> pick(const std::vector<HostTensor>& all) {
  std::vector<const HostTensor*> out;
  for (int i = 0; i < kBatch; ++i) out.push_back(&all[std::size_t(i) % all.size()]);
  return out;
}

// Reference arrays of one kind from every face in the parity directory.
std::vector<HostTensor> all_faces(const fs::path& dir, const std::string& suffix) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (n.size() > suffix.size() && n.compare(n.size() - suffix.size(), suffix.size(), suffix) == 0)
      files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  std::vector<HostTensor> out;
  for (const auto& f : files) out.push_back(nets::read_npy(f));
  if (out.empty()) {
    throw InvalidArgument("nets_bench", "no *" + suffix + " in " + dir.string(),
                          "re-run scripts/setup to regenerate the parity references");
  }
  return out;
}

std::vector<float> vk_run(Stream& s, const std::function<nets::Var(nets::Tape&)>& fn) {
  nets::Tape t(s, /*recording=*/false);
  const nets::Var y = fn(t);
  s.run();
  return y.value().download();
}

NetReport bench_recognition(const Device& dev, const fs::path& dir, const nlohmann::json& index,
                            const Options& o, TfjsServer& tf) {
  NetReport r{"FaceRecognitionNet"};
  const nets::TfjsWeights w = nets::load_tfjs_weights(
      nets::face_api_manifest("face_recognition_model-weights_manifest.json"));
  const nets::FaceRecognitionNet net(dev, w);
  DnnBuilder b = build_recognition(w);
  r.flops = b.flops();
  cv::dnn::Net& dnn = b.net();
  prepare(dnn);
  r.opencv_flops = double(dnn.getFLOPS(cv::dnn::MatShape{1, 3, 150, 150}));

  const HostTensor x = read_parity(dir, "sample1_f0_150.npy");
  const std::vector<float> x_nchw = hwc_to_nchw({&x});
  const Tensor tx = Tensor::from(dev, {1, 3, 150, 150}, x_nchw);
  const cv::Mat bx = nchw_blob(x_nchw, 1, 3, 150, 150);
  Stream s(dev);
  const auto vk_once = [&] {
    return vk_run(s, [&](nets::Tape& t) { return net.forward(t, nets::Var(tx)); });
  };
  const std::vector<float> vk = vk_once(), cv_out = dnn_forward(dnn, bx);
  r.check_vk_vs_cv = max_abs_diff(vk, cv_out);
  const auto ref = index.at("images").at(0).at("detections").at(0).at("descriptor_150");
  r.check_vk_vs_faceapi = max_abs_diff(vk, ref.get<std::vector<float>>());

  std::vector<float> sink;
  time_single(
      r, [&] { sink = vk_once(); }, [&] { sink = dnn_forward(dnn, bx); }, tf,
      "faceapi_recognition_150", o);

  const std::vector<HostTensor> faces = all_faces(dir, "_150.npy");
  const std::vector<float> xb = hwc_to_nchw(pick(faces));
  const Tensor txb = Tensor::from(dev, {kBatch, 3, 150, 150}, xb);
  const cv::Mat bxb = nchw_blob(xb, kBatch, 3, 150, 150);
  const std::vector<float> vkb =
      vk_run(s, [&](nets::Tape& t) { return net.forward(t, nets::Var(txb)); });
  {  // batch item 0 (the first face file) against a single run of it
    const std::vector<float> x0 = hwc_to_nchw({&faces[0]});
    const Tensor t0 = Tensor::from(dev, {1, 3, 150, 150}, x0);
    const std::vector<float> single =
        vk_run(s, [&](nets::Tape& t) { return net.forward(t, nets::Var(t0)); });
    r.check_batch = max_abs_diff(std::vector<float>(vkb.begin(), vkb.begin() + 128), single);
  }
  time_batch(
      r, [&] { sink = vk_run(s, [&](nets::Tape& t) { return net.forward(t, nets::Var(txb)); }); },
      [&] { sink = dnn_forward(dnn, bxb); }, tf, "faceapi_recognition_150_batch8", o);
  return r;
}

NetReport bench_landmarks(const Device& dev, const fs::path& dir, const nlohmann::json& index,
                          const Options& o, TfjsServer& tf) {
  NetReport r{"FaceLandmark68Net"};
  const nets::TfjsWeights w = nets::load_tfjs_weights(
      nets::face_api_manifest("face_landmark_68_model-weights_manifest.json"));
  const nets::FaceLandmark68Net net(dev, w);
  DnnBuilder b = build_landmarks(w);
  r.flops = b.flops();
  cv::dnn::Net& dnn = b.net();
  prepare(dnn);
  r.opencv_flops = double(dnn.getFLOPS(cv::dnn::MatShape{1, 3, 112, 112}));
  Stream s(dev);

  // Same 112×112 input on both: the raw 136 outputs.
  const HostTensor x112 = read_parity(dir, "sample1_f0_lm_112.npy");
  const std::vector<float> x_nchw = hwc_to_nchw({&x112});
  const Tensor tx = Tensor::from(dev, {1, 3, 112, 112}, x_nchw);
  const std::vector<float> vk =
      vk_run(s, [&](nets::Tape& t) { return net.forward(t, nets::Var(tx)); });
  r.check_vk_vs_cv = max_abs_diff(vk, dnn_forward(dnn, nchw_blob(x_nchw, 1, 3, 112, 112)));
  const auto ref = index.at("images").at(0).at("detections").at(0).at("landmarks_raw");
  r.check_vk_vs_faceapi = max_abs_diff(vk, ref.get<std::vector<float>>());

  // Timed as face-api's detectLandmarks: one face crop → pad + resize to 112 →
  // net → landmarks in crop pixels. OpenCV pads and resizes with
  // copyMakeBorder + cv::resize (half-pixel bilinear: the same work, not the
  // same rounding as TF's legacy resize).
  const HostTensor crop = read_parity(dir, "sample1_f0_lm_in.npy");
  const Tensor tcrop = nets::image_to_device(dev, crop);
  const cv::Mat mcrop = hwc_mat(crop);
  const int ch = mcrop.rows, cw = mcrop.cols, side = std::max(ch, cw);
  const int after_x = (side - cw + 1) / 2, after_y = (side - ch + 1) / 2;
  std::vector<float> sink;
  const auto vk_detect = [&] { sink = net.detect_landmarks(s, tcrop); };
  const auto cv_detect = [&] {
    cv::Mat square, small;
    cv::copyMakeBorder(mcrop, square, side - ch - after_y, after_y, side - cw - after_x, after_x,
                       cv::BORDER_CONSTANT, cv::Scalar::all(0));
    cv::resize(square, small, cv::Size(112, 112), 0, 0, cv::INTER_LINEAR);
    dnn.setInput(
        cv::dnn::blobFromImage(small, 1.0, cv::Size(), cv::Scalar(), false, false, CV_32F));
    const cv::Mat raw = dnn.forward();
    const auto rel = nets::landmarks_relative_to_crop(raw.ptr<float>(), cw, ch);
    sink.assign(rel.begin(), rel.end());
  };
  time_single(r, vk_detect, cv_detect, tf, "faceapi_landmarks_112", o);

  const std::vector<HostTensor> faces = all_faces(dir, "_lm_112.npy");
  const std::vector<float> xb = hwc_to_nchw(pick(faces));
  const Tensor txb = Tensor::from(dev, {kBatch, 3, 112, 112}, xb);
  const cv::Mat bxb = nchw_blob(xb, kBatch, 3, 112, 112);
  const std::vector<float> vkb =
      vk_run(s, [&](nets::Tape& t) { return net.forward(t, nets::Var(txb)); });
  {
    const std::vector<float> x0 = hwc_to_nchw({&faces[0]});
    const Tensor t0 = Tensor::from(dev, {1, 3, 112, 112}, x0);
    const std::vector<float> single =
        vk_run(s, [&](nets::Tape& t) { return net.forward(t, nets::Var(t0)); });
    r.check_batch = max_abs_diff(std::vector<float>(vkb.begin(), vkb.begin() + 136), single);
  }
  time_batch(
      r, [&] { sink = vk_run(s, [&](nets::Tape& t) { return net.forward(t, nets::Var(txb)); }); },
      [&] { sink = dnn_forward(dnn, bxb); }, tf, "faceapi_landmarks_112_batch8", o);
  return r;
}

NetReport bench_detector(const Device& dev, const fs::path& dir, const nlohmann::json& index,
                         const Options& o, TfjsServer& tf) {
  constexpr int kSize = 416, kCells = kSize / 32;
  NetReport r{"TinyFaceDetector"};
  const nets::TfjsWeights w = nets::load_tfjs_weights(
      nets::face_api_manifest("tiny_face_detector_model-weights_manifest.json"));
  const nets::TinyFaceDetector net(dev, w);
  DnnBuilder b = build_detector(w, kSize);
  r.flops = b.flops();
  cv::dnn::Net& dnn = b.net();
  prepare(dnn);
  r.opencv_flops = double(dnn.getFLOPS(cv::dnn::MatShape{1, 3, kSize, kSize}));
  Stream s(dev);

  // Same 416×416 input on both: the raw [25, 13, 13] logits.
  const HostTensor xin = read_parity(dir, "sample1_det_in.npy");
  const std::vector<float> x_nchw = hwc_to_nchw({&xin});
  const Tensor tx = Tensor::from(dev, {1, 3, kSize, kSize}, x_nchw);
  const std::vector<float> vk =
      vk_run(s, [&](nets::Tape& t) { return net.forward(t, nets::Var(tx)); });
  r.check_vk_vs_cv = max_abs_diff(vk, dnn_forward(dnn, nchw_blob(x_nchw, 1, 3, kSize, kSize)));
  const HostTensor ref = read_parity(dir, "sample1_det_out.npy");  // HWC [13, 13, 25]
  r.check_vk_vs_faceapi = max_abs_diff(vk, hwc_to_nchw({&ref}));

  // Timed as face-api's locateFaces: the decoded photo → pad to a square at
  // the bottom/right → resize to 416 → net → decode → NMS.
  const HostTensor photo = read_parity(dir, "sample1.npy");
  const Tensor tphoto = nets::image_to_device(dev, photo);
  const cv::Mat mphoto = hwc_mat(photo);
  const int ph = mphoto.rows, pw = mphoto.cols, side = std::max(ph, pw);
  const auto reshaped = nets::tiny_yolo_reshaped_size(pw, ph, kSize);
  std::size_t vk_faces = 0, cv_faces = 0;
  const auto vk_detect = [&] { vk_faces = net.detect(s, tphoto, kSize, 0.5f).size(); };
  const auto cv_detect = [&] {
    cv::Mat square, small;
    cv::copyMakeBorder(mphoto, square, 0, side - ph, 0, side - pw, cv::BORDER_CONSTANT,
                       cv::Scalar::all(0));
    cv::resize(square, small, cv::Size(kSize, kSize), 0, 0, cv::INTER_LINEAR);
    dnn.setInput(
        cv::dnn::blobFromImage(small, 1.0, cv::Size(), cv::Scalar(), false, false, CV_32F));
    const std::vector<float> raw = mat_values(dnn.forward());
    const auto cands = nets::decode_tiny_yolo(raw, kCells, reshaped, 0.5);
    std::vector<nets::FaceBox> boxes;
    std::vector<double> scores;
    for (const auto& c : cands) {
      boxes.push_back({c.relative.x * kSize, c.relative.y * kSize, c.relative.width * kSize,
                       c.relative.height * kSize});
      scores.push_back(c.score);
    }
    cv_faces = nets::non_max_suppression(boxes, scores, nets::kTinyFaceIouThreshold).size();
  };
  time_single(r, vk_detect, cv_detect, tf, "faceapi_tiny_detector_416", o);
  const std::size_t ref_faces = index.at("images").at(0).at("detections").size();
  r.note = "faces found in sample1: vkjr2 " + std::to_string(vk_faces) + ", OpenCV pipeline " +
           std::to_string(cv_faces) + ", face-api " + std::to_string(ref_faces);
  return r;
}

// Per-kernel GPU times of `reps` forward passes of each net (VKJR2_PROFILE),
// counted after the load (weight packing and folding) and one warm-up pass, on
// a separate profiling device so the timed runs above carry no timestamp queries.
void profile_nets(const fs::path& dir, int reps) {
  const auto run = [&](const char* what, const std::function<void(const Device&)>& fn) {
    DeviceOptions po;
    po.validation = false;
    po.profile = true;
    const Device pdev(po);
    fn(pdev);
    std::printf("\n%s, %d forward passes:\n%s", what, reps, pdev.profile_report().c_str());
  };
  run("FaceRecognitionNet 150x150, 1 face", [&](const Device& d) {
    const auto net = nets::FaceRecognitionNet::load(d);
    const HostTensor x = read_parity(dir, "sample1_f0_150.npy");
    const Tensor tx = nets::image_to_device(d, x);
    Stream s(d);
    for (int i = 0; i <= reps; ++i) {
      if (i == 1) d.reset_profile();
      vk_run(s, [&](nets::Tape& t) { return net->forward(t, nets::Var(tx)); });
    }
  });
  run("FaceLandmark68Net 112x112, 1 face", [&](const Device& d) {
    const auto net = nets::FaceLandmark68Net::load(d);
    const Tensor tx = nets::image_to_device(d, read_parity(dir, "sample1_f0_lm_112.npy"));
    Stream s(d);
    for (int i = 0; i <= reps; ++i) {
      if (i == 1) d.reset_profile();
      vk_run(s, [&](nets::Tape& t) { return net->forward(t, nets::Var(tx)); });
    }
  });
  run("FaceLandmark68Net 112x112, batch 8", [&](const Device& d) {
    const auto net = nets::FaceLandmark68Net::load(d);
    const std::vector<HostTensor> faces = all_faces(dir, "_lm_112.npy");
    const Tensor tx = Tensor::from(d, {kBatch, 3, 112, 112}, hwc_to_nchw(pick(faces)));
    Stream s(d);
    for (int i = 0; i <= reps; ++i) {
      if (i == 1) d.reset_profile();
      vk_run(s, [&](nets::Tape& t) { return net->forward(t, nets::Var(tx)); });
    }
  });
  run("TinyFaceDetector 416 on sample1 (detect)", [&](const Device& d) {
    const auto net = nets::TinyFaceDetector::load(d);
    const Tensor tx = nets::image_to_device(d, read_parity(dir, "sample1.npy"));
    Stream s(d);
    for (int i = 0; i <= reps; ++i) {
      if (i == 1) d.reset_profile();
      net->detect(s, tx, 416, 0.5f);
    }
  });
}

void usage() {
  std::printf(
      "usage: nets_bench [--json FILE] [--quick] [--runs N] [--no-tfjs] [--faceapi-script PATH]\n"
      "                  [--profile]\n"
      "Times face-api's FaceRecognitionNet (150x150), FaceLandmark68Net (112x112) and\n"
      "TinyFaceDetector (416, sample1), one face at a time, and batches of 8 faces\n"
      "through the first two (net only, faces/s) on vkjr2's Vulkan device (VKJR2_DEVICE picks it)\n"
      "against face-api on TF.js WASM (node bench/faceapi_bench.mjs --serve, after\n"
      "scripts/setup) and OpenCV DNN running the same networks with the same weights\n"
      "(built through the cv::dnn API, checked against vkjr2's output first), all in one\n"
      "run, the three's runs interleaved so that all see the same machine load. Median of\n"
      "N runs (default 7, --quick 3) after 2 warm-ups (--quick 1); prints a table, writes\n"
      "JSON (default nets_bench.json). --profile adds per-kernel GPU times of each net.\n"
      "Inputs: the face-api parity references ($VKJR2_PARITY_DIR, else\n"
      "${VKJR2_CACHE_DIR:-~/.cache/vkjr2}/parity).\n");
}

int run(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        throw InvalidArgument("nets_bench", arg + " needs a value", "see --help");
      }
      return argv[++i];
    };
    if (arg == "--json") {
      o.json_path = value();
    } else if (arg == "--quick") {
      o.runs = 3;
      o.warmup = 1;
    } else if (arg == "--runs") {
      const std::string v = value();
      o.runs = std::atoi(v.c_str());
      if (o.runs < 1) throw InvalidArgument("nets_bench", "--runs " + v, "pass a count >= 1");
    } else if (arg == "--no-tfjs") {
      o.tfjs = false;
    } else if (arg == "--faceapi-script") {
      o.faceapi_script = value();
    } else if (arg == "--profile") {
      o.profile = true;
    } else if (arg == "--help" || arg == "-h") {
      usage();
      return 0;
    } else {
      std::fprintf(stderr, "nets_bench: unknown argument '%s' (try --help)\n", arg.c_str());
      return 2;
    }
  }
  const fs::path dir = parity_dir();
  const fs::path index_path = dir / "index.json";
  if (!fs::exists(index_path)) {
    throw InvalidArgument("nets_bench", "no face-api references at " + dir.string(),
                          "run scripts/setup, or set VKJR2_PARITY_DIR");
  }
  std::ifstream index_file(index_path);
  const nlohmann::json index = nlohmann::json::parse(index_file);

  const std::string load_before = load_average();
  // OpenCV at its default: one thread per core, as lavapipe uses.
  cv::setNumThreads(cv::getNumberOfCPUs());
  const int cv_threads = cv::getNumThreads();

  // The TF.js peer: started before anything else, then idle between the
  // runs it is asked for (it and we never share the 2 cores).
  std::fprintf(stderr, "nets_bench: starting face-api on TF.js...\n");
  TfjsServer tfjs(o);
  if (!tfjs.available())
    std::fprintf(stderr, "nets_bench: no TF.js peer: %s\n", tfjs.reason().c_str());

  DeviceOptions options;
  options.validation = false;
  options.profile = false;  // timestamps would slow the timed runs; see --profile
  const Device dev(options);
  const double peak = bench::device_fma_gflops(dev);

  std::vector<NetReport> nets_done;
  std::fprintf(stderr, "nets_bench: recognition...\n");
  nets_done.push_back(bench_recognition(dev, dir, index, o, tfjs));
  std::fprintf(stderr, "nets_bench: landmarks...\n");
  nets_done.push_back(bench_landmarks(dev, dir, index, o, tfjs));
  std::fprintf(stderr, "nets_bench: detector...\n");
  nets_done.push_back(bench_detector(dev, dir, index, o, tfjs));
  const std::string load_after = load_average();

  const std::string tf_peer =
      tfjs.available() ? "face-api TF.js WASM 1 thread" : "face-api TF.js (unavailable)";
  const std::string cv_peer =
      "OpenCV " + std::string(CV_VERSION) + " DNN " + std::to_string(cv_threads) + " thr";
  const std::array<const char*, 3> row_names = {"recognition 150x150, 1 face",
                                                "landmarks 112x112, 1 face (+pad/resize)",
                                                "tiny detector 416, sample1 (+decode)"};
  std::vector<bench::Result> results;
  for (std::size_t i = 0; i < nets_done.size(); ++i) {
    const NetReport& n = nets_done[i];
    results.push_back(ms_row(row_names[i], n.vk_ms, tf_peer, n.tf_ms, n.flops, peak));
    results.push_back(ms_row(row_names[i], n.vk_ms, cv_peer, n.cv_ms, n.flops, peak));
    if (n.vk_batch_fps > 0) {
      const std::string batch = " batch " + std::to_string(kBatch);
      std::string name = i == 0 ? "recognition" : "landmarks";
      name += batch;
      name += " (net only)";
      for (const auto& [peer, fps] :
           {std::pair{tf_peer, n.tf_batch_fps}, std::pair{cv_peer, n.cv_batch_fps}}) {
        std::string peer_batch = peer;
        peer_batch += ",";
        peer_batch += batch;
        bench::Result br{name, n.vk_batch_fps, "faces/s", peer_batch, fps};
        br.fraction_of_device_peak = n.flops * n.vk_batch_fps * 1e-9 / peak;
        results.push_back(br);
      }
    }
  }

  bench::print_table("vkjr2 nets_bench: face-api networks (device FMA peak " +
                         std::to_string(int(peak)) + " GFLOP/s)",
                     dev, results);
  std::printf("\nload average (1/5/15 min): %s before, %s after\n", load_before.c_str(),
              load_after.c_str());
  std::printf("TF.js peer: %s\n", tfjs.available()
                                      ? (tfjs.peer() + ", its runs interleaved with ours").c_str()
                                      : ("unavailable: " + tfjs.reason()).c_str());
  std::printf("OpenCV DNN: %d threads (cv::setNumThreads at the machine default), fusion on\n",
              cv_threads);
  std::printf("\n%-20s %9s %9s %9s %9s %10s %8s %9s %9s %9s\n", "net", "MFLOP", "vk ms", "faces/s",
              "GFLOP/s", "of peak", "TF.js ms", "OpenCV ms", "vk-cv", "vk-faceapi");
  for (std::size_t i = 0; i < nets_done.size(); ++i) {
    const NetReport& n = nets_done[i];
    const double gflops = n.flops / (n.vk_ms * 1e-3) * 1e-9;
    std::printf("%-20s %9.1f %9.2f %9.1f %9.2f %9.1f%% %8.2f %9.2f %9.2g %9.2g\n", n.net.c_str(),
                n.flops * 1e-6, n.vk_ms, 1e3 / n.vk_ms, gflops, 100 * gflops / peak, n.tf_ms,
                n.cv_ms, n.check_vk_vs_cv, n.check_vk_vs_faceapi);
  }
  std::printf(
      "\nvk-cv: max |vkjr2 − OpenCV DNN| on the same input (descriptor / raw landmarks / raw\n"
      "detector logits); vk-faceapi: max |vkjr2 − face-api reference|. FLOPs = 2·MACs of\n"
      "convolutions and FC, counted from the graph (OpenCV's getFLOPS, all layers:");
  for (const NetReport& n : nets_done) std::printf(" %.1f", n.opencv_flops * 1e-6);
  std::printf(" MFLOP).\n");
  bool mismatch = false;
  for (const NetReport& n : nets_done) {
    if (!(n.check_vk_vs_cv <= 1e-3)) {
      mismatch = true;
      std::printf(
          "WARNING: %s: OpenCV DNN differs from vkjr2 by %.3g: its timing is not "
          "comparable\n",
          n.net.c_str(), n.check_vk_vs_cv);
    }
    if (n.vk_batch_fps > 0) {
      std::printf("%s: batch item 0 vs single run: max abs diff %.3g\n", n.net.c_str(),
                  n.check_batch);
    }
    if (!n.note.empty()) std::printf("%s: %s\n", n.net.c_str(), n.note.c_str());
    if (!n.tf_over_vk.empty()) {
      const auto [lo, hi] = std::minmax_element(n.tf_over_vk.begin(), n.tf_over_vk.end());
      std::printf("%s: TF.js / vkjr2 run by run: median %.3fx, range %.3f-%.3fx over %zu runs\n",
                  n.net.c_str(), median(n.tf_over_vk), *lo, *hi, n.tf_over_vk.size());
    }
    if (!n.tf_over_vk_batch.empty()) {
      const auto [lo, hi] =
          std::minmax_element(n.tf_over_vk_batch.begin(), n.tf_over_vk_batch.end());
      std::printf(
          "%s: batch %d, TF.js / vkjr2 run by run: median %.3fx, range %.3f-%.3fx over %zu runs\n",
          n.net.c_str(), kBatch, median(n.tf_over_vk_batch), *lo, *hi, n.tf_over_vk_batch.size());
    }
  }

  nlohmann::json j = bench::to_json(dev, results);
  j["device_fma_gflops"] = peak;
  j["load_average_before"] = load_before;
  j["load_average_after"] = load_after;
  j["runs"] = o.runs;
  j["warmup"] = o.warmup;
  j["opencv_threads"] = cv_threads;
  if (tfjs.available()) {
    j["tfjs"] = tfjs.about();
    j["tfjs"]["available"] = true;
  } else {
    j["tfjs"] = nlohmann::json{{"available", false}, {"reason", tfjs.reason()}};
  }
  j["nets"] = nlohmann::json::array();
  for (const NetReport& n : nets_done) {
    j["nets"].push_back({{"net", n.net},
                         {"flops", n.flops},
                         {"opencv_getflops", n.opencv_flops},
                         {"vkjr2_ms", n.vk_ms},
                         {"opencv_ms", n.cv_ms},
                         {"tfjs_ms", n.tf_ms},
                         {"tfjs_over_vkjr2_per_run", n.tf_over_vk},
                         {"vkjr2_batch_faces_per_s", n.vk_batch_fps},
                         {"opencv_batch_faces_per_s", n.cv_batch_fps},
                         {"tfjs_batch_faces_per_s", n.tf_batch_fps},
                         {"tfjs_over_vkjr2_batch_per_run", n.tf_over_vk_batch},
                         {"max_abs_diff_vkjr2_opencv", n.check_vk_vs_cv},
                         {"max_abs_diff_vkjr2_faceapi", n.check_vk_vs_faceapi},
                         {"note", n.note}});
  }
  bench::write_json(o.json_path, j);
  std::printf("wrote %s\n", o.json_path.c_str());

  if (o.profile) profile_nets(dir, 5);
  return mismatch ? 3 : 0;
}

}  // namespace
}  // namespace vkjr2

int main(int argc, char** argv) {
  try {
    return vkjr2::run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "nets_bench: error: %s\n", e.what());
    return 1;
  }
}
