#include <vkjr2/jr2/align.hpp>
#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/cotrain.hpp>
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/grid_sample.hpp>
#include <vkjr2/kernels/layout.hpp>
#include <vkjr2/kernels/metrics.hpp>
#include <vkjr2/nets/checkpoint.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/nets/optimizer.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <utility>

#include "internal/training.hpp"

namespace vkjr2::jr2 {
namespace {

namespace k = kernels;
using detail::Clock;
using detail::mix;
using detail::seconds_since;
using nets::Var;

constexpr std::int64_t kCrop = nets::kRecognitionInputSize;  // 150
constexpr std::uint64_t kValSeed = 0xc07a11d5eed5ull;

void require(bool ok, const std::string& what, const std::string& fix) {
  if (!ok) throw InvalidArgument("cotrain", what, fix);
}

std::string num(double x) { return detail::number_text(x, 9); }

// The checkpointed state: the student and the margin head.
class CoTrainModel : public nets::Module {
 public:
  CoTrainModel(std::unique_ptr<Restorer> s, std::unique_ptr<nets::AdaFaceHead> h)
      : student(&register_module("student", std::move(s))),
        head(&register_module("head", std::move(h))) {}
  Restorer* student;
  nets::AdaFaceHead* head;
};

// 255 · clamp(x, 0, 1) = 255 · (relu(x) − relu(x − 1)): the pixels a saved
// restored frame holds, differentiable.
Var to_pixels_var(nets::Tape& t, const Var& x) {
  const Var low = nets::relu(t, x);
  const Var high = nets::relu(t, nets::scale_shift(t, x, 1.f, -1.f));
  return nets::scale_shift(t, nets::sub(t, low, high), 255.f);
}

// theta [2×3] of the 150² similarity crop for 68 landmarks in a w×h image.
std::array<float, 6> theta_for(std::span<const double> landmarks, std::int64_t w, std::int64_t h) {
  const std::vector<float> lm(landmarks.begin(), landmarks.end());
  const Similarity s = fit_similarity(five_points(lm), canonical_points(int(kCrop)));
  return crop_theta(s, w, h, kCrop, kCrop);
}

double mean_of(const std::vector<float>& v) {
  double a = 0;
  for (float f : v) a += f;
  return v.empty() ? std::numeric_limits<double>::quiet_NaN() : a / double(v.size());
}

}  // namespace

const char* order_name(CoTrainOrder order) {
  return order == CoTrainOrder::restore_first ? "restore-first" : "align-first";
}

CoTrainOrder parse_order(const std::string& text) {
  if (text == "restore-first") return CoTrainOrder::restore_first;
  if (text == "align-first") return CoTrainOrder::align_first;
  throw InvalidArgument("cotrain", "unknown order '" + text + "'",
                        "use restore-first (the paper's method) or align-first");
}

unsigned parse_layer_groups(const std::string& text) {
  if (text == "all") return kAllLayers;
  unsigned g = 0;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t end = std::min(text.find(',', at), text.size());
    const std::string part = text.substr(at, end - at);
    if (part == "early") {
      g |= kEarlyLayers;
    } else if (part == "middle") {
      g |= kMiddleLayers;
    } else if (part == "late") {
      g |= kLateLayers;
    } else {
      std::string what = "unknown layer group '" + part;
      what += "' in '" + text + "'";
      throw InvalidArgument("cotrain", what, "use all, or a comma list of early, middle, late");
    }
    at = end + 1;
  }
  return g;
}

std::string layer_groups_name(unsigned g) {
  if (g == kAllLayers) return "all";
  std::string s;
  for (const auto& [bit, name] :
       {std::pair{kEarlyLayers, "early"}, std::pair{kMiddleLayers, "middle"},
        std::pair{kLateLayers, "late"}}) {
    if ((g & bit) != 0) s += (s.empty() ? "" : ",") + std::string(name);
  }
  return s;
}

unsigned layer_group_of(const std::string& p, int levels) {
  const auto starts = [&](const std::string& prefix) { return p.rfind(prefix, 0) == 0; };
  if (starts("intro.") || starts("encoders.0.") || starts("downs.0.")) return kEarlyLayers;
  if (starts("ending.") || starts("decoders." + std::to_string(levels - 1) + ".")) {
    return kLateLayers;
  }
  return kMiddleLayers;
}

