// The kernels benchmarks: see kernels_cases.hpp.
#include "kernels_cases.hpp"

#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/fft.hpp>
#include <vkjr2/kernels/grid_sample.hpp>
#include <vkjr2/kernels/metrics.hpp>
#include <vkjr2/kernels/psf_conv.hpp>
#include <vkjr2/kernels/warp.hpp>

#include <fftw3.h>
#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/quality/qualityssim.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>

namespace vkjr2::bench {
namespace {

std::vector<float> noise(std::size_t n, std::uint32_t seed, float lo = 0.f, float hi = 1.f) {
  cv::RNG rng(seed);
  std::vector<float> v(n);
  for (float& x : v) x = static_cast<float>(rng.uniform(double(lo), double(hi)));
  return v;
}

// Warp 512×512×3 by a smooth random flow, bilinear, border: vs cv::remap.
bench::Result warp_vs_remap(const Device& dev) {
  constexpr int n = 512;
  const auto img = noise(3 * n * n, 1);
  std::vector<float> flow(2 * n * n);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      flow[y * n + x] = 2.f * std::sin(0.05f * float(y));
      flow[n * n + y * n + x] = 2.f * std::cos(0.03f * float(x));
    }
  }
  Tensor ti = Tensor::from(dev, {1, 3, n, n}, img);
  Tensor tf = Tensor::from(dev, {1, 2, n, n}, flow);
  Tensor to = Tensor::empty(dev, {1, 3, n, n});
  Stream s(dev);
  const double t = bench::median_seconds(
      [&] {
        kernels::warp(s, ti, tf, to, kernels::SamplePadding::border);
        s.run();
      },
      7);
  cv::Mat src(n, n, CV_32FC3), dst, mx(n, n, CV_32F), my(n, n, CV_32F);
  cv::randu(src, 0, 1);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      mx.at<float>(y, x) = float(x) + flow[y * n + x];
      my.at<float>(y, x) = float(y) + flow[n * n + y * n + x];
    }
  }
  const double tp = bench::median_seconds(
      [&] { cv::remap(src, dst, mx, my, cv::INTER_LINEAR, cv::BORDER_REPLICATE); }, 7);
  return {"warp bilinear 512x512x3", n * n / t * 1e-6, "Mpix/s", "cv::remap", n * n / tp * 1e-6};
}

// 3×3 conv 64→64 at 128×128, bias: vs OpenCV DNN.
bench::Result conv_vs_dnn(const Device& dev, double peak) {
  constexpr int c = 64, hw = 128;
  const auto x = noise(c * hw * hw, 2, -1, 1);
  const auto w = noise(c * c * 9, 3, -0.1f, 0.1f);
  const auto b = noise(c, 4);
  Tensor tx = Tensor::from(dev, {1, c, hw, hw}, x);
  Tensor tw = Tensor::from(dev, {c, c, 3, 3}, w);
  Tensor tb = Tensor::from(dev, {c}, b);
  Tensor ty = Tensor::empty(dev, {1, c, hw, hw});
  kernels::Conv2dParams p;
  p.pad = {1, 1, 1, 1};
  Stream s(dev);
  const double t = bench::median_seconds(
      [&] {
        kernels::conv2d(s, tx, tw, &tb, ty, p);
        s.run();
      },
      7);
  const double flops = 2.0 * c * c * 9 * hw * hw;

  cv::dnn::LayerParams lp;
  lp.type = "Convolution";
  lp.name = "conv";
  lp.set("kernel_size", 3);
  lp.set("num_output", c);
  lp.set("pad", 1);
  lp.set("bias_term", true);
  const int wshape[] = {c, c, 3, 3};
  lp.blobs.push_back(cv::Mat(4, wshape, CV_32F, const_cast<float*>(w.data())).clone());
  lp.blobs.push_back(cv::Mat(1, c, CV_32F, const_cast<float*>(b.data())).clone());
  cv::dnn::Net net;
  net.addLayerToPrev(lp.name, lp.type, lp);
  net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  const int xshape[] = {1, c, hw, hw};
  net.setInput(cv::Mat(4, xshape, CV_32F, const_cast<float*>(x.data())));
  const double tp = bench::median_seconds([&] { net.forward(); }, 7, 2);
  bench::Result r{"conv2d 3x3 64->64 128x128", flops / t * 1e-9, "GFLOP/s", "OpenCV DNN",
                  flops / tp * 1e-9};
  r.fraction_of_device_peak = r.value / peak;
  return r;
}

