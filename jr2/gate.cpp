#include "gate.hpp"

#include <vkjr2/jr2/protocol.hpp>
#include <vkjr2/nets/layers.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/nets/optimizer.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <utility>

#include "internal/text_and_draws.hpp"

namespace vkjr2::jr2 {
namespace {

constexpr const char* kKind = "vkjr2.gate";
constexpr int kDescriptorSize = 128;
constexpr double kInvE = 0.36787944117144233;  // 1/e: the label of an unchanged rank
constexpr std::array<double, 5> kMargins = {0, 0.05, 0.1, 0.2, 1};

std::string num(double x) { return detail::number_text(x, 17); }

double normal_density(double x, double mu, double sigma) {
  const double z = (x - mu) / sigma;
  return std::exp(-0.5 * z * z) / (sigma * std::sqrt(2 * std::numbers::pi));
}

void require(bool ok, const std::string& problem, const std::string& fix) {
  if (!ok) throw InvalidArgument("jr2::Gate", problem, fix);
}

// One head: features → hidden (ReLU) → 1.
class Head : public nets::Module {
 public:
  Head(const Device& device, int in, int hidden, std::uint32_t seed)
      : fc1(register_module("fc1", std::make_unique<nets::Linear>(device, in, hidden, true, seed))),
        fc2(register_module("fc2",
                            std::make_unique<nets::Linear>(device, hidden, 1, true, seed + 1))) {}
  nets::Var forward(nets::Tape& t, const nets::Var& x) const {
    return fc2.forward(t, nets::relu(t, fc1.forward(t, x)));
  }
  nets::Linear& fc1;
  nets::Linear& fc2;
};

class HeadPair : public nets::Module {
 public:
  HeadPair(const Device& device, int in, int hidden, std::uint32_t seed)
      : score(register_module("score", std::make_unique<Head>(device, in, hidden, seed))),
        rank(register_module("rank", std::make_unique<Head>(device, in, hidden, seed + 100))) {}
  Head& score;
  Head& rank;
};

// Per feature, the training set's mean and standard deviation (1 where it
// does not vary).
std::pair<std::vector<float>, std::vector<float>> standardization(
    const std::vector<std::vector<float>>& rows) {
  const std::size_t f = rows.front().size();
  std::vector<double> mean(f, 0), var(f, 0);
  for (const auto& r : rows) {
    for (std::size_t j = 0; j < f; ++j) mean[j] += r[j] / double(rows.size());
  }
  for (const auto& r : rows) {
    for (std::size_t j = 0; j < f; ++j) var[j] += (r[j] - mean[j]) * (r[j] - mean[j]);
  }
  std::vector<float> m(f), s(f);
  for (std::size_t j = 0; j < f; ++j) {
    m[j] = float(mean[j]);
    const double sd = std::sqrt(var[j] / double(rows.size()));
    s[j] = sd > 1e-9 ? float(sd) : 1.f;
  }
  return {m, s};
}

double reciprocal_rank(const GateSample& s, bool restore) {
  return 1.0 / double(restore ? s.rank_post : s.rank_raw);
}

}  // namespace

struct Gate::Heads {
  std::vector<float> mean, stdev;  // per input feature
  std::unique_ptr<HeadPair> net;
};

std::vector<std::string> gate_feature_names(bool with_descriptor) {
  std::vector<std::string> n = {"descriptor_norm", "detector_score", "tracked_share",
                                "log_d_over_r0", "sharpness"};
  if (with_descriptor) {
    for (int i = 0; i < kDescriptorSize; ++i) n.push_back("descriptor." + std::to_string(i));
  }
  return n;
}

std::vector<float> gate_feature_vector(const GateFeatures& f, bool with_descriptor) {
  std::vector<float> v = {float(f.descriptor_norm), float(f.detector_score), float(f.tracked_share),
                          float(std::log(std::max(f.d_over_r0, 1e-3))), float(f.sharpness)};
  if (with_descriptor) {
    if (f.acquired && f.descriptor.size() != std::size_t(kDescriptorSize)) {
      throw InvalidArgument("jr2::gate_feature_vector",
                            "the template has " + std::to_string(f.descriptor.size()) +
                                " values, not " + std::to_string(kDescriptorSize),
                            "give the face recognizer's template");
    }
    for (int i = 0; i < kDescriptorSize; ++i) {
      v.push_back(f.acquired ? f.descriptor[std::size_t(i)] : 0.f);
    }
  }
  return v;
}

double gate_sharpness(std::span<const float> grey, int height, int width, int x0, int y0, int x1,
                      int y1) {
  if (grey.size() != std::size_t(height) * std::size_t(width) || height < 3 || width < 3) {
    throw InvalidArgument("jr2::gate_sharpness",
                          "a grey image of " + std::to_string(grey.size()) + " values is not " +
                              std::to_string(height) + "×" + std::to_string(width) +
                              " (at least 3×3)",
                          "give the frame's grey plane");
  }
  // The Laplacian needs a neighbour on each side.
  x0 = std::max(x0, 1);
  y0 = std::max(y0, 1);
  x1 = std::min(x1, width - 1);
  y1 = std::min(y1, height - 1);
  if (x1 - x0 < 3 || y1 - y0 < 3) {
    throw InvalidArgument("jr2::gate_sharpness",
                          "the box is smaller than 3×3 inside the " + std::to_string(width) + "×" +
                              std::to_string(height) + " image",
                          "give a box that overlaps the image");
  }
  double sum = 0, sum2 = 0, lap2 = 0;
  const auto at = [&](int y, int x) { return double(grey[std::size_t(y) * width + x]); };
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      const double v = at(y, x);
      const double l = at(y - 1, x) + at(y + 1, x) + at(y, x - 1) + at(y, x + 1) - 4 * v;
      sum += v;
      sum2 += v * v;
      lap2 += l * l;
    }
  }
  const double n = double(x1 - x0) * double(y1 - y0);
  const double var = std::max(sum2 / n - (sum / n) * (sum / n), 0.0);
  return std::log((lap2 / n + 1e-6) / (var + 1e-6));
}