void CoTrainOptions::validate() const {
  require(std::isfinite(lambda) && lambda >= 0 && lambda <= 1e6, "--lambda " + num(lambda),
          "use a distillation weight >= 0 (0: fine-tune without the teacher)");
  require(layers >= 1 && layers <= kAllLayers, "--layers " + std::to_string(layers),
          "use all, or a comma list of early, middle, late");
  require(window >= 64 && window <= 512 && window % 8 == 0, "--window " + std::to_string(window),
          "use 64..512 pixels, a multiple of 8 (128 holds an 80-pixel face with context)");
  require(jitter >= 0 && jitter <= 64, "--jitter " + std::to_string(jitter), "use 0..64 pixels");
  require(batch >= 2 && batch <= 256, "--batch " + std::to_string(batch),
          "use 2..256 (AdaFace's norm statistics need two clips)");
  require(steps >= 1, "--steps " + std::to_string(steps), "use at least 1 step");
  require(std::isfinite(lr) && lr > 0 && lr < 1, "--lr " + num(lr), "use (0, 1), e.g. 1e-4");
  require(std::isfinite(min_lr) && min_lr >= 0 && min_lr <= lr, "--min-lr " + num(min_lr),
          "use 0 <= min-lr <= lr");
  require(std::isfinite(weight_decay) && weight_decay >= 0 && weight_decay < 1,
          "--weight-decay " + num(weight_decay), "use a decay in [0, 1)");
  require(warmup_steps >= 0, "--warmup " + std::to_string(warmup_steps), "use >= 0 steps");
  require(std::isfinite(clip_grad_norm) && clip_grad_norm >= 0,
          "--clip-grad " + num(clip_grad_norm), "use a norm >= 0 (0: no clipping)");
  require(d_over_r0_lo > 0 && d_over_r0_hi >= d_over_r0_lo && d_over_r0_hi <= 20,
          "D/r0 range [" + num(d_over_r0_lo) + ", " + num(d_over_r0_hi) + "]",
          "use 0 < lo <= hi <= 20");
  require(pool >= batch && pool <= 100000, "--pool " + std::to_string(pool),
          "use a pool of at least --batch clips");
  require(refresh >= 0 && refresh <= pool, "--refresh " + std::to_string(refresh),
          "use 0..pool new clips per step");
  require(val_clips >= 1 && val_clips <= 4096, "--val-clips " + std::to_string(val_clips),
          "use 1..4096 held-out clips");
  k::check_adaface_params(adaface, "cotrain");
}

struct CoTrainer::Impl {
  Device device;
  CoTrainOptions o;
  std::vector<CoTrainFace> faces, val;
  std::vector<std::shared_ptr<const sim::BlurModel>> blur;
  FaceAnalyzer analyzer;
  std::unique_ptr<Restorer> teacher;
  std::unique_ptr<CoTrainModel> model;
  std::vector<std::string> identities;
  std::vector<int> labels, val_labels;  // per face
  Stream stream;
  std::int64_t size = 0, t3 = 0, win = 0;  // clip side, 3T, window side
  bool paired = true, val_paired = true;   // training clips; held-out clips
  std::unique_ptr<nets::Adam> adam;
  nets::WarmupCosine schedule;
  std::unique_ptr<detail::GradientNorm> gradient_norm;
  std::vector<std::pair<std::string, Var>> trainable;
  // Per face (train, val): the clip on the device, 0..1 ([1, 3, S, S] clean
  // or [1, 3·F, S, S] frames), and its face box (clean or mean frame).
  std::vector<Tensor> face_clip, val_clip;
  std::vector<nets::FaceBox> face_box, val_box;
  std::vector<float> centres;  // [classes, 128] clean centres (the fixed yardstick)
  bool prepared = false;
  std::vector<std::string> dropped;          // unpaired training clips without a detected face
  std::set<std::string> dropped_identities;  // identities that kept no clip (nor held-out face)
  // The pool: clip k in slot k % pool.
  Tensor pool_frames;
  std::vector<nets::FaceBox> pool_box;
  std::vector<std::int32_t> pool_label;
  std::int64_t pool_first = 0, pool_end = 0;
  Tensor batch_frames, labels_dev;
  double pending_sim_seconds = 0;
  // Held-out clips.
  Tensor val_frames, val_clean;
  std::vector<nets::FaceBox> vbox;
  std::vector<std::int32_t> vlabel;
  std::vector<CoTrainEvalReport::Row> fixed_rows;  // teacher, degraded (computed once)