// Affine crop 512×512×3 → 112×112 (affine_grid + grid_sample) vs cv::warpAffine.
bench::Result grid_sample_vs_warp_affine(const Device& dev) {
  constexpr int n = 512, out = 112;
  Tensor ti = Tensor::from(dev, {1, 3, n, n}, noise(3 * n * n, 5));
  const std::vector<float> theta = {0.4f, -0.05f, 0.02f, 0.05f, 0.4f, -0.03f};
  Tensor tt = Tensor::from(dev, {1, 2, 3}, theta);
  Tensor tg = Tensor::empty(dev, {1, out, out, 2});
  Tensor to = Tensor::empty(dev, {1, 3, out, out});
  Stream s(dev);
  const double t = bench::median_seconds(
      [&] {
        kernels::affine_grid(s, tt, tg, false);
        kernels::grid_sample(s, ti, tg, to);
        s.run();
      },
      9);
  cv::Mat src(n, n, CV_32FC3), dst;
  cv::randu(src, 0, 1);
  const cv::Mat m = (cv::Mat_<double>(2, 3) << 1.8, -0.2, 200, 0.2, 1.8, 180);
  const double tp = bench::median_seconds(
      [&] {
        cv::warpAffine(src, dst, m, cv::Size(out, out), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP);
      },
      9);
  return {"grid-sample 512^2 -> 112^2 x3", out * out / t * 1e-6, "Mpix/s", "cv::warpAffine",
          out * out / tp * 1e-6};
}

bench::Result ssim_vs_opencv(const Device& dev) {
  constexpr int n = 512;
  const auto a = noise(3 * n * n, 6), b = noise(3 * n * n, 7);
  Tensor ta = Tensor::from(dev, {1, 3, n, n}, a);
  Tensor tb = Tensor::from(dev, {1, 3, n, n}, b);
  Tensor to = Tensor::empty(dev, {1});
  Stream s(dev);
  const double t = bench::median_seconds(
      [&] {
        kernels::ssim(s, ta, tb, 1.f, to);
        s.run();
      },
      5);
  cv::Mat ma(n, n, CV_32FC3), mb(n, n, CV_32FC3);
  cv::randu(ma, 0, 1);
  cv::randu(mb, 0, 1);
  const double tp =
      bench::median_seconds([&] { cv::quality::QualitySSIM::compute(ma, mb, cv::noArray()); }, 5);
  bench::Result r{"SSIM 512x512x3", t * 1e3, "ms", "cv::quality::QualitySSIM", tp * 1e3};
  r.higher_is_better = false;
  return r;
}

bench::Result fft_vs_fftw(const Device& dev, int n) {
  const auto x = noise(std::size_t(2) * n * n, 8, -1, 1);
  Tensor tx = Tensor::from(dev, {1, n, n, 2}, x);
  Tensor ty = Tensor::empty(dev, {1, n, n, 2});
  kernels::FftPlan plan(dev, {1, n, n}, kernels::FftKind::c2c);
  Stream s(dev);
  const double t = bench::median_seconds(
      [&] {
        plan.forward(s, tx, ty);
        s.run();
      },
      n > 512 ? 5 : 15);
  auto* in = fftwf_alloc_complex(std::size_t(n) * n);
  auto* outp = fftwf_alloc_complex(std::size_t(n) * n);
  fftwf_plan p = fftwf_plan_dft_2d(n, n, in, outp, FFTW_FORWARD, FFTW_MEASURE);
  std::memcpy(in, x.data(), x.size() * sizeof(float));
  const double tp = bench::median_seconds([&] { fftwf_execute(p); }, n > 512 ? 5 : 15);
  fftwf_destroy_plan(p);
  fftwf_free(in);
  fftwf_free(outp);
  const std::string size = std::to_string(n) + "^2";
  bench::Result r{"FFT c2c " + size, t * 1e3, "ms", "FFTW (1 thread, MEASURE)", tp * 1e3};
  r.higher_is_better = false;
  return r;
}