double rank_change_label(int rank_raw, int rank_post) {
  if (rank_raw < 1 || rank_post < 1) {
    throw InvalidArgument("jr2::rank_change_label",
                          "ranks " + std::to_string(rank_raw) + " and " +
                              std::to_string(rank_post) + " (they start at 1)",
                          "give the mate's 1-based ranks");
  }
  return std::exp(double(rank_raw - rank_post) / double(rank_raw) - 1.0);
}

double rank_label_reweighting(double m) {
  return -1.25 + normal_density(m, -0.25, 0.2) + normal_density(m, -kInvE, 0.18) +
         normal_density(m, 1 - kInvE, 0.3);
}

void GateTrainOptions::validate() const {
  const auto bad = [](const std::string& what, const std::string& fix) {
    throw InvalidArgument("jr2::GateTrainOptions", what, fix);
  };
  if (hidden < 1 || hidden > 1024) bad("hidden " + std::to_string(hidden), "use 1..1024");
  if (steps < 1 || steps > 1000000) bad("steps " + std::to_string(steps), "use 1..1000000");
  if (!(lr > 0 && lr < 1)) bad("lr " + num(lr), "use a learning rate in (0, 1)");
  if (!(weight_decay >= 0 && weight_decay < 1)) {
    bad("weight_decay " + num(weight_decay), "use a value in [0, 1)");
  }
  if (!(weight_floor > 0 && weight_floor <= 10)) {
    bad("weight_floor " + num(weight_floor), "use a value in (0, 10]");
  }
}

Gate::Gate(std::unique_ptr<Heads> heads, GateTrainOptions options)
    : heads_(std::move(heads)), options_(options) {}
Gate::Gate(Gate&&) noexcept = default;
Gate& Gate::operator=(Gate&&) noexcept = default;
Gate::~Gate() = default;

nets::Var Gate::forward(nets::Tape& tape, int head, const nets::Var& x) const {
  if (head == 0) return heads_->net->score.forward(tape, x);
  return nets::sigmoid(tape, heads_->net->rank.forward(tape, x));
}

Tensor Gate::inputs(const Device& device, std::span<const GateFeatures> probes) const {
  const std::size_t f = heads_->mean.size();
  std::vector<float> x;
  x.reserve(probes.size() * f);
  for (const GateFeatures& p : probes) {
    const std::vector<float> v = gate_feature_vector(p, options_.descriptor);
    for (std::size_t j = 0; j < f; ++j) {
      const float z = (v[j] - heads_->mean[j]) / heads_->stdev[j];
      require(std::isfinite(z),
              "feature " + gate_feature_names(options_.descriptor)[j] + " is " + num(v[j]),
              "give finite features (a NaN frame or a failed estimate upstream)");
      x.push_back(z);
    }
  }
  return Tensor::from(device, Shape{std::int64_t(probes.size()), std::int64_t(f)}, x);
}