  Impl(const Device& d, const CoTrainOptions& options, const std::filesystem::path& pretrained,
       std::vector<CoTrainFace> f, std::vector<CoTrainFace> v,
       std::vector<std::shared_ptr<const sim::BlurModel>> b)
      : device(d),
        o(options),
        faces(std::move(f)),
        val(std::move(v)),
        blur(std::move(b)),
        analyzer(d),
        teacher(Restorer::load(d, pretrained)),
        stream(d) {
    analyzer.recognition_net().set_frozen(true);
    for (const Var& p : teacher->parameters()) p.set_requires_grad(false);
    teacher->eval();
    const RestorerConfig& net = teacher->config();
    require(o.window % (1 << net.levels()) == 0,
            "--window " + std::to_string(o.window) + " for a restorer of " +
                std::to_string(net.levels()) + " levels",
            "use a multiple of " + std::to_string(1 << net.levels()));
    require(!faces.empty() && !val.empty(), "no training or no held-out faces",
            "pass at least one of each");
    paired = faces.front().paired();
    val_paired = val.front().paired();
    size = paired ? faces.front().clean.shape[0] : faces.front().frames.front().shape[0];
    for (const auto* list : {&faces, &val}) {
      for (const CoTrainFace& face : *list) {
        require(face.paired() == list->front().paired(),
                face.source + " is " + (face.paired() ? "" : "un") + "paired while " +
                    list->front().source + " is not",
                "pass only clean clips or only degraded ones (the held-out faces may differ "
                "from the training faces)");
        const auto check = [&](const HostTensor& im) {
          require(im.shape.size() == 3 && im.shape[0] == size && im.shape[1] == size &&
                      im.shape[2] == 3,
                  face.source + " has shape " + shape_str(im.shape),
                  "pass square " + std::to_string(size) + "×" + std::to_string(size) +
                      " RGB clips (all the same size)");
        };
        if (face.paired()) {
          check(face.clean);
        } else {
          require(int(face.frames.size()) >= net.frames,
                  face.source + " has " + std::to_string(face.frames.size()) + " frames",
                  "pass at least the restorer's " + std::to_string(net.frames));
          for (const HostTensor& im : face.frames) check(im);
        }
      }
    }
    // Unpaired clips in which the detector finds no face are left out (with
    // an identity that keeps none, and its held-out faces).
    if (!paired) keep_faces_with_a_face();
    // Identities in first-seen order; every val face's identity must train.
    std::map<std::string, int> index;
    for (const CoTrainFace& face : faces) {
      auto [it, fresh] = index.emplace(face.identity, int(identities.size()));
      if (fresh) identities.push_back(face.identity);
      labels.push_back(it->second);
    }
    require(identities.size() >= 2,
            std::to_string(identities.size()) + " training identities" +
                (dropped.empty() ? std::string()
                                 : " (" + std::to_string(dropped.size()) +
                                       " clips without a detectable face left out)"),
            dropped.empty() ? "pass faces of at least 2 identities"
                            : "use more clips per identity or a weaker turbulence range");
    for (const CoTrainFace& face : val) {
      const auto it = index.find(face.identity);
      require(it != index.end(),
              "held-out face " + face.source + " of identity '" + face.identity +
                  "' that no training face has",
              "hold out other realizations of the training identities");
      val_labels.push_back(it->second);
    }
    require(!val.empty(), "no held-out faces", "pass at least one");
    require(size >= o.window, "clips of " + std::to_string(size) + "² pixels",
            "use a --window of at most the clip side");
    win = o.order == CoTrainOrder::restore_first ? o.window : kCrop;
    t3 = 3LL * net.frames;

    // The student starts as the teacher; the head's centres are set in prepare().
    auto student = std::make_unique<Restorer>(d, net, 0);
    const auto tp = teacher->named_parameters();
    const auto sp = student->named_parameters();
    for (std::size_t i = 0; i < sp.size(); ++i) {
      const Tensor copy = Tensor::empty(d, tp[i].second.shape());
      k::copy(stream, tp[i].second.value(), copy);
      sp[i].second.set_value(copy);
      sp[i].second.set_requires_grad((layer_group_of(sp[i].first, net.levels()) & o.layers) != 0);
    }
    stream.run();
    auto head = std::make_unique<nets::AdaFaceHead>(
        d, int(nets::FaceRecognitionNet::kDescriptorSize), int(identities.size()),
        std::uint32_t(mix(o.seed, 0x68656164)), o.adaface);
    model = std::make_unique<CoTrainModel>(std::move(student), std::move(head));
    for (const auto& [name, param] : model->named_parameters()) {
      if (param.requires_grad()) trainable.emplace_back(name, param);
    }
    adam = std::make_unique<nets::Adam>(
        trainable, k::AdamOptions{.lr = o.lr, .weight_decay = o.weight_decay, .decoupled = true});
    gradient_norm = std::make_unique<detail::GradientNorm>(d, trainable);
    schedule.base_lr = o.lr;
    schedule.min_lr = o.min_lr;
    schedule.warmup_steps = std::uint32_t(o.warmup_steps);
    schedule.total_steps = std::uint32_t(o.steps);
    const std::int64_t w = o.window;
    pool_frames = Tensor::empty(d, Shape{o.pool, t3, w, w});
    pool_box.resize(std::size_t(o.pool));
    pool_label.resize(std::size_t(o.pool));
    batch_frames = Tensor::empty(d, Shape{o.batch, t3, w, w});
    labels_dev = Tensor::empty(d, Shape{o.batch}, DType::i32);
  }

  // ---- faces ----------------------------------------------------------------

  Tensor upload_face(const CoTrainFace& face) {
    if (face.paired()) return image_to_device(device, face.clean, 3, 255.f);
    std::vector<float> all;
    for (const HostTensor& im : face.frames) {
      const std::vector<float> p = image_to_planes(im, 3, 255.f);
      all.insert(all.end(), p.begin(), p.end());
    }
    return Tensor::from(device, Shape{1, 3 * std::int64_t(face.frames.size()), size, size}, all);
  }

