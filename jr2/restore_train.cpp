#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/restore_train.hpp>
#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/metrics.hpp>
#include <vkjr2/kernels/psf_conv.hpp>
#include <vkjr2/kernels/reduce.hpp>
#include <vkjr2/kernels/warp.hpp>
#include <vkjr2/nets/checkpoint.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <utility>

#include "internal/text_and_draws.hpp"
#include "internal/training.hpp"

namespace vkjr2::jr2 {
namespace {

namespace k = kernels;
using detail::Clock;
using detail::mix;
using detail::seconds_since;
using nets::Var;

double unit(std::mt19937_64& rng) { return detail::unit_interval(rng()); }

// Seeds of the held-out clips: fixed, so every run scores the same clips.
constexpr std::uint64_t kValSeed = 0x5eed0fa11d47a5e7ull;

// How a clean clip is cut from its image.
struct CropPlan {
  std::size_t image = 0;
  double x0 = 0, y0 = 0, side = 0;  // the window in source pixels
  bool mirror = false;
};

// The window resampled to crop² pixels as [3, crop, crop] planes in 0..1:
// the mean of n×n bilinear samples per output pixel, n ≥ the shrink factor
// (a box prefilter, so downscaled textures do not alias).
std::vector<float> cut_clip(const HostTensor& rgb, const CropPlan& c, int crop) {
  const std::int64_t h = rgb.shape[0], w = rgb.shape[1];
  const double step = c.side / crop;
  const int n = std::max(1, int(std::ceil(step)));
  std::vector<float> out(std::size_t(3) * std::size_t(crop) * std::size_t(crop));
  auto at = [&](std::int64_t y, std::int64_t x, int ch) {
    y = std::clamp<std::int64_t>(y, 0, h - 1);
    x = std::clamp<std::int64_t>(x, 0, w - 1);
    return double(rgb.values[std::size_t((y * w + x) * 3 + ch)]);
  };
  for (int i = 0; i < crop; ++i) {
    for (int j = 0; j < crop; ++j) {
      double acc[3] = {0, 0, 0};
      for (int si = 0; si < n; ++si) {
        for (int sj = 0; sj < n; ++sj) {
          const double y = c.y0 + (i + (si + 0.5) / n) * step - 0.5;
          const double x = c.x0 + (j + (sj + 0.5) / n) * step - 0.5;
          const double fy = std::floor(y), fx = std::floor(x);
          const double ty = y - fy, tx = x - fx;
          const auto iy = std::int64_t(fy), ix = std::int64_t(fx);
          for (int ch = 0; ch < 3; ++ch) {
            acc[ch] += (1 - ty) * ((1 - tx) * at(iy, ix, ch) + tx * at(iy, ix + 1, ch)) +
                       ty * ((1 - tx) * at(iy + 1, ix, ch) + tx * at(iy + 1, ix + 1, ch));
          }
        }
      }
      const int oj = c.mirror ? crop - 1 - j : j;
      for (int ch = 0; ch < 3; ++ch) {
        const std::size_t at_px =
            (std::size_t(ch) * std::size_t(crop) + std::size_t(i)) * std::size_t(crop) +
            std::size_t(oj);
        out[at_px] = float(acc[ch] / (n * n) / 255.0);
      }
    }
  }
  return out;
}

void require(bool ok, const std::string& what, const std::string& fix) {
  if (!ok) throw InvalidArgument("restore-train", what, fix);
}

}  // namespace

void RestoreTrainOptions::validate() const {
  net.validate();
  const int m = 1 << net.levels();
  require(crop >= 16 && crop <= 512 && crop % m == 0 && crop % 4 == 0,
          "--crop " + std::to_string(crop),
          "use 16..512 pixels, a multiple of " + std::to_string(std::max(m, 4)));
  require(batch >= 1 && batch <= 256, "--batch " + std::to_string(batch), "use 1..256");
  require(steps >= 1, "--steps " + std::to_string(steps), "use at least 1 step");
  require(std::isfinite(lr) && lr > 0 && lr < 1, "--lr " + std::to_string(lr),
          "use a learning rate in (0, 1), e.g. 1e-3");
  require(std::isfinite(min_lr) && min_lr >= 0 && min_lr <= lr,
          "--min-lr " + std::to_string(min_lr), "use 0 <= min-lr <= lr");
  require(std::isfinite(weight_decay) && weight_decay >= 0 && weight_decay < 1,
          "--weight-decay " + std::to_string(weight_decay), "use a decay in [0, 1)");
  require(warmup_steps >= 0, "--warmup " + std::to_string(warmup_steps), "use >= 0 steps");
  require(std::isfinite(clip_grad_norm) && clip_grad_norm >= 0,
          "--clip-grad " + std::to_string(clip_grad_norm), "use a norm >= 0 (0: no clipping)");
  require(d_over_r0_lo > 0 && d_over_r0_hi >= d_over_r0_lo && d_over_r0_hi <= 20,
          "D/r0 range [" + std::to_string(d_over_r0_lo) + ", " + std::to_string(d_over_r0_hi) + "]",
          "use 0 < lo <= hi <= 20 (--d-over-r0 1,8 spans weak to strong)");
  require(scale_lo > 0 && scale_hi >= scale_lo && scale_hi <= 1,
          "scale range [" + std::to_string(scale_lo) + ", " + std::to_string(scale_hi) + "]",
          "use 0 < lo <= hi <= 1 (the crop window as a share of the image's shorter side)");
  require(pool >= batch && pool <= 100000, "--pool " + std::to_string(pool),
          "use a pool of at least --batch clips");
  require(refresh >= 0 && refresh <= pool, "--refresh " + std::to_string(refresh),
          "use 0..pool new clips per step");
  require(val_clips >= 1 && val_clips <= 4096, "--val-clips " + std::to_string(val_clips),
          "use 1..4096 held-out clips");
  require(std::isfinite(explicit_weight) && explicit_weight >= 0 && explicit_weight <= 100,
          "--explicit " + std::to_string(explicit_weight),
          "use a consistency weight in [0, 100] (0: off; 0.5 is a start)");
}

std::vector<float> held_out_crop(const HostTensor& rgb, int size) {
  const double h = double(rgb.shape[0]), w = double(rgb.shape[1]);
  CropPlan c;
  c.side = std::max(double(size), 0.5 * std::min(h, w));
  c.x0 = (w - c.side) / 2;
  c.y0 = (h - c.side) / 2;
  return cut_clip(rgb, c, size);
}

Var redegrade(nets::Tape& tape, const Var& x, const Tensor& flow, const Tensor& beta,
              const Tensor& basis) {
  const Shape& s = x.shape();
  const char* op = "jr2::redegrade";
  if (s.rank() != 4) throw InvalidArgument(op, "x has shape " + s.str(), "pass [B, C, H, W]");
  k::require_shape(flow, Shape{s[0], 2, s[2], s[3]}, op, "flow");
  if (beta.shape().rank() != 4 || beta.shape()[0] != s[0] || beta.shape()[2] != s[2] ||
      beta.shape()[3] != s[3] || basis.shape().rank() != 3 || basis.shape()[0] != beta.shape()[1]) {
    throw InvalidArgument(op,
                          "beta " + beta.shape().str() + " and basis " + basis.shape().str() +
                              " do not fit x " + s.str(),
                          "pass beta [B, K, H, W] and basis [K, S, S]");
  }
  Stream& stream = tape.stream();
  const Device& dev = x.value().device();
  Tensor warped = Tensor::empty(dev, s), y = Tensor::empty(dev, s);
  Tensor norm = Tensor::empty(dev, Shape{s[0], 1, s[2], s[3]});
  k::warp(stream, x.value(), flow, warped, k::SamplePadding::border);
  k::psf_conv(stream, warped, beta, basis, y, norm, {.normalize = true});
  const bool grad = tape.needs_grad({&x});
  Var out = tape.output(y, grad);
  if (grad) {
    tape.record([x, out, flow, beta, basis, warped, norm](nets::Tape& t) {
      const Tensor& dy = nets::Tape::grad_of(out);
      if (!dy.defined()) return;
      const Device& d = dy.device();
      const Tensor d_warped = Tensor::empty(d, warped.shape());
      const Tensor d_beta = Tensor::empty(d, beta.shape());
      k::psf_conv_backward(t.stream(), warped, beta, basis, out.value(), norm, dy, d_warped, d_beta,
                           {.normalize = true});
      nets::GradSlot gx = t.slot(x);
      k::warp_backward(t.stream(), x.value(), flow, d_warped, &gx.target, nullptr,
                       k::SamplePadding::border);
      t.commit(gx);
    });
  }
  return out;
}

struct RestoreTrainer::Impl {
  Device device;
  RestoreTrainOptions o;
  std::vector<TrainImage> train, val;
  std::vector<std::shared_ptr<const sim::BlurModel>> blur;
  Restorer net;
  nets::Adam adam;
  nets::WarmupCosine schedule;
  Stream stream;
  // The pool: clip k in slot k % pool; clips [pool_first, pool_end) present.
  Tensor pool_frames, pool_clean;
  std::int64_t pool_first = 0, pool_end = 0;
  // With explicit_weight: each clip's reference-frame maps [pool, 2, s, s],
  // [pool, K, s, s] and the basis they weight.
  Tensor pool_flow, pool_beta, basis;
  Tensor val_frames, val_clean;
  Tensor batch_frames, batch_clean, batch_flow, batch_beta, batch_reference;
  detail::GradientNorm gradient_norm;
  double pending_sim_seconds = 0;