// Elementwise add of 16 Mi floats (3 × 64 MiB moved) vs a C++ loop.
bench::Result add_vs_cpp(const Device& dev) {
  constexpr std::int64_t n = 16 << 20;
  Tensor a = Tensor::from(dev, {n}, noise(n, 9)), b = Tensor::from(dev, {n}, noise(n, 10));
  Tensor c = Tensor::empty(dev, {n});
  Stream s(dev);
  const double t = bench::median_seconds(
      [&] {
        kernels::add(s, a, b, c);
        s.run();
      },
      7);
  std::vector<float> ha = noise(n, 9), hb = noise(n, 10), hc(n);
  const double tp = bench::median_seconds(
      [&] {
        for (std::int64_t i = 0; i < n; ++i) hc[i] = ha[i] + hb[i];
      },
      7);
  const double bytes = 3.0 * 4 * n;
  return {"elementwise add 16M", bytes / t * 1e-9, "GB/s", "C++ loop (1 thread)",
          bytes / tp * 1e-9};
}

// PSF-basis blur, 3-channel image, K kernels of S×S: the direct or the FFT
// path vs cv::filter2D of every β_k ⊙ x_c plus multiply-add (OpenCV
// switches to a DFT for large kernels).
bench::Result psf_vs_filter2d(const Device& dev, int k, int sz, int hw, bool fft = false) {
  const auto x = noise(std::size_t(3) * hw * hw, 11);
  const auto beta = noise(std::size_t(k) * hw * hw, 12);
  const auto psi = noise(std::size_t(k) * sz * sz, 13);
  Tensor tx = Tensor::from(dev, {1, 3, hw, hw}, x);
  Tensor tb = Tensor::from(dev, {1, k, hw, hw}, beta);
  Tensor tp = Tensor::from(dev, {k, sz, sz}, psi);
  Tensor ty = Tensor::empty(dev, {1, 3, hw, hw});
  Tensor tn = Tensor::empty(dev, {1, 1, hw, hw});
  Stream s(dev);
  const std::unique_ptr<kernels::PsfConvFft> plan =
      fft ? std::make_unique<kernels::PsfConvFft>(dev, tp, 1, 3, hw, hw) : nullptr;
  const double t = bench::median_seconds(
      [&] {
        if (plan) {
          plan->forward(s, tx, tb, ty, tn);
        } else {
          kernels::psf_conv(s, tx, tb, tp, ty, tn);
        }
        s.run();
      },
      3);
  std::vector<cv::Mat> xs, betas, psis;
  for (int c = 0; c < 3; ++c)
    xs.emplace_back(hw, hw, CV_32F, const_cast<float*>(&x[std::size_t(c) * hw * hw]));
  for (int i = 0; i < k; ++i) {
    betas.emplace_back(hw, hw, CV_32F, const_cast<float*>(&beta[std::size_t(i) * hw * hw]));
    cv::Mat kernel(sz, sz, CV_32F, const_cast<float*>(&psi[std::size_t(i) * sz * sz]));
    cv::Mat flipped;
    cv::flip(kernel, flipped, -1);  // filter2D correlates; ψ ⊛ is a convolution
    psis.push_back(flipped);
  }
  const double tpeer = bench::median_seconds(
      [&] {
        cv::Mat u, v;
        for (int c = 0; c < 3; ++c) {
          cv::Mat acc = cv::Mat::zeros(hw, hw, CV_32F);
          for (int i = 0; i < k; ++i) {
            cv::multiply(betas[std::size_t(i)], xs[std::size_t(c)], u);
            cv::filter2D(u, v, CV_32F, psis[std::size_t(i)], cv::Point(-1, -1), 0,
                         cv::BORDER_CONSTANT);
            acc += v;
          }
        }
      },
      3);
  bench::Result r{"PSF basis K=" + std::to_string(k) + " " + std::to_string(sz) + "x" +
                      std::to_string(sz) + " " + std::to_string(hw) + "^2 x3 (" +
                      (fft ? "fft" : "direct") + ")",
                  t * 1e3, "ms", "cv::filter2D + multiply-add", tpeer * 1e3};
  r.higher_is_better = false;
  return r;
}

}  // namespace