  // The face box of a clip: the strongest detection in the clean clip (or
  // the mean of the frames; failing that, in the first frame that has one:
  // the mean of frames whose tilts are independent is smeared), trying
  // larger detector inputs first; nullopt when none is found.
  std::optional<nets::FaceBox> detect_face(const Tensor& clip) {
    const std::size_t plane = std::size_t(3 * size * size);
    const std::vector<float> all = clip.download();
    const std::size_t n = all.size() / plane;
    const auto detect = [&](const std::vector<float>& pixels) -> std::optional<nets::FaceBox> {
      const Tensor image = Tensor::from(device, Shape{1, 3, size, size}, pixels);
      for (int input : {416, 320, 224, 160}) {
        FaceOptions fo;
        fo.input_size = input;
        const auto found = analyzer.detect(stream, image, fo);
        if (!found.empty()) return found.front().box;
      }
      return std::nullopt;
    };
    std::vector<float> frame(plane, 0.f);
    for (std::size_t f = 0; f < n; ++f) {
      for (std::size_t i = 0; i < plane; ++i) frame[i] += all[f * plane + i] * 255.f / float(n);
    }
    if (auto box = detect(frame)) return box;
    for (std::size_t f = 0; n > 1 && f < n; ++f) {
      for (std::size_t i = 0; i < plane; ++i) frame[i] = all[f * plane + i] * 255.f;
      if (auto box = detect(frame)) return box;
    }
    return std::nullopt;
  }
  nets::FaceBox find_face(const CoTrainFace& face, const Tensor& clip) {
    const std::optional<nets::FaceBox> box = detect_face(clip);
    if (!box) {
      throw InvalidArgument("cotrain", "no face found in " + face.source,
                            "leave the clip out, or use clips with one visible face");
    }
    return *box;
  }

  // Descriptors [n, 128] of frames [n, 3, H, W] (pixels 0..255), aligned by
  // the landmarks found in each frame within its box.
  std::vector<float> describe(const Tensor& pixels, std::span<const nets::FaceBox> boxes) {
    return describe_crops(align_frames(pixels, thetas(pixels, boxes)));
  }
  // Descriptors of 150² crops [n, 3, 150, 150] (pixels 0..255).
  std::vector<float> describe_crops(const Tensor& crops) {
    const Tensor d = analyzer.recognition_net().describe(stream, crops);
    stream.run();
    return d.download();
  }

  // Unpaired training clips: uploads each and finds its face box; a clip in
  // none of whose frames the detector finds a face is left out, as a
  // pipeline on real footage would do, and so is a held-out face whose
  // identity keeps no training clip.
  void keep_faces_with_a_face() {
    std::vector<CoTrainFace> kept;
    std::set<std::string> kept_identities;
    for (CoTrainFace& face : faces) {
      Tensor clip = upload_face(face);
      const std::optional<nets::FaceBox> box = detect_face(clip);
      if (!box) {
        dropped.push_back(face.source);
        continue;
      }
      face_clip.push_back(std::move(clip));
      face_box.push_back(*box);
      kept_identities.insert(face.identity);
      kept.push_back(std::move(face));
    }
    faces = std::move(kept);
    std::erase_if(val, [&](const CoTrainFace& face) {
      const bool lost = !kept_identities.contains(face.identity);
      if (lost) dropped_identities.insert(face.identity);
      return lost;
    });
  }

  void prepare_faces() {
    if (prepared) return;
    if (paired) {  // unpaired clips were uploaded and found in the constructor
      for (const CoTrainFace& face : faces) {
        face_clip.push_back(upload_face(face));
        face_box.push_back(find_face(face, face_clip.back()));
      }
    }
    for (std::size_t i = 0; i < val.size(); ++i) {
      val_clip.push_back(upload_face(val[i]));
      val_box.push_back(find_face(val[i], val_clip.back()));
    }
    // Class centres: the mean clean descriptor of each identity (paired),
    // else of its first frames (the only image an unpaired face has).
    const std::size_t c = identities.size(), dim = 128;
    centres.assign(c * dim, 0.f);
    std::vector<int> count(c, 0);
    for (std::size_t i = 0; i < faces.size(); ++i) {
      const Tensor first = face_clip[i].view(Shape{1, 3, size, size}, 0);
      const Tensor px = Tensor::empty(device, Shape{1, 3, size, size});
      k::scale_shift(stream, first, 255.f, 0.f, px);
      const std::vector<float> d = describe(px, std::span(&face_box[i], 1));
      const auto l = std::size_t(labels[i]);
      for (std::size_t j = 0; j < dim; ++j) centres[l * dim + j] += d[j];
      ++count[l];
    }
    for (std::size_t l = 0; l < c; ++l) {
      for (std::size_t j = 0; j < dim; ++j) centres[l * dim + j] /= float(count[l]);
    }
    // The head's kernel is [D, C]: column l is centre l.
    std::vector<float> kernel(dim * c);
    for (std::size_t l = 0; l < c; ++l) {
      for (std::size_t j = 0; j < dim; ++j) kernel[j * c + l] = centres[l * dim + j];
    }
    model->head->weight.set_value(
        Tensor::from(device, Shape{std::int64_t(dim), std::int64_t(c)}, kernel));
    prepared = true;
  }