  Impl(const Device& d, const RestoreTrainOptions& options, std::vector<TrainImage> tr,
       std::vector<TrainImage> va, std::vector<std::shared_ptr<const sim::BlurModel>> b)
      : device(d),
        o(options),
        train(std::move(tr)),
        val(std::move(va)),
        blur(std::move(b)),
        net(d, options.net, std::uint32_t(mix(options.seed, 0x6e6574))),
        adam(net.named_parameters(),
             {.lr = options.lr, .weight_decay = options.weight_decay, .decoupled = true}),
        stream(d),
        gradient_norm(d, net.named_parameters()) {
    schedule.base_lr = o.lr;
    schedule.min_lr = o.min_lr;
    schedule.warmup_steps = std::uint32_t(o.warmup_steps);
    schedule.total_steps = std::uint32_t(o.steps);
    const std::int64_t t3 = 3LL * o.net.frames, s = o.crop;
    pool_frames = Tensor::empty(d, Shape{o.pool, t3, s, s});
    pool_clean = Tensor::empty(d, Shape{o.pool, 3, s, s});
    batch_frames = Tensor::empty(d, Shape{o.batch, t3, s, s});
    batch_clean = Tensor::empty(d, Shape{o.batch, 3, s, s});
    if (o.explicit_weight > 0) {
      // The maps' shapes and the basis, from a simulator of these settings.
      const sim::Simulator probe(d, probe_sim_params(o.d_over_r0_lo, int(s)), blur, sim_options());
      const sim::BlurModel* model = probe.blur_model(0);
      require(model != nullptr, "--explicit without a blur model",
              "pass the simulator's blur models (sim::load_shipped_blur_models)");
      for (int c = 1; c < 3; ++c) {
        require(probe.blur_model(c) == model && &probe.beta(c) == &probe.beta(0),
                "--explicit with a blur model per channel",
                "use blur models whose channels share one β (one wavelength)");
      }
      basis = model->basis();
      const std::int64_t kb = basis.shape()[0];
      pool_flow = Tensor::empty(d, Shape{o.pool, 2, s, s});
      pool_beta = Tensor::empty(d, Shape{o.pool, kb, s, s});
      batch_flow = Tensor::empty(d, Shape{o.batch, 2, s, s});
      batch_beta = Tensor::empty(d, Shape{o.batch, kb, s, s});
      batch_reference = Tensor::empty(d, Shape{o.batch, 3, s, s});
    }
  }