Gate Gate::train(const Device& device, std::span<const GateSample> train,
                 const GateTrainOptions& options) {
  options.validate();
  std::vector<GateFeatures> score_x, rank_x;
  std::vector<float> score_y, rank_y, rank_w;
  for (const GateSample& s : train) {
    if (!s.features.acquired) continue;
    require(std::isfinite(s.quality), s.file + ": quality " + num(s.quality),
            "label the probe again");
    score_x.push_back(s.features);
    score_y.push_back(float(s.quality));
    if (s.mated) {
      const double label = rank_change_label(s.rank_raw, s.rank_post);
      rank_x.push_back(s.features);
      rank_y.push_back(float(label));
      rank_w.push_back(
          float(std::max(rank_label_reweighting(label - kInvE), double(options.weight_floor))));
    }
  }
  require(score_x.size() >= 3 && rank_x.size() >= 3,
          std::to_string(score_x.size()) + " probes with a template, " +
              std::to_string(rank_x.size()) + " of them mated",
          "train on a split with at least 3 of each (a larger benchmark, or both its splits)");
  double wsum = 0;
  for (float w : rank_w) wsum += w;
  for (float& w : rank_w) w = float(w * double(rank_w.size()) / wsum);  // mean 1

  auto heads = std::make_unique<Heads>();
  std::vector<std::vector<float>> rows;
  for (const GateFeatures& f : score_x) rows.push_back(gate_feature_vector(f, options.descriptor));
  std::tie(heads->mean, heads->stdev) = standardization(rows);
  const int in = int(heads->mean.size());
  heads->net = std::make_unique<HeadPair>(device, in, options.hidden, options.seed);
  Gate gate(std::move(heads), options);

  const Tensor xs = gate.inputs(device, score_x), xr = gate.inputs(device, rank_x);
  const auto column = [&](const std::vector<float>& v) {
    return Tensor::from(device, Shape{std::int64_t(v.size()), 1}, v);
  };
  const nets::Var ys(column(score_y)), yr(column(rank_y)), wr(column(rank_w));
  nets::Adam adam(gate.heads_->net->named_parameters(),
                  {.lr = options.lr, .weight_decay = options.weight_decay, .decoupled = true});
  Stream stream(device);
  for (int step = 0; step < options.steps; ++step) {
    nets::Tape tape(stream);
    const nets::Var ds = nets::sub(tape, gate.forward(tape, 0, nets::Var(xs)), ys);
    const nets::Var dr = nets::sub(tape, gate.forward(tape, 1, nets::Var(xr)), yr);
    const nets::Var loss =
        nets::add(tape, nets::mean_all(tape, nets::mul(tape, ds, ds)),
                  nets::mean_all(tape, nets::mul(tape, nets::mul(tape, dr, dr), wr)));
    adam.zero_grad();
    tape.backward(loss);
    adam.step(stream);
    stream.run();
  }
  return gate;
}

bool Gate::decide(bool acquired, double quality, double rank_label, double quality_threshold,
                  double rank_margin) {
  if (!acquired) return true;  // nothing to lose: restoring may let the face be found
  return quality < quality_threshold && rank_label >= kInvE - rank_margin;
}

std::vector<GatePrediction> Gate::predict(Stream& stream,
                                          std::span<const GateFeatures> probes) const {
  std::vector<GatePrediction> out(probes.size());
  if (probes.empty()) return out;
  nets::Tape tape(stream, false);
  const nets::Var x(inputs(stream.device(), probes));
  const Tensor q = forward(tape, 0, x).value(), r = forward(tape, 1, x).value();
  stream.run();
  const std::vector<float> qv = q.download(), rv = r.download();
  for (std::size_t i = 0; i < probes.size(); ++i) {
    out[i].quality = qv[i];
    out[i].rank_label = rv[i];
    out[i].restore = decide(probes[i].acquired, qv[i], rv[i], quality_threshold_, rank_margin_);
  }
  return out;
}

GatePrediction Gate::predict(Stream& stream, const GateFeatures& probe) const {
  return predict(stream, std::span(&probe, 1)).front();
}

void Gate::set_thresholds(double quality_threshold, double rank_margin) {
  require(!std::isnan(quality_threshold) && rank_margin >= 0 && rank_margin <= 1,
          "threshold " + num(quality_threshold) + ", margin " + num(rank_margin),
          "give a threshold that is a number and a margin in [0, 1]");
  quality_threshold_ = quality_threshold;
  rank_margin_ = rank_margin;
}