  // ---- clips ------------------------------------------------------------------

  // Frames [1, 3T, W, W] of face `f` into `frames` and the clean window into
  // `clean` (when defined), the window's centre at the face box's moved by
  // (dx, dy); returns the box in window pixels. Paired faces are simulated
  // at d_over_r0 with sim_seed; unpaired ones read frames first..first+T−1.
  nets::FaceBox cut(const std::vector<Tensor>& clips, const std::vector<nets::FaceBox>& boxes,
                    std::size_t f, bool is_paired, double d_over_r0, std::uint64_t sim_seed,
                    std::int64_t first, int dx, int dy, const Tensor& frames, const Tensor& clean) {
    const std::int64_t w = o.window, s = size;
    const nets::FaceBox& b = boxes[f];
    const auto x0 = std::clamp<std::int64_t>(
        std::int64_t(std::lround(b.x + b.width / 2 + dx - double(w) / 2)), 0, s - w);
    const auto y0 = std::clamp<std::int64_t>(
        std::int64_t(std::lround(b.y + b.height / 2 + dy - double(w) / 2)), 0, s - w);
    const int frames_t = teacher->config().frames;
    if (is_paired) {
      sim::Simulator simulator(device, probe_sim_params(d_over_r0, int(s)), blur,
                               probe_sim_options());
      simulator.reset(sim_seed);
      const Tensor full = Tensor::empty(device, Shape{1, 3, s, s});
      for (int t = 0; t < frames_t; ++t) {
        simulator.frame(stream, clips[f], full);
        k::slice(stream, full, {0, y0, x0}, frames.view(Shape{1, 3, w, w}, t * 3 * w * w));
      }
      if (clean.defined()) k::slice(stream, clips[f], {0, y0, x0}, clean);
    } else {
      k::slice(stream, clips[f], {3 * first, y0, x0}, frames);
    }
    stream.run();
    return nets::FaceBox{b.x - double(x0), b.y - double(y0), b.width, b.height};
  }

  void make_clip(std::int64_t kk) {
    std::mt19937_64 rng(mix(o.seed, std::uint64_t(kk)));
    const auto f = std::size_t(detail::draw_below(rng, faces.size()));
    const double u = detail::unit_interval(rng());
    const double d = o.d_over_r0_lo * std::pow(o.d_over_r0_hi / o.d_over_r0_lo, u);
    const std::uint64_t sim_seed = rng();
    const int span = 2 * o.jitter + 1;
    const int dx = int(detail::draw_below(rng, std::uint64_t(span))) - o.jitter;
    const int dy = int(detail::draw_below(rng, std::uint64_t(span))) - o.jitter;
    std::int64_t first = 0;
    if (!paired) {
      const std::size_t n = faces[f].frames.size(), t = std::size_t(teacher->config().frames);
      first = std::int64_t(detail::draw_below(rng, n - t + 1));
    }
    const std::int64_t slot = kk % o.pool, w = o.window;
    const Tensor frames = pool_frames.view(Shape{1, t3, w, w}, slot * t3 * w * w);
    // Training needs no clean window: the loss is recognition and distillation.
    pool_box[std::size_t(slot)] =
        cut(face_clip, face_box, f, paired, d, sim_seed, first, dx, dy, frames, Tensor());
    pool_label[std::size_t(slot)] = labels[f];
  }

  void fill_pool(std::int64_t first, const std::function<void(int, int)>& progress) {
    prepare_faces();
    const std::int64_t end = first + o.pool;
    std::int64_t from = std::max(first, pool_end);
    if (first < pool_first || from > end) from = first;
    const auto t0 = Clock::now();
    for (std::int64_t kk = from; kk < end; ++kk) {
      make_clip(kk);
      if (progress) progress(int(kk - from + 1), int(end - from));
    }
    pending_sim_seconds += seconds_since(t0);
    pool_first = first;
    pool_end = end;
  }

  // ---- the two orders -----------------------------------------------------------

  // theta [n, 2, 3] of the 150² crops of frames [n, 3, H, W] (pixels
  // 0..255): the 68 landmarks found in each within its box.
  Tensor thetas(const Tensor& pixels, std::span<const nets::FaceBox> boxes) {
    const std::int64_t n = pixels.shape()[0], h = pixels.shape()[2], w = pixels.shape()[3];
    std::vector<float> theta;
    for (std::int64_t i = 0; i < n; ++i) {
      const Tensor one = pixels.view(Shape{1, 3, h, w}, i * 3 * h * w);
      const auto lm =
          analyzer.landmark_net().landmarks_in_image(stream, one, boxes[std::size_t(i)]);
      const auto th = theta_for(lm, w, h);
      theta.insert(theta.end(), th.begin(), th.end());
    }
    return Tensor::from(device, Shape{n, 2, 3}, theta);
  }