  sim::SimOptions sim_options() const {
    sim::SimOptions so = probe_sim_options();
    so.field.correlate_high_order = o.correlate_high_order;
    return so;
  }

  // Simulates T frames of the clean planes into frames[3T, s, s] (a view);
  // the reference frame's flow and β into the slot's maps when `slot` ≥ 0
  // and the maps are kept.
  void simulate(const std::vector<float>& clean, double d_over_r0, std::uint64_t sim_seed,
                const Tensor& frames, std::int64_t slot = -1) {
    const std::int64_t s = o.crop;
    sim::Simulator simulator(device, probe_sim_params(d_over_r0, int(s)), blur, sim_options());
    simulator.reset(sim_seed);
    const Tensor x = Tensor::from(device, Shape{1, 3, s, s}, clean);
    const std::int64_t frame_size = 3LL * s * s;
    for (int f = 0; f < o.net.frames; ++f) {
      simulator.frame(stream, x, frames.view(Shape{1, 3, s, s}, f * frame_size));
      if (slot >= 0 && pool_flow.defined() && f == o.net.reference_frame()) {
        const std::int64_t kb = basis.shape()[0];
        k::copy(stream, simulator.flow(), pool_flow.view(Shape{1, 2, s, s}, slot * 2 * s * s));
        k::copy(stream, simulator.beta(), pool_beta.view(Shape{1, kb, s, s}, slot * kb * s * s));
      }
    }
    stream.run();
  }