const std::vector<KernelCase>& kernel_cases() {
  static const std::vector<KernelCase> cases = {
      {"warp", "warp bilinear 512x512x3 vs cv::remap", false, false,
       [](const Device& d, double) { return warp_vs_remap(d); }},
      {"conv2d", "conv2d 3x3 64->64 128x128 vs OpenCV DNN", false, true,
       [](const Device& d, double peak) { return conv_vs_dnn(d, peak); }},
      {"grid-sample", "affine_grid + grid_sample 512^2 -> 112^2 vs cv::warpAffine", false, false,
       [](const Device& d, double) { return grid_sample_vs_warp_affine(d); }},
      {"ssim", "SSIM 512x512x3 vs cv::quality::QualitySSIM", false, false,
       [](const Device& d, double) { return ssim_vs_opencv(d); }},
      {"fft-256", "FFT c2c 256^2 vs FFTW", false, false,
       [](const Device& d, double) { return fft_vs_fftw(d, 256); }},
      {"fft-1024", "FFT c2c 1024^2 vs FFTW", false, false,
       [](const Device& d, double) { return fft_vs_fftw(d, 1024); }},
      {"add", "elementwise add 16M vs a C++ loop", false, false,
       [](const Device& d, double) { return add_vs_cpp(d); }},
      {"psf-direct", "PSF basis K=16 9x9 256^2 (direct) vs cv::filter2D", false, false,
       [](const Device& d, double) { return psf_vs_filter2d(d, 16, 9, 256); }},
      {"psf-fft-24", "PSF basis K=24 21x21 256^2 (fft, the simulator's basis)", false, false,
       [](const Device& d, double) { return psf_vs_filter2d(d, 24, 21, 256, true); }},
      {"psf-fft-100", "PSF basis K=100 33x33 256^2 (fft, the issue's case)", false, false,
       [](const Device& d, double) { return psf_vs_filter2d(d, 100, 33, 256, true); }},
      {"psf-direct-100", "PSF basis K=100 33x33 256^2 (direct; minutes)", true, false,
       [](const Device& d, double) { return psf_vs_filter2d(d, 100, 33, 256); }},
  };
  return cases;
}

std::vector<std::string> kernel_case_ids() {
  std::vector<std::string> ids;
  for (const KernelCase& c : kernel_cases()) ids.push_back(c.id);
  return ids;
}

KernelsRun run_kernel_cases(const Device& device, const std::vector<std::string>& only, bool full,
                            const std::string& log_prefix) {
  for (const std::string& id : only) {
    const auto ids = kernel_case_ids();
    if (std::find(ids.begin(), ids.end(), id) == ids.end()) {
      std::string known;
      for (const std::string& k : ids) known += (known.empty() ? "" : ", ") + k;
      std::string message = "unknown benchmark '" + id + "' (known: ";
      message += known;
      message += ")";
      throw std::invalid_argument(message);
    }
  }
  std::vector<const KernelCase*> selected;
  for (const KernelCase& c : kernel_cases()) {
    const bool named = std::find(only.begin(), only.end(), c.id) != only.end();
    if (only.empty() ? (full || !c.full_only) : named) selected.push_back(&c);
  }
  cv::setNumThreads(0);  // OpenCV single-threaded, as the peers are stated
  KernelsRun run;
  if (std::any_of(selected.begin(), selected.end(),
                  [](const KernelCase* c) { return c->needs_peak; })) {
    std::fprintf(stderr, "%s: device FMA peak...\n", log_prefix.c_str());
    run.peak_gflops = device_fma_gflops(device);
  }
  for (const KernelCase* c : selected) {
    std::fprintf(stderr, "%s: %s...\n", log_prefix.c_str(), c->id.c_str());
    run.results.push_back(c->run(device, run.peak_gflops));
  }
  return run;
}

void print_kernels_table(const Device& device, const KernelsRun& run) {
  std::string title = "vkjr2 kernels benchmarks (";
  if (run.peak_gflops >= 0) {
    title += "device FMA peak " + std::to_string(int(run.peak_gflops)) + " GFLOP/s; ";
  }
  print_table(title + "OpenCV and FFTW on 1 thread)", device, run.results);
}

nlohmann::json kernels_json(const Device& device, const KernelsRun& run) {
  nlohmann::json j = to_json(device, run.results);
  if (run.peak_gflops >= 0) j["device_fma_peak_gflops"] = run.peak_gflops;
  j["peer_threads"] = 1;
  return j;
}

}  // namespace vkjr2::bench
