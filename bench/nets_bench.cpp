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
#include <vkjr2/nets/tfjs_weights.hpp>
#include <vkjr2/nets/tiny_face_detector.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/runtime/npy.hpp>

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
#include "nets_dnn_peer.hpp"
#include "nets_tfjs_peer.hpp"

#ifndef VKJR2_SOURCE_DIR
#define VKJR2_SOURCE_DIR "."
#endif

namespace vkjr2 {
namespace {

namespace fs = std::filesystem;
using vkjr2::HostTensor;

using bench::build_detector;
using bench::build_landmarks;
using bench::build_recognition;
using bench::dnn_forward;
using bench::DnnBuilder;
using bench::mat_values;
using bench::prepare;
using bench::TfjsServer;
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
  return vkjr2::read_npy(p);
}

// HWC images of one size → NCHW floats, batch in order.
std::vector<float> hwc_to_nchw(const std::vector<const HostTensor*>& images) {
  std::vector<float> out;
  for (const HostTensor* img : images) {
    const std::vector<float> planes = vkjr2::image_to_planes(*img);
    out.insert(out.end(), planes.begin(), planes.end());
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
  for (const auto& f : files) out.push_back(vkjr2::read_npy(f));
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
  TfjsServer tfjs(o.tfjs, o.faceapi_script);
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