  Tensor reference_pixels(const Tensor& frames) {
    const std::int64_t n = frames.shape()[0], w = frames.shape()[3];
    const Tensor ref = Tensor::empty(device, Shape{n, 3, w, w});
    k::slice(stream, frames, {3LL * teacher->config().reference_frame(), 0, 0}, ref);
    Tensor px = Tensor::empty(device, ref.shape());
    k::scale_shift(stream, ref, 255.f, 0.f, px);
    return px;
  }

  // Every channel of `frames` [n, C, H, W] warped by theta [n, 2, 3] to
  // [n, C, 150, 150], no gradient (align-first's input, the recognizer's
  // crops outside the training graph, aligned clean windows).
  Tensor align_frames(const Tensor& frames, const Tensor& theta) {
    nets::Tape t(stream, false);
    const Var grid = nets::affine_grid(t, Var(theta), kCrop, kCrop, false);
    const Var out = nets::grid_sample(t, Var(frames), grid, {k::SamplePadding::zeros, false});
    stream.run();
    return out.value();
  }

  std::int64_t step() const { return std::int64_t(adam->steps()); }
};

CoTrainer::CoTrainer(const Device& device, const CoTrainOptions& options,
                     const std::filesystem::path& pretrained, std::vector<CoTrainFace> faces,
                     std::vector<CoTrainFace> val,
                     std::vector<std::shared_ptr<const sim::BlurModel>> blur) {
  options.validate();
  require(!faces.empty(), "no training faces", "pass clips of at least 2 identities");
  impl_ = std::make_unique<Impl>(device, options, pretrained, std::move(faces), std::move(val),
                                 std::move(blur));
}

CoTrainer::~CoTrainer() = default;

int CoTrainer::step() const noexcept { return int(impl_->step()); }
const std::vector<std::string>& CoTrainer::identities() const { return impl_->identities; }
const Restorer& CoTrainer::student() const { return *impl_->model->student; }
const nets::AdaFaceHead& CoTrainer::head() const { return *impl_->model->head; }

const std::vector<std::string>& CoTrainer::faceless_clips() const { return impl_->dropped; }

std::vector<std::string> CoTrainer::faceless_identities() const {
  return {impl_->dropped_identities.begin(), impl_->dropped_identities.end()};
}

std::int64_t CoTrainer::trainable_parameters() const {
  std::int64_t n = 0;
  for (const auto& [name, v] : impl_->trainable) n += v.numel();
  return n;
}

void CoTrainer::prepare(const std::function<void(int, int)>& progress) {
  impl_->fill_pool(impl_->step() * impl_->o.refresh, progress);
}

CoTrainStepReport CoTrainer::train_step() {
  Impl& m = *impl_;
  const CoTrainOptions& o = m.o;
  const std::int64_t s = m.step();
  m.fill_pool(s * o.refresh, {});
  CoTrainStepReport r;
  r.sim_seconds = m.pending_sim_seconds;
  m.pending_sim_seconds = 0;
  const auto t0 = Clock::now();

  std::mt19937_64 rng(mix(mix(o.seed, 0xba7c4), std::uint64_t(s)));
  const std::int64_t w = o.window, px = w * w;
  std::vector<nets::FaceBox> boxes;
  std::vector<std::int32_t> labels;
  for (int b = 0; b < o.batch; ++b) {
    const auto slot = std::int64_t(detail::draw_below(rng, std::uint64_t(o.pool)));
    k::copy(m.stream, m.pool_frames.view(Shape{m.t3 * px}, slot * m.t3 * px),
            m.batch_frames.view(Shape{m.t3 * px}, b * m.t3 * px));
    boxes.push_back(m.pool_box[std::size_t(slot)]);
    labels.push_back(m.pool_label[std::size_t(slot)]);
  }
  m.labels_dev.upload_bytes(labels.data(), labels.size() * sizeof(std::int32_t));
  Restorer& student = *m.model->student;
  student.train();
  m.model->head->train();

  // The student's input: the window, or (align-first) the aligned crops.
  Tensor input = m.batch_frames, theta;
  if (o.order == CoTrainOrder::align_first) {
    theta = m.thetas(m.reference_pixels(m.batch_frames), boxes);
    input = m.align_frames(m.batch_frames, theta);
  }
  auto lap = Clock::now();
  auto split = [&](double& slot) {
    m.stream.run();
    slot = seconds_since(lap);
    lap = Clock::now();
  };
  nets::Tape tape(m.stream);
  const Var out = student.forward(tape, Var(input));
  split(r.student_s);
  Tensor target;
  {
    nets::Tape frozen(m.stream, false);
    target = m.teacher->forward(frozen, Var(input)).value();
  }
  split(r.teacher_s);
  const Var pixels = to_pixels_var(tape, out);
  Var crops = pixels;
  if (o.order == CoTrainOrder::restore_first) {
    theta = m.thetas(pixels.value(), boxes);
    split(r.landmarks_s);
    const Var grid = nets::affine_grid(tape, Var(theta), kCrop, kCrop, false);
    crops = nets::grid_sample(tape, pixels, grid, {k::SamplePadding::zeros, false});
  }
  const Var desc = m.analyzer.recognition_net().forward(tape, crops);
  const Var logits = m.model->head->forward(tape, desc, m.labels_dev);
  const Var recognition = nets::cross_entropy(tape, logits, m.labels_dev);
  const Var distillation = nets::l1_loss(tape, out, Var(target));
  Var loss = recognition;
  if (o.lambda > 0) {
    loss = nets::add(tape, recognition, nets::scale_shift(tape, distillation, o.lambda));
  }
  split(r.recognize_s);
  tape.backward(loss);
  m.gradient_norm->record(m.stream);
  split(r.backward_s);
  r.loss = loss.value().download()[0];
  r.recognition = recognition.value().download()[0];
  r.distillation = distillation.value().download()[0];
  r.grad_norm = m.gradient_norm->norm();
  if (!std::isfinite(r.loss) || !std::isfinite(r.grad_norm)) {
    throw Error("cotrain",
                "the loss or gradient norm became " + num(r.loss) + " / " + num(r.grad_norm) +
                    " at step " + std::to_string(s + 1),
                "lower --lr or --clip-grad, or resume from the last checkpoint");
  }
  m.gradient_norm->clip(m.stream, r.grad_norm, o.clip_grad_norm);
  r.lr = m.schedule.at(std::uint32_t(s));
  m.adam->set_lr(float(r.lr));
  m.adam->step(m.stream);
  m.adam->zero_grad();
  // The frozen recognizer still receives no gradient; the frozen student
  // layers neither (they do not require one).
  split(r.update_s);
  r.step = int(s + 1);
  r.train_seconds = seconds_since(t0);
  return r;
}