  void make_clip(std::int64_t k) {
    std::mt19937_64 rng(mix(o.seed, std::uint64_t(k)));
    CropPlan c;
    c.image = std::size_t(rng() % train.size());
    const HostTensor& img = train[c.image].rgb;
    const double h = double(img.shape[0]), w = double(img.shape[1]);
    const double scale = o.scale_lo + (o.scale_hi - o.scale_lo) * unit(rng);
    c.side = std::max(double(o.crop), scale * std::min(h, w));
    c.x0 = unit(rng) * (w - c.side);
    c.y0 = unit(rng) * (h - c.side);
    c.mirror = (rng() & 1) != 0;
    const double d = o.d_over_r0_lo * std::pow(o.d_over_r0_hi / o.d_over_r0_lo, unit(rng));
    const std::uint64_t sim_seed = rng();
    const std::vector<float> clean = cut_clip(img, c, o.crop);
    const std::int64_t slot = k % o.pool;
    const std::int64_t t3 = 3LL * o.net.frames, s = o.crop;
    pool_clean.view(Shape{1, 3, s, s}, slot * 3 * s * s).upload(clean);
    simulate(clean, d, sim_seed, pool_frames.view(Shape{1, t3, s, s}, slot * t3 * s * s), slot);
  }

  // Makes the pool hold clips [first, first + pool).
  void fill_pool(std::int64_t first, const std::function<void(int, int)>& progress) {
    const std::int64_t end = first + o.pool;
    std::int64_t from = std::max(first, pool_end);
    if (first < pool_first || from > end) from = first;  // not a continuation: rebuild
    const auto t0 = Clock::now();
    for (std::int64_t k = from; k < end; ++k) {
      make_clip(k);
      if (progress) progress(int(k - from + 1), int(end - from));
    }
    pending_sim_seconds += seconds_since(t0);
    pool_first = first;
    pool_end = end;
  }

  void make_val() {
    if (val_frames.defined()) return;
    const std::int64_t t3 = 3LL * o.net.frames, s = o.crop, v = o.val_clips;
    val_frames = Tensor::empty(device, Shape{v, t3, s, s});
    val_clean = Tensor::empty(device, Shape{v, 3, s, s});
    for (std::int64_t i = 0; i < v; ++i) {
      const std::vector<float> clean = held_out_crop(val[std::size_t(i) % val.size()].rgb, int(s));
      const double u = v > 1 ? double(i) / double(v - 1) : 0.5;
      const double d = o.d_over_r0_lo * std::pow(o.d_over_r0_hi / o.d_over_r0_lo, u);
      val_clean.view(Shape{1, 3, s, s}, i * 3 * s * s).upload(clean);
      simulate(clean, d, mix(kValSeed, std::uint64_t(i)),
               val_frames.view(Shape{1, t3, s, s}, i * t3 * s * s));
    }
  }