GateOutcome gate_outcome(std::span<const GateSample> samples, std::span<const bool> restore) {
  require(
      samples.size() == restore.size(),
      std::to_string(samples.size()) + " samples, " + std::to_string(restore.size()) + " decisions",
      "give one decision per sample");
  GateOutcome o;
  o.probes = samples.size();
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const GateSample& s = samples[i];
    o.restored += restore[i] ? 1 : 0;
    if (!s.mated) continue;
    require(s.rank_raw >= 1 && s.rank_post >= 1, s.file + ": a mated probe without ranks",
            "label the probe again");
    ++o.mated;
    o.mrr_degraded += reciprocal_rank(s, false);
    o.mrr_restored += reciprocal_rank(s, true);
    o.mrr_gated += reciprocal_rank(s, restore[i]);
    o.rank1_degraded += s.rank_raw == 1 ? 1 : 0;
    o.rank1_restored += s.rank_post == 1 ? 1 : 0;
    o.rank1_gated += (restore[i] ? s.rank_post : s.rank_raw) == 1 ? 1 : 0;
  }
  if (o.mated > 0) {
    o.mrr_degraded /= double(o.mated);
    o.mrr_restored /= double(o.mated);
    o.mrr_gated /= double(o.mated);
  }
  return o;
}

GateOutcome Gate::outcome(Stream& stream, std::span<const GateSample> samples) const {
  std::vector<GateFeatures> f;
  for (const GateSample& s : samples) f.push_back(s.features);
  const std::vector<GatePrediction> p = predict(stream, f);
  std::unique_ptr<bool[]> restore(new bool[p.size()]);
  for (std::size_t i = 0; i < p.size(); ++i) restore[i] = p[i].restore;
  GateOutcome o = gate_outcome(samples, std::span<const bool>(restore.get(), p.size()));
  o.quality_threshold = quality_threshold_;
  o.rank_margin = rank_margin_;
  return o;
}

GateOutcome Gate::choose_thresholds(Stream& stream, std::span<const GateSample> validation) {
  require(!validation.empty(), "no validation probes", "give a split with probes");
  std::vector<GateFeatures> f;
  for (const GateSample& s : validation) f.push_back(s.features);
  const std::vector<GatePrediction> p = predict(stream, f);
  std::vector<double> taus = {-std::numeric_limits<double>::infinity(),
                              std::numeric_limits<double>::infinity()};
  for (const GatePrediction& q : p) taus.push_back(std::nextafter(q.quality, 1e9));
  std::sort(taus.begin(), taus.end());
  taus.erase(std::unique(taus.begin(), taus.end()), taus.end());
  std::unique_ptr<bool[]> restore(new bool[p.size()]);
  bool have = false;
  GateOutcome best;
  for (double margin : kMargins) {
    for (double tau : taus) {
      for (std::size_t i = 0; i < p.size(); ++i) {
        restore[i] = decide(f[i].acquired, p[i].quality, p[i].rank_label, tau, margin);
      }
      GateOutcome o = gate_outcome(validation, std::span<const bool>(restore.get(), p.size()));
      o.quality_threshold = tau;
      o.rank_margin = margin;
      const bool better =
          !have || o.mrr_gated > best.mrr_gated + 1e-12 ||
          (std::abs(o.mrr_gated - best.mrr_gated) <= 1e-12 && o.restored < best.restored);
      if (better) {
        best = o;
        have = true;
      }
    }
  }
  set_thresholds(best.quality_threshold, best.rank_margin);
  return best;
}

void Gate::save(const std::filesystem::path& path) const {
  std::map<std::string, std::string> meta = metadata;
  meta["kind"] = kKind;
  meta["features"] = std::to_string(heads_->mean.size());
  meta["descriptor"] = options_.descriptor ? "1" : "0";
  meta["hidden"] = std::to_string(options_.hidden);
  meta["align"] = align_mode_name(align_);
  meta["quality_threshold"] = num(quality_threshold_);
  meta["rank_margin"] = num(rank_margin_);
  meta["train.steps"] = std::to_string(options_.steps);
  meta["train.lr"] = num(options_.lr);
  meta["train.weight_decay"] = num(options_.weight_decay);
  meta["train.weight_floor"] = num(options_.weight_floor);
  meta["train.seed"] = std::to_string(options_.seed);
  std::vector<nets::SafetensorsRecord> records;
  const std::int64_t f = std::int64_t(heads_->mean.size());
  records.push_back(nets::SafetensorsRecord::f32("feature_mean", {f}, heads_->mean));
  records.push_back(nets::SafetensorsRecord::f32("feature_std", {f}, heads_->stdev));
  for (const auto& [name, var] : heads_->net->named_parameters()) {
    std::vector<std::int64_t> shape(var.shape().dims().begin(), var.shape().dims().end());
    records.push_back(nets::SafetensorsRecord::f32(name, shape, var.value().download()));
  }
  nets::write_safetensors(path, records, meta);
}