CoTrainEvalReport CoTrainer::evaluate() {
  Impl& m = *impl_;
  const auto t0 = Clock::now();
  m.prepare_faces();
  const CoTrainOptions& o = m.o;
  const std::int64_t v = o.val_clips, w = o.window, t3 = m.t3, c = m.win;
  Restorer& student = *m.model->student;
  student.eval();
  if (!m.val_frames.defined()) {
    m.val_frames = Tensor::empty(m.device, Shape{v, t3, w, w});
    if (m.val_paired) m.val_clean = Tensor::empty(m.device, Shape{v, 3, w, w});
    for (std::int64_t i = 0; i < v; ++i) {
      const auto f = std::size_t(i) % m.val.size();
      const double u = v > 1 ? double(i) / double(v - 1) : 0.5;
      const double d = o.d_over_r0_lo * std::pow(o.d_over_r0_hi / o.d_over_r0_lo, u);
      const Tensor clean =
          m.val_paired ? m.val_clean.view(Shape{1, 3, w, w}, i * 3 * w * w) : Tensor();
      m.vbox.push_back(m.cut(m.val_clip, m.val_box, f, m.val_paired, d,
                             mix(kValSeed, std::uint64_t(i)), 0, 0, 0,
                             m.val_frames.view(Shape{1, t3, w, w}, i * t3 * w * w), clean));
      m.vlabel.push_back(m.val_labels[f]);
    }
  }
  // Align-first scores the aligned crops (theta from the degraded frames).
  Tensor inputs = m.val_frames, clean = m.val_clean, theta;
  if (o.order == CoTrainOrder::align_first) {
    theta = m.thetas(m.reference_pixels(m.val_frames), m.vbox);
    inputs = m.align_frames(m.val_frames, theta);
    if (m.val_paired) clean = m.align_frames(m.val_clean, theta);
  }
  const std::size_t classes = m.identities.size(), dim = 128;
  // One row: the restored (or degraded) frames [v, 3, c, c] in 0..1.
  auto score = [&](const Tensor& frames) {
    CoTrainEvalReport::Row row;
    Tensor px;
    {
      nets::Tape t(m.stream, false);
      px = to_pixels_var(t, Var(frames)).value();
    }
    std::vector<float> d;
    if (o.order == CoTrainOrder::restore_first) {
      d = m.describe(px, m.vbox);
    } else {
      d = m.describe_crops(px);
    }
    double hits = 0, genuine = 0;
    for (std::int64_t i = 0; i < v; ++i) {
      const float* z = d.data() + std::size_t(i) * dim;
      double zn = 0;
      for (std::size_t j = 0; j < dim; ++j) zn += double(z[j]) * z[j];
      std::size_t best = 0;
      double best_cos = -2, own = 0;
      for (std::size_t l = 0; l < classes; ++l) {
        const float* cc = m.centres.data() + l * dim;
        double dot = 0, cn = 0;
        for (std::size_t j = 0; j < dim; ++j) {
          dot += double(z[j]) * cc[j];
          cn += double(cc[j]) * cc[j];
        }
        const double cs = dot / std::sqrt(zn * cn);
        if (cs > best_cos) {
          best_cos = cs;
          best = l;
        }
        if (std::int32_t(l) == m.vlabel[std::size_t(i)]) own = cs;
      }
      hits += best == std::size_t(m.vlabel[std::size_t(i)]) ? 1 : 0;
      genuine += own;
    }
    row.top1 = hits / double(v);
    row.genuine_cos = genuine / double(v);
    row.psnr = row.ssim = std::numeric_limits<double>::quiet_NaN();
    if (m.val_paired) {
      const Tensor p = Tensor::empty(m.device, Shape{v}), q = Tensor::empty(m.device, Shape{v});
      k::psnr(m.stream, frames, clean, 1.f, p);
      k::ssim(m.stream, frames, clean, 1.f, q);
      m.stream.run();
      row.psnr = mean_of(p.download());
      row.ssim = mean_of(q.download());
    }
    return row;
  };
  auto restore = [&](const Restorer& net) {
    Tensor outs = Tensor::empty(m.device, Shape{v, 3, c, c});
    for (std::int64_t b0 = 0; b0 < v; b0 += o.batch) {
      const std::int64_t n = std::min<std::int64_t>(o.batch, v - b0);
      nets::Tape t(m.stream, false);
      const Var out = net.forward(t, Var(inputs.view(Shape{n, t3, c, c}, b0 * t3 * c * c)));
      k::copy(m.stream, out.value(), outs.view(Shape{n, 3, c, c}, b0 * 3 * c * c));
      m.stream.run();
    }
    return outs;
  };
  CoTrainEvalReport r;
  r.step = int(m.step());
  if (m.fixed_rows.empty()) {
    const Tensor degraded = Tensor::empty(m.device, Shape{v, 3, c, c});
    k::slice(m.stream, inputs, {3LL * m.teacher->config().reference_frame(), 0, 0}, degraded);
    m.fixed_rows = {score(restore(*m.teacher)), score(degraded)};
  }
  r.teacher = m.fixed_rows[0];
  r.degraded = m.fixed_rows[1];
  r.student = score(restore(student));
  student.train();
  r.seconds = seconds_since(t0);
  return r;
}

