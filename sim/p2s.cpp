#include <vkjr2/nets/optimizer.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/p2s.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <set>

namespace vkjr2::sim {
namespace {

std::size_t sz(std::int64_t v) { return static_cast<std::size_t>(v); }

constexpr float kLeakySlope = 0.2f;
constexpr const char* kFormat = "vkjr2.p2s";
constexpr const char* kVersion = "1";

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

void check_config(const P2sNetConfig& c) {
  const char* op = "sim::P2sNet";
  if (c.j_max < 4 || c.j_max > kMaxZernikeModes)
    throw InvalidArgument(
        op,
        "j_max " + std::to_string(c.j_max) + " is outside 4.." + std::to_string(kMaxZernikeModes),
        "use the basis' j_max (params.zernike_modes)");
  if (c.count < 2)
    throw InvalidArgument(op,
                          "K = " + std::to_string(c.count) + " leaves no coefficient to predict",
                          "use a basis with at least one principal component");
  if (c.hidden < 1)
    throw InvalidArgument(op, "hidden width " + std::to_string(c.hidden) + " is not positive",
                          "use e.g. 200");
  if (!std::isfinite(c.input_d_over_r0) || c.input_d_over_r0 <= 0 ||
      !std::isfinite(c.output_scale) || c.output_scale <= 0)
    throw InvalidArgument(op, "input_d_over_r0 and output_scale must be positive and finite",
                          "use p2s_config_for(basis)");
}

std::vector<float> input_scales(const P2sNetConfig& c) {
  const double amplitude = std::pow(c.input_d_over_r0, 5.0 / 6.0);
  std::vector<float> s;
  for (int j = 4; j <= c.j_max; ++j)
    s.push_back(static_cast<float>(1.0 / (std::sqrt(noll_covariance(j, j)) * amplitude)));
  return s;
}

}  // namespace

P2sNetConfig p2s_config_for(const PsfBasis& basis) {
  P2sNetConfig c;
  c.j_max = basis.j_max;
  c.count = basis.count();
  if (basis.count() >= 2 && basis.variances[1] > 0) c.output_scale = std::sqrt(basis.variances[1]);
  return c;
}

P2sNet::P2sNet(const Device& device, const P2sNetConfig& config)
    : l1((check_config(config),
          register_module("l1", std::make_unique<nets::Linear>(device, config.j_max - 3,
                                                               config.hidden, true, config.seed)))),
      l2(register_module("l2", std::make_unique<nets::Linear>(device, config.hidden, config.hidden,
                                                              true, config.seed + 1))),
      l3(register_module(
          "l3", std::make_unique<nets::Linear>(device, config.hidden, config.count - 1, true,
                                               config.seed + 2))),
      config_(config) {
  input_scale = register_buffer(
      "input_scale", Tensor::from(device, Shape{config.j_max - 3}, input_scales(config)));
}

nets::Var P2sNet::forward_normalized(nets::Tape& t, const nets::Var& coeffs) const {
  if (coeffs.shape().rank() != 2 || coeffs.shape()[1] != inputs())
    throw InvalidArgument("sim::P2sNet::forward",
                          "coefficients have shape " + coeffs.shape().str() + ", expected [P, " +
                              std::to_string(inputs()) + "] (a_4..a_" +
                              std::to_string(config_.j_max) + ")",
                          "pass one row of j_max − 3 radians per PSF");
  nets::Var h = nets::mul_channel(t, coeffs, input_scale);
  h = nets::leaky_relu(t, l1.forward(t, h), kLeakySlope);
  h = nets::leaky_relu(t, l2.forward(t, h), kLeakySlope);
  return l3.forward(t, h);
}

nets::Var P2sNet::forward(nets::Tape& t, const nets::Var& coeffs) const {
  return nets::scale_shift(t, forward_normalized(t, coeffs), config_.output_scale);
}

std::vector<float> predict_betas(const Device& device, const P2sNet& net,
                                 std::span<const double> coeffs) {
  const int in = net.inputs();
  if (coeffs.size() % sz(in) != 0)
    throw InvalidArgument(
        "sim::predict_betas",
        std::to_string(coeffs.size()) + " coefficients are not rows of " + std::to_string(in),
        "pass count × (j_max − 3) values");
  const std::size_t count = coeffs.size() / sz(in);
  const int k = net.config().count;
  std::vector<float> betas(count * sz(k));
  constexpr std::size_t kChunk = 4096;
  Stream stream(device);
  for (std::size_t first = 0; first < count; first += kChunk) {
    const std::size_t n = std::min(kChunk, count - first);
    const std::vector<float> x(coeffs.begin() + std::ptrdiff_t(first * sz(in)),
                               coeffs.begin() + std::ptrdiff_t((first + n) * sz(in)));
    nets::Tape tape(stream, /*recording=*/false);
    const nets::Var y =
        net.forward(tape, nets::Var(Tensor::from(device, Shape{std::int64_t(n), in}, x)));
    stream.run();
    const std::vector<float> out = y.value().download();
    for (std::size_t i = 0; i < n; ++i) {
      float* row = betas.data() + (first + i) * sz(k);
      row[0] = 1.f;
      std::copy_n(out.begin() + std::ptrdiff_t(i * sz(k - 1)), k - 1, row + 1);
    }
  }
  return betas;
}

namespace {

struct Pairs {
  std::vector<double> coeffs;  // [n, J − 3]
  std::vector<float> psfs;     // [n, S²]
  std::vector<float> betas;    // [n, K]
};

Pairs draw_pairs(const WavePsf& psf, const PsfBasis& basis, const NollSampler& noll,
                 const P2sTrainConfig& c, std::uint64_t seed, int count,
                 const P2sProgressFn& progress, const char* stage) {
  Rng rng(seed);
  Pairs p;
  const std::vector<double> drawn =
      draw_aberrations(rng, noll, c.d_over_r0_min, c.d_over_r0_max, count);
  const std::size_t modes = sz(psf.modes());
  const std::size_t pixels = sz(std::int64_t(basis.size) * basis.size);
  p.psfs.resize(sz(count) * pixels);
  constexpr int kChunk = 1024;
  for (int first = 0; first < count; first += kChunk) {
    const int n = std::min(kChunk, count - first);
    psf.compute(std::span<const double>(drawn).subspan(sz(first) * modes, sz(n) * modes),
                std::span<float>(p.psfs).subspan(sz(first) * pixels, sz(n) * pixels));
    if (progress) progress({stage, first + n, count, 0});
  }
  p.betas = project(basis, p.psfs);
  p.coeffs = leading_columns(drawn, psf.modes(), basis.j_max - 3);
  return p;
}

}  // namespace

P2sTrainReport train_p2s(Device& device, P2sNet& net, const PsfBasis& basis,
                         const P2sTrainConfig& c, const P2sProgressFn& progress) {
  const auto t0 = Clock::now();
  const char* op = "sim::train_p2s";
  if (net.config().j_max != basis.j_max || net.config().count != basis.count())
    throw InvalidArgument(op,
                          "the network (j_max " + std::to_string(net.config().j_max) + ", K " +
                              std::to_string(net.config().count) +
                              ") does not fit the basis (j_max " + std::to_string(basis.j_max) +
                              ", K " + std::to_string(basis.count()) + ")",
                          "build the network from p2s_config_for(basis)");
  if (c.steps < 1 || c.batch < 1 || c.train_samples < c.batch || c.test_samples < 1)
    throw InvalidArgument(op, "needs steps ≥ 1, batch ≥ 1, train_samples ≥ batch, test_samples ≥ 1",
                          "check the P2sTrainConfig");

  const int drawn = std::max(basis.j_max, c.residual_j_max);
  const WavePsf psf(device, PsfSampling{basis.nyquist, basis.size, drawn, c.min_pupil_px});
  const NollSampler noll(drawn);
  const Pairs train = draw_pairs(psf, basis, noll, c, c.seed, c.train_samples, progress, "data");
  P2sTrainReport report;
  report.data_seconds = seconds_since(t0);

  const int in = net.inputs(), out = net.outputs(), k = basis.count();
  const float inv_scale = 1.f / net.config().output_scale;
  std::vector<float> xs(sz(c.batch) * sz(in)), ys(sz(c.batch) * sz(out));
  std::vector<std::uint32_t> order(sz(c.train_samples));
  std::iota(order.begin(), order.end(), 0u);
  Rng rng(c.seed ^ 0x9e3779b97f4a7c15ull);
  std::size_t cursor = order.size();

  kernels::AdamOptions adam;
  adam.lr = c.lr;
  nets::Adam optimizer(net.named_parameters(), adam);
  const nets::WarmupCosine schedule{c.lr, c.min_lr, c.warmup_steps, std::uint32_t(c.steps)};
  net.train();
  const auto t_train = Clock::now();
  Stream stream(device);
  std::vector<double> recent;
  for (int step = 0; step < c.steps; ++step) {
    for (int b = 0; b < c.batch; ++b) {
      if (cursor == order.size()) {  // a new epoch: Fisher–Yates with our seeded Rng
        for (std::size_t i = order.size() - 1; i > 0; --i)
          std::swap(order[i], order[sz(std::int64_t(rng.bits() % (i + 1)))]);
        cursor = 0;
      }
      const std::size_t s = order[cursor++];
      for (int j = 0; j < in; ++j)
        xs[sz(b) * sz(in) + sz(j)] = static_cast<float>(train.coeffs[s * sz(in) + sz(j)]);
      for (int j = 0; j < out; ++j)
        ys[sz(b) * sz(out) + sz(j)] = train.betas[s * sz(k) + sz(j) + 1] * inv_scale;
    }
    nets::Tape tape(stream);
    const nets::Var x(Tensor::from(device, Shape{c.batch, in}, xs));
    const nets::Var y(Tensor::from(device, Shape{c.batch, out}, ys));
    const nets::Var loss = nets::mse_loss(tape, net.forward_normalized(tape, x), y);
    optimizer.zero_grad();
    tape.backward(loss);
    optimizer.set_lr(schedule.at(std::uint32_t(step)));
    optimizer.step(stream);
    stream.run();
    const double l = loss.value().download()[0];
    if (!std::isfinite(l))
      throw Error(
          op, "the training loss became " + std::to_string(l) + " at step " + std::to_string(step),
          "lower the learning rate");
    recent.push_back(l);
    if (recent.size() > 50) recent.erase(recent.begin());
    if (progress && (step % 50 == 0 || step + 1 == c.steps))
      progress({"train", step + 1, c.steps, l});
  }
  net.eval();
  report.steps = c.steps;
  report.final_loss = std::accumulate(recent.begin(), recent.end(), 0.0) / double(recent.size());
  report.train_seconds = seconds_since(t_train);

  const Pairs test = draw_pairs(psf, basis, noll, c, c.seed + 1, c.test_samples, progress, "test");
  const int pixels = basis.size * basis.size;
  const std::vector<float> predicted = reconstruct(basis, predict_betas(device, net, test.coeffs));
  report.test_p2s_rel_l2 = mean_relative_l2(predicted, test.psfs, pixels);
  report.test_pca_rel_l2 = mean_relative_l2(reconstruct(basis, test.betas), test.psfs, pixels);
  report.test_mean_rel_l2 = mean_relative_l2(reconstruct(basis, test.betas, 1), test.psfs, pixels);
  {
    const std::size_t n = sz(std::min(c.test_samples, c.train_samples));
    const std::span<const double> a(train.coeffs.data(), n * sz(in));
    const std::span<const float> h(train.psfs.data(), n * sz(pixels));
    report.train_p2s_rel_l2 =
        mean_relative_l2(reconstruct(basis, predict_betas(device, net, a)), h, pixels);
  }
  report.total_seconds = seconds_since(t0);
  return report;
}

// ---- artifact ---------------------------------------------------------------------

namespace {

std::string fmt_double(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

vkjr2::HostTensor host_of(const Tensor& t) {
  const auto dims = t.shape().dims();
  return {std::vector<std::int64_t>(dims.begin(), dims.end()), t.download()};
}

}  // namespace

void save_p2s_model(const std::filesystem::path& path, const PsfBasis& basis, const P2sNet& net) {
  const P2sNetConfig& c = net.config();
  const auto s = std::int64_t(basis.size);
  if (basis.size < 1 || basis.kernels.size() != sz(basis.count()) * sz(s * s) ||
      c.count != basis.count() || c.j_max != basis.j_max)
    throw InvalidArgument("sim::save_p2s_model",
                          "the basis (K " + std::to_string(basis.count()) + ", j_max " +
                              std::to_string(basis.j_max) + ") and the network (K " +
                              std::to_string(c.count) + ", j_max " + std::to_string(c.j_max) +
                              ") do not belong together, or the basis is malformed",
                          "save the network trained for this basis");
  std::map<std::string, vkjr2::HostTensor> tensors;
  tensors["basis.kernels"] = {{basis.count(), s, s}, basis.kernels};
  tensors["basis.variances"] = {{basis.count()}, basis.variances};
  for (const auto& [name, v] : net.named_parameters()) tensors["p2s." + name] = host_of(v.value());
  for (const auto& [name, v] : net.named_buffers()) tensors["p2s." + name] = host_of(v.value());
  const std::map<std::string, std::string> meta{
      {"format", kFormat},
      {"version", kVersion},
      {"size", std::to_string(basis.size)},
      {"count", std::to_string(basis.count())},
      {"nyquist", fmt_double(basis.nyquist)},
      {"j_max", std::to_string(basis.j_max)},
      {"hidden", std::to_string(c.hidden)},
      {"input_d_over_r0", fmt_double(c.input_d_over_r0)},
      {"output_scale", fmt_double(c.output_scale)},
  };
  nets::write_safetensors_f32(path, tensors, meta);
}

namespace {

class ModelReader {
 public:
  explicit ModelReader(const std::filesystem::path& path) : path_(path.string()) {
    try {
      file_ = nets::read_safetensors(path);
    } catch (const InvalidArgument&) {
      throw;
    } catch (const Error& e) {
      fail(e.problem(), "check the path, or make the model again with `vkjr2 sim-train`");
    }
  }