  std::int64_t step() const { return std::int64_t(adam.steps()); }
};

RestoreTrainer::RestoreTrainer(const Device& device, const RestoreTrainOptions& options,
                               std::vector<TrainImage> train, std::vector<TrainImage> val,
                               std::vector<std::shared_ptr<const sim::BlurModel>> blur) {
  options.validate();
  require(!train.empty(), "no training images", "pass at least one clean image");
  require(!val.empty(), "no held-out images", "pass at least one held-out image");
  for (const auto* list : {&train, &val}) {
    for (const TrainImage& im : *list) {
      const auto& s = im.rgb.shape;
      require(s.size() == 3 && s[2] == 3, im.name + " has shape " + shape_str(s),
              "pass H×W×3 RGB images");
      require(s[0] >= options.crop && s[1] >= options.crop,
              im.name + " is " + std::to_string(s[1]) + "×" + std::to_string(s[0]) +
                  ", smaller than the " + std::to_string(options.crop) + "² crop",
              "leave it out or lower --crop");
    }
  }
  impl_ =
      std::make_unique<Impl>(device, options, std::move(train), std::move(val), std::move(blur));
}

RestoreTrainer::~RestoreTrainer() = default;

int RestoreTrainer::step() const noexcept { return int(impl_->step()); }

const Restorer& RestoreTrainer::restorer() const { return impl_->net; }

void RestoreTrainer::prepare(const std::function<void(int, int)>& progress) {
  impl_->fill_pool(impl_->step() * impl_->o.refresh, progress);
}

RestoreStepReport RestoreTrainer::train_step() {
  Impl& m = *impl_;
  const RestoreTrainOptions& o = m.o;
  const std::int64_t s = m.step();
  m.fill_pool(s * o.refresh, {});
  RestoreStepReport r;
  r.sim_seconds = m.pending_sim_seconds;
  m.pending_sim_seconds = 0;
  const auto t0 = Clock::now();

  // The batch: slots drawn from rng(seed, step).
  std::mt19937_64 rng(mix(mix(o.seed, 0xba7c4), std::uint64_t(s)));
  const std::int64_t t3 = 3LL * o.net.frames, px = std::int64_t(o.crop) * o.crop;
  for (int b = 0; b < o.batch; ++b) {
    const std::int64_t slot = std::int64_t(rng() % std::uint64_t(o.pool));
    k::copy(m.stream, m.pool_frames.view(Shape{t3 * px}, slot * t3 * px),
            m.batch_frames.view(Shape{t3 * px}, b * t3 * px));
    k::copy(m.stream, m.pool_clean.view(Shape{3 * px}, slot * 3 * px),
            m.batch_clean.view(Shape{3 * px}, b * 3 * px));
    if (m.pool_flow.defined()) {
      const std::int64_t kb = m.basis.shape()[0];
      k::copy(m.stream, m.pool_flow.view(Shape{2 * px}, slot * 2 * px),
              m.batch_flow.view(Shape{2 * px}, b * 2 * px));
      k::copy(m.stream, m.pool_beta.view(Shape{kb * px}, slot * kb * px),
              m.batch_beta.view(Shape{kb * px}, b * kb * px));
    }
  }
  nets::Tape tape(m.stream);
  const Var out = m.net.forward(tape, Var(m.batch_frames));
  Var loss = nets::charbonnier_loss(tape, out, Var(m.batch_clean), 1e-3f);
  Var consistency;
  if (m.pool_flow.defined()) {
    k::slice(m.stream, m.batch_frames, {3LL * o.net.reference_frame(), 0, 0}, m.batch_reference);
    const Var again = redegrade(tape, out, m.batch_flow, m.batch_beta, m.basis);
    consistency = nets::charbonnier_loss(tape, again, Var(m.batch_reference), 1e-3f);
    loss = nets::add(tape, loss, nets::scale_shift(tape, consistency, o.explicit_weight));
  }
  tape.backward(loss);
  m.gradient_norm.record(m.stream);
  m.stream.run();
  r.loss = loss.value().download()[0];
  if (consistency.defined()) r.consistency = consistency.value().download()[0];
  r.grad_norm = m.gradient_norm.norm();
  if (!std::isfinite(r.loss) || !std::isfinite(r.grad_norm)) {
    throw Error("restore-train",
                "the loss or gradient norm became " + std::to_string(r.loss) + " / " +
                    std::to_string(r.grad_norm) + " at step " + std::to_string(s + 1),
                "lower --lr or --clip-grad, or resume from the last checkpoint");
  }
  m.gradient_norm.clip(m.stream, r.grad_norm, o.clip_grad_norm);
  r.lr = m.schedule.at(std::uint32_t(s));
  m.adam.set_lr(float(r.lr));
  m.adam.step(m.stream);
  m.adam.zero_grad();
  m.stream.run();
  r.step = int(s + 1);
  r.train_seconds = seconds_since(t0);
  return r;
}

RestoreEvalReport RestoreTrainer::evaluate() {
  Impl& m = *impl_;
  const auto t0 = Clock::now();
  m.make_val();
  const RestoreTrainOptions& o = m.o;
  const std::int64_t v = o.val_clips, t3 = 3LL * o.net.frames, s = o.crop;
  RestoreEvalReport r;
  r.step = int(m.step());
  const Tensor psnr_r = Tensor::empty(m.device, Shape{v}),
               ssim_r = Tensor::empty(m.device, Shape{v});
  const Tensor psnr_d = Tensor::empty(m.device, Shape{v}),
               ssim_d = Tensor::empty(m.device, Shape{v});
  const Tensor restored = Tensor::empty(m.device, Shape{v, 3, s, s});
  const Tensor degraded = Tensor::empty(m.device, Shape{v, 3, s, s});
  k::slice(m.stream, m.val_frames, {3LL * o.net.reference_frame(), 0, 0}, degraded);
  for (std::int64_t b0 = 0; b0 < v; b0 += o.batch) {
    const std::int64_t n = std::min<std::int64_t>(o.batch, v - b0);
    nets::Tape tape(m.stream, false);
    const Var out =
        m.net.forward(tape, Var(m.val_frames.view(Shape{n, t3, s, s}, b0 * t3 * s * s)));
    k::copy(m.stream, out.value(), restored.view(Shape{n, 3, s, s}, b0 * 3 * s * s));
    m.stream.run();
  }
  k::psnr(m.stream, restored, m.val_clean, 1.f, psnr_r);
  k::ssim(m.stream, restored, m.val_clean, 1.f, ssim_r);
  k::psnr(m.stream, degraded, m.val_clean, 1.f, psnr_d);
  k::ssim(m.stream, degraded, m.val_clean, 1.f, ssim_d);
  m.stream.run();
  auto mean = [](const Tensor& t) {
    const auto x = t.download();
    double a = 0;
    for (float f : x) a += f;
    return a / double(x.size());
  };
  r.psnr_restored = mean(psnr_r);
  r.ssim_restored = mean(ssim_r);
  r.psnr_degraded = mean(psnr_d);
  r.ssim_degraded = mean(ssim_d);
  r.seconds = seconds_since(t0);
  return r;
}

std::map<std::string, std::string> RestoreTrainer::options_metadata() const {
  const RestoreTrainOptions& o = impl_->o;
  auto num = [](double x) {
    char b[64];
    std::snprintf(b, sizeof b, "%.9g", x);
    return std::string(b);
  };
  std::map<std::string, std::string> m = o.net.metadata();
  m["train.crop"] = std::to_string(o.crop);
  m["train.batch"] = std::to_string(o.batch);
  m["train.steps"] = std::to_string(o.steps);
  m["train.lr"] = num(o.lr);
  m["train.min_lr"] = num(o.min_lr);
  m["train.weight_decay"] = num(o.weight_decay);
  m["train.warmup_steps"] = std::to_string(o.warmup_steps);
  m["train.clip_grad_norm"] = num(o.clip_grad_norm);
  m["train.d_over_r0"] = num(o.d_over_r0_lo) + "," + num(o.d_over_r0_hi);
  m["train.scale"] = num(o.scale_lo) + "," + num(o.scale_hi);
  m["train.pool"] = std::to_string(o.pool);
  m["train.refresh"] = std::to_string(o.refresh);
  m["train.seed"] = std::to_string(o.seed);
  m["train.explicit_weight"] = num(o.explicit_weight);
  m["train.correlate_high_order"] = o.correlate_high_order ? "true" : "false";
  m["train.images"] = std::to_string(impl_->train.size());
  return m;
}

void RestoreTrainer::save_checkpoint(const std::filesystem::path& path,
                                     const std::map<std::string, std::string>& metadata) const {
  std::map<std::string, std::string> meta = metadata;
  for (auto& [key, value] : options_metadata()) meta[key] = value;
  nets::save_checkpoint(path, impl_->net, &impl_->adam, meta);
}

void RestoreTrainer::load_checkpoint(const std::filesystem::path& path) {
  const nets::SafetensorsFile file = nets::read_safetensors(path);
  detail::require_same_settings("restore-train", path, file.metadata, options_metadata());
  nets::load_checkpoint(path, impl_->net, &impl_->adam);
}

}  // namespace vkjr2::jr2
