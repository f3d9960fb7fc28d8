// The smallest vkjr2 program: one image through the turbulence simulator,
// then the face stack (detect → landmarks → align → 128-d descriptor) on the
// clean and the degraded image, and how far each face's descriptor moved.
//
//   vkjr2_minimal IMAGE [--preset weak|moderate|strong] [--max-side PX] [--seed N]
//
// Face models: $VKJR2_CACHE_DIR (default ~/.cache/vkjr2; scripts/setup
// fetches them). Blur model: $VKJR2_ARTIFACT_DIR, else the installed
// share/vkjr2/p2s_default.safetensors. Walked through in docs/api.md.
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/runtime/tensor.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

namespace {

struct Args {
  std::string image;
  std::string preset = "moderate";
  int max_side = 640;  // the simulator's cost grows with the pixel count
  unsigned seed = 1;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--preset" && has_value) {
      a.preset = argv[++i];
    } else if (arg == "--max-side" && has_value) {
      a.max_side = std::stoi(argv[++i]);
    } else if (arg == "--seed" && has_value) {
      a.seed = unsigned(std::stoul(argv[++i]));
    } else if (a.image.empty() && arg[0] != '-') {
      a.image = arg;
    } else {
      throw vkjr2::InvalidArgument(
          "command line", "unexpected argument '" + arg + "'",
          "vkjr2_minimal IMAGE [--preset NAME] [--max-side PX] [--seed N]");
    }
  }
  if (a.image.empty()) {
    throw vkjr2::InvalidArgument("command line", "no image given", "vkjr2_minimal IMAGE");
  }
  return a;
}

// RGB planes [3, H, W] in 0..1 (the simulator's range), at most max_side wide or high.
std::vector<float> load_planes(const std::string& path, int max_side, int& height, int& width) {
  cv::Mat bgr = cv::imread(path, cv::IMREAD_COLOR);
  if (bgr.empty()) {
    throw vkjr2::Error("load image", path + " cannot be read", "pass a PNG or JPEG file");
  }
  const double scale = double(max_side) / std::max(bgr.cols, bgr.rows);
  if (scale < 1) cv::resize(bgr, bgr, cv::Size(), scale, scale, cv::INTER_AREA);
  height = bgr.rows;
  width = bgr.cols;
  const std::size_t hw = std::size_t(height) * std::size_t(width);
  std::vector<float> planes(3 * hw);
  for (int y = 0; y < height; ++y) {
    const auto* row = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < width; ++x) {
      const std::size_t i = std::size_t(y) * std::size_t(width) + std::size_t(x);
      for (int c = 0; c < 3; ++c) planes[std::size_t(c) * hw + i] = float(row[x][2 - c]) / 255.f;
    }
  }
  return planes;
}

double iou(const vkjr2::nets::FaceBox& a, const vkjr2::nets::FaceBox& b) {
  const double w = std::min(a.x + a.width, b.x + b.width) - std::max(a.x, b.x);
  const double h = std::min(a.y + a.height, b.y + b.height) - std::max(a.y, b.y);
  if (w <= 0 || h <= 0) return 0;
  return w * h / (a.width * a.height + b.width * b.height - w * h);
}

void print_faces(const char* label, const std::vector<vkjr2::jr2::Face>& faces) {
  std::printf("%s: %zu face(s)\n", label, faces.size());
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const vkjr2::jr2::Face& f = faces[i];
    std::printf(
        "  #%zu score %.3f box (%.0f, %.0f, %.0f x %.0f) descriptor [%.4f, %.4f, %.4f, ...]\n", i,
        double(f.score), f.box.x, f.box.y, f.box.width, f.box.height, double(f.descriptor.at(0)),
        double(f.descriptor.at(1)), double(f.descriptor.at(2)));
  }
}

int run(const Args& a) {
  int h = 0, w = 0;
  const std::vector<float> planes = load_planes(a.image, a.max_side, h, w);

  vkjr2::Device device;  // VKJR2_DEVICE picks one; VKJR2_VALIDATION=1 checks every call
  std::printf("device: %s\n", device.info().name.c_str());
  const vkjr2::jr2::FaceAnalyzer analyzer(device);  // loads the three face-api models

  // The simulator, on an RGB frame [1, 3, H, W] in 0..1.
  vkjr2::sim::Params params = vkjr2::sim::preset(a.preset);
  params.image = {h, w, 3, 1};
  vkjr2::sim::Simulator simulator(device, params, vkjr2::sim::load_default_blur_model(device));
  simulator.reset(a.seed);
  const vkjr2::Shape shape{1, 3, h, w};
  const auto clean = vkjr2::Tensor::from(device, shape, planes);
  const auto degraded = vkjr2::Tensor::empty(device, shape);
  vkjr2::Stream stream(device);
  simulator.frame(stream, clean, degraded);  // recorded, not yet run
  stream.run();                              // submit + wait
  std::printf("simulated %dx%d, preset %s: D/r0 = %.2f\n", w, h, a.preset.c_str(),
              simulator.derived().channels.at(0).d_over_r0);

  // The face stack wants RGB in 0..255.
  std::vector<float> clean255 = planes, degraded255 = degraded.download();
  for (float& v : clean255) v *= 255.f;
  for (float& v : degraded255) v = std::clamp(v, 0.f, 1.f) * 255.f;
  const vkjr2::jr2::FaceOptions options;  // input 416, score ≥ 0.5, face-api alignment
  const auto faces_clean =
      analyzer.analyze(stream, vkjr2::Tensor::from(device, shape, clean255), options);
  const auto faces_degraded =
      analyzer.analyze(stream, vkjr2::Tensor::from(device, shape, degraded255), options);
  print_faces("clean", faces_clean);
  print_faces("degraded", faces_degraded);

  // Each clean face against the degraded face that overlaps it most.
  for (std::size_t i = 0; i < faces_clean.size(); ++i) {
    double best = 0;
    const vkjr2::jr2::Face* match = nullptr;
    for (const auto& f : faces_degraded) {
      if (const double o = iou(faces_clean[i].box, f.box); o > best) {
        best = o;
        match = &f;
      }
    }
    if (match == nullptr || best < 0.3) {
      std::printf("face #%zu: lost in the degraded image\n", i);
      continue;
    }
    const double d = vkjr2::jr2::descriptor_distance(faces_clean[i].descriptor, match->descriptor);
    std::printf("face #%zu: descriptor distance clean -> degraded %.4f (%s, threshold %.1f)\n", i,
                d, d < vkjr2::jr2::kFaceApiMatchThreshold ? "same person" : "no match",
                vkjr2::jr2::kFaceApiMatchThreshold);
  }
  return faces_clean.empty() ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parse(argc, argv));
  } catch (const vkjr2::NoDeviceError& e) {
    std::fprintf(stderr, "vkjr2_minimal: %s\n", e.what());
    return 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vkjr2_minimal: %s\n", e.what());
    return 1;
  }
}