  [[noreturn]] void fail(const std::string& problem, const std::string& fix = {}) const {
    throw InvalidArgument("sim::load_p2s_model", path_ + ": " + problem,
                          fix.empty() ? "make the model again with `vkjr2 sim-train`" : fix);
  }

  const std::string& meta(const std::string& key) const {
    const auto it = file_.metadata.find(key);
    if (it == file_.metadata.end()) fail("metadata \"" + key + "\" is missing (not a P2S model?)");
    return it->second;
  }
  double meta_double(const std::string& key) const {
    const std::string& s = meta(key);
    std::size_t used = 0;
    double v = 0;
    try {
      v = std::stod(s, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != s.size() || s.empty() || !std::isfinite(v))
      fail("metadata \"" + key + "\" = \"" + s + "\" is not a finite number");
    return v;
  }
  int meta_int(const std::string& key, int lo, int hi) const {
    const double v = meta_double(key);
    if (v != std::floor(v) || v < lo || v > hi)
      fail("metadata \"" + key + "\" = " + meta(key) + " is not an integer in " +
           std::to_string(lo) + ".." + std::to_string(hi));
    return static_cast<int>(v);
  }

  // The tensor's values, checked for shape and finiteness; marks it used.
  std::vector<float> take(const std::string& name, const std::vector<std::int64_t>& shape) {
    const nets::SafetensorsRecord* r = file_.find(name);
    if (r == nullptr) fail("tensor \"" + name + "\" is missing");
    if (r->shape != shape)
      fail("tensor \"" + name + "\" has shape " + vkjr2::shape_str(r->shape) + ", expected " +
           vkjr2::shape_str(shape));
    used_.insert(name);
    std::vector<float> v = r->to_float();
    for (std::size_t i = 0; i < v.size(); ++i)
      if (!std::isfinite(v[i]))
        fail("tensor \"" + name + "\" holds a non-finite value at element " + std::to_string(i));
    return v;
  }

  void check_all_used() const {
    for (const auto& r : file_.tensors)
      if (!used_.contains(r.name)) fail("unexpected tensor \"" + r.name + "\"");
  }

 private:
  std::string path_;
  nets::SafetensorsFile file_;
  std::set<std::string> used_;
};

}  // namespace

P2sModel load_p2s_model(const Device& device, const std::filesystem::path& path) {
  ModelReader r(path);
  if (r.meta("format") != kFormat)
    r.fail("format is \"" + r.meta("format") + "\", not \"" + kFormat + "\"");
  if (r.meta("version") != kVersion)
    r.fail("version " + r.meta("version") + " is not supported (this build reads " + kVersion +
           ")");
  P2sModel m;
  m.basis.size = r.meta_int("size", 1, 1023);
  if (m.basis.size % 2 == 0) r.fail("size " + std::to_string(m.basis.size) + " is not odd");
  const int count = r.meta_int("count", 2, 1 << 20);
  m.basis.nyquist = r.meta_double("nyquist");
  if (m.basis.nyquist <= 0) r.fail("nyquist " + r.meta("nyquist") + " is not positive");
  m.basis.j_max = r.meta_int("j_max", 4, kMaxZernikeModes);
  const auto s = std::int64_t(m.basis.size);
  m.basis.kernels = r.take("basis.kernels", {count, s, s});
  m.basis.variances = r.take("basis.variances", {count});

  P2sNetConfig c;
  c.j_max = m.basis.j_max;
  c.count = count;
  c.hidden = r.meta_int("hidden", 1, 1 << 16);
  c.input_d_over_r0 = r.meta_double("input_d_over_r0");
  c.output_scale = static_cast<float>(r.meta_double("output_scale"));
  if (c.input_d_over_r0 <= 0 || !(c.output_scale > 0))
    r.fail("input_d_over_r0 or output_scale is not positive");
  m.net = std::make_unique<P2sNet>(device, c);
  auto load = [&](const std::string& name, const nets::Var& v) {
    const auto dims = v.shape().dims();
    const std::vector<std::int64_t> shape(dims.begin(), dims.end());
    v.set_value(Tensor::from(device, v.shape(), r.take("p2s." + name, shape)));
  };
  for (const auto& [name, v] : m.net->named_parameters()) load(name, v);
  for (const auto& [name, v] : m.net->named_buffers()) load(name, v);
  r.check_all_used();
  m.net->eval();
  return m;
}

P2sTrainReport make_p2s_artifact(Device& device, const Params& params,
                                 const P2sArtifactConfig& config, const std::filesystem::path& out,
                                 const P2sProgressFn& progress) {
  const auto t0 = Clock::now();
  const Derived d = derive(params);
  if (config.channel < 0 || config.channel >= int(d.channels.size()))
    throw InvalidArgument("sim::make_p2s_artifact",
                          "channel " + std::to_string(config.channel) + " is outside 0.." +
                              std::to_string(int(d.channels.size()) - 1),
                          "pick a channel of the parameters' image");
  const double nyquist = d.channels[sz(config.channel)].nyquist;
  if (progress) progress({"basis", 0, 1, 0});
  const PsfBasis basis = make_psf_basis(device, nyquist, params.zernike_modes, config.basis);
  if (progress) progress({"basis", 1, 1, 0});
  const double basis_seconds = seconds_since(t0);

  P2sNetConfig nc = p2s_config_for(basis);
  nc.hidden = config.hidden;
  nc.input_d_over_r0 = config.input_d_over_r0;
  nc.seed = config.net_seed;
  P2sNet net(device, nc);
  P2sTrainReport report = train_p2s(device, net, basis, config.train, progress);
  save_p2s_model(out, basis, net);
  report.basis_seconds = basis_seconds;
  report.total_seconds = seconds_since(t0);
  return report;
}

}  // namespace vkjr2::sim