std::map<std::string, std::string> CoTrainer::options_metadata() const {
  const CoTrainOptions& o = impl_->o;
  std::map<std::string, std::string> m = impl_->teacher->config().metadata();
  m["cotrain.order"] = order_name(o.order);
  m["cotrain.lambda"] = num(o.lambda);
  m["cotrain.layers"] = layer_groups_name(o.layers);
  m["cotrain.window"] = std::to_string(o.window);
  m["cotrain.jitter"] = std::to_string(o.jitter);
  m["cotrain.batch"] = std::to_string(o.batch);
  m["cotrain.steps"] = std::to_string(o.steps);
  m["cotrain.lr"] = num(o.lr);
  m["cotrain.min_lr"] = num(o.min_lr);
  m["cotrain.weight_decay"] = num(o.weight_decay);
  m["cotrain.warmup_steps"] = std::to_string(o.warmup_steps);
  m["cotrain.clip_grad_norm"] = num(o.clip_grad_norm);
  m["cotrain.d_over_r0"] = num(o.d_over_r0_lo) + "," + num(o.d_over_r0_hi);
  m["cotrain.pool"] = std::to_string(o.pool);
  m["cotrain.refresh"] = std::to_string(o.refresh);
  m["cotrain.seed"] = std::to_string(o.seed);
  m["cotrain.adaface"] = num(o.adaface.m) + "," + num(o.adaface.h) + "," + num(o.adaface.s) + "," +
                         num(o.adaface.eps) + "," + num(o.adaface.alpha);
  m["cotrain.data"] = impl_->paired ? "paired" : "unpaired";
  m["cotrain.faces"] = std::to_string(impl_->faces.size());
  std::string ids;
  for (const std::string& id : impl_->identities) ids += (ids.empty() ? "" : ",") + id;
  m["cotrain.identities"] = ids;
  return m;
}

void CoTrainer::save_checkpoint(const std::filesystem::path& path,
                                const std::map<std::string, std::string>& metadata) const {
  std::map<std::string, std::string> meta = metadata;
  for (auto& [key, value] : options_metadata()) meta[key] = value;
  nets::save_checkpoint(path, *impl_->model, impl_->adam.get(), meta);
}

void CoTrainer::load_checkpoint(const std::filesystem::path& path) {
  const nets::SafetensorsFile file = nets::read_safetensors(path);
  detail::require_same_settings("cotrain", path, file.metadata, options_metadata());
  impl_->prepare_faces();  // the centres first: the checkpoint's head replaces them
  nets::load_checkpoint(path, *impl_->model, impl_->adam.get());
}

}  // namespace vkjr2::jr2