Gate Gate::load(const Device& device, const std::filesystem::path& path) {
  const nets::SafetensorsFile file = nets::read_safetensors(path);
  const auto fail = [&](const std::string& problem) {
    throw Error("load gate", path.string() + ": " + problem,
                "give a file `vkjr2 gate train` wrote (or train one again)");
  };
  const auto meta = [&](const char* key) {
    const auto it = file.metadata.find(key);
    if (it == file.metadata.end()) fail("no metadata key '" + std::string(key) + "'");
    return it->second;
  };
  const auto number = [&](const char* key) {
    const std::string s = meta(key);
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || end != s.c_str() + s.size())
      fail("metadata " + std::string(key) + " = '" + s + "'");
    return v;
  };
  if (file.metadata.count("kind") == 0 || file.metadata.at("kind") != kKind) {
    throw Error("load gate",
                path.string() + " is not a gate (metadata kind is not '" + kKind + "')",
                "give the file `vkjr2 gate train` wrote");
  }
  GateTrainOptions o;
  o.descriptor = meta("descriptor") == "1";
  o.hidden = int(number("hidden"));
  o.steps = int(number("train.steps"));
  o.lr = float(number("train.lr"));
  o.weight_decay = float(number("train.weight_decay"));
  o.weight_floor = float(number("train.weight_floor"));
  o.seed = std::uint32_t(number("train.seed"));
  try {
    o.validate();
  } catch (const InvalidArgument& e) {
    fail(e.problem());
  }
  const int f = int(number("features"));
  const int expected = kGateSummaryFeatures + (o.descriptor ? kDescriptorSize : 0);
  if (f != expected) {
    fail(std::to_string(f) + " features, not the " + std::to_string(expected) + " it names");
  }
  auto heads = std::make_unique<Heads>();
  const auto vector_of = [&](const char* name) {
    const nets::SafetensorsRecord* r = file.find(name);
    if (r == nullptr || r->shape != std::vector<std::int64_t>{f}) {
      fail("tensor " + std::string(name) + " is missing or not [" + std::to_string(f) + "]");
    }
    return r->to_float();
  };
  heads->mean = vector_of("feature_mean");
  heads->stdev = vector_of("feature_std");
  for (float s : heads->stdev) {
    if (!(s > 0) || !std::isfinite(s)) fail("a feature_std value is " + num(s));
  }
  heads->net = std::make_unique<HeadPair>(device, f, o.hidden, o.seed);
  for (const auto& [name, var] : heads->net->named_parameters()) {
    const nets::SafetensorsRecord* r = file.find(name);
    const std::vector<std::int64_t> shape(var.shape().dims().begin(), var.shape().dims().end());
    if (r == nullptr || r->shape != shape) {
      fail("tensor " + name + " is missing or not " + var.shape().str());
    }
    const std::vector<float> v = r->to_float();
    for (float x : v) {
      if (!std::isfinite(x)) fail("tensor " + name + " holds a non-finite value");
    }
    var.set_value(Tensor::from(device, var.shape(), v));
  }
  Gate g(std::move(heads), o);
  const double tau = number("quality_threshold"), margin = number("rank_margin");
  if (std::isnan(tau) || !(margin >= 0 && margin <= 1)) {
    fail("quality_threshold " + num(tau) + ", rank_margin " + num(margin));
  }
  g.set_thresholds(tau, margin);
  const std::string align = meta("align");
  if (align == "similarity") {
    g.set_align(AlignMode::similarity);
  } else if (align == "face_api") {
    g.set_align(AlignMode::face_api);
  } else {
    fail("metadata align = '" + align + "' (similarity or face_api)");
  }
  g.metadata = file.metadata;
  for (const char* k :
       {"kind", "features", "descriptor", "hidden", "align", "quality_threshold", "rank_margin",
        "train.steps", "train.lr", "train.weight_decay", "train.weight_floor", "train.seed"}) {
    g.metadata.erase(k);
  }
  return g;
}

}  // namespace vkjr2::jr2
