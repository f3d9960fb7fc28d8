// CoTrainer on real faces with a tiny restorer: the first step's student is
// the teacher (zero distillation, equal held-out rows), a resumed run equals
// the straight one bit for bit, frozen layer groups and the recognizer stay
// as they are, every configuration (fine-tune, align-first, unpaired) takes
// steps, and bad options and faces are clear errors.
#include <vkjr2/jr2/cotrain.hpp>
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/runtime/npy.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/parity.hpp"
#include "support/temp_dir.hpp"
#include "support/test_device.hpp"

namespace vkjr2::jr2 {
namespace {

constexpr std::int64_t kClip = 96;

// Square 96² clips of twice each face box of the sample photos (the way a
// benchmark clip holds its face), labelled by face: `count` identities.
std::vector<CoTrainFace> sample_faces(std::size_t count) {
  static std::vector<CoTrainFace> all;
  if (all.empty()) {
    Device& dev = test::device();
    const FaceAnalyzer analyzer(dev);
    const auto index = test::parity_index();
    Stream s(dev);
    for (const auto& image : index["images"]) {
      const HostTensor photo =
          vkjr2::read_npy(test::parity_dir() / image["pixels"].get<std::string>());
      const Tensor img = image_to_device(dev, photo);
      FaceOptions fo;
      fo.descriptors = false;
      for (const Face& f : analyzer.analyze(s, img, fo)) {
        const double side = 2 * std::max(f.box.width, f.box.height);
        const double x0 = f.box.x + f.box.width / 2 - side / 2;
        const double y0 = f.box.y + f.box.height / 2 - side / 2;
        if (x0 < 0 || y0 < 0 || x0 + side > double(photo.shape[1]) ||
            y0 + side > double(photo.shape[0])) {
          continue;
        }
        nets::Tape t(s, false);
        const nets::Var crop =
            nets::slice(t, nets::Var(img), {0, std::int64_t(y0), std::int64_t(x0)},
                        Shape{1, 3, std::int64_t(side), std::int64_t(side)});
        const nets::Var clip =
            nets::resize(t, crop, kernels::ResizeMode::bilinear_half_pixel, kClip, kClip);
        s.run();
        CoTrainFace face;
        face.identity = "face" + std::to_string(all.size());
        face.source = face.identity + ".png";
        face.clean = image_to_host(clip.value());
        all.push_back(std::move(face));
      }
    }
  }
  EXPECT_GE(all.size(), count) << "the sample photos hold too few whole faces";
  return {all.begin(), all.begin() + std::ptrdiff_t(std::min(count, all.size()))};
}

// A tiny restorer file (2 frames, width 4, one level): the teacher.
std::filesystem::path tiny_restorer(const std::filesystem::path& dir) {
  auto path = dir / "tiny.safetensors";
  if (!std::filesystem::exists(path)) {
    const Restorer r(test::device(), RestorerConfig{2, 4, {1}, 0, {1}}, 3);
    r.save(path);
  }
  return path;
}

CoTrainOptions tiny_options() {
  CoTrainOptions o;
  o.window = 64;
  o.jitter = 4;
  o.batch = 2;
  o.steps = 3;
  o.warmup_steps = 1;
  o.lr = 1e-3f;
  o.pool = 3;
  o.val_clips = 2;
  o.lambda = 5.f;
  o.seed = 7;
  return o;
}

std::unique_ptr<CoTrainer> make(const CoTrainOptions& o, const std::filesystem::path& teacher,
                                std::vector<CoTrainFace> faces) {
  Device& dev = test::device();
  std::vector<CoTrainFace> val = sample_faces(2);
  return std::make_unique<CoTrainer>(dev, o, teacher, std::move(faces), std::move(val),
                                     sim::load_shipped_blur_models(dev));
}

std::vector<std::vector<float>> state(const CoTrainer& t) {
  std::vector<std::vector<float>> out;
  for (const auto& [name, v] : t.student().named_parameters()) out.push_back(v.value().download());
  out.push_back(t.head().weight.value().download());
  out.push_back(t.head().running_mean.value().download());
  out.push_back(t.head().running_std.value().download());
  return out;
}

struct Workspace {
  test::TempDir dir;
  std::filesystem::path teacher = tiny_restorer(dir.path);
};

TEST(CoTrainer, StartsAsTheTeacherAndResumesBitExactly) {
  Workspace run;
  const CoTrainOptions o = tiny_options();
  auto straight = make(o, run.teacher, sample_faces(3));
  EXPECT_EQ(straight->identities().size(), 3u);
  const CoTrainEvalReport before = straight->evaluate();
  EXPECT_EQ(before.student.top1, before.teacher.top1);
  EXPECT_EQ(before.student.genuine_cos, before.teacher.genuine_cos);
  EXPECT_EQ(before.student.psnr, before.teacher.psnr);
  EXPECT_TRUE(std::isfinite(before.degraded.psnr) && before.degraded.psnr > 10);
  EXPECT_GT(before.degraded.genuine_cos, 0.5);  // the clean centres know the faces

  std::vector<CoTrainStepReport> reports;
  for (int i = 0; i < 3; ++i) reports.push_back(straight->train_step());
  EXPECT_EQ(reports[0].distillation, 0.0);  // the student starts as the teacher
  for (const auto& r : reports) {
    EXPECT_TRUE(std::isfinite(r.recognition) && r.recognition > 0) << r.step;
    EXPECT_GT(r.grad_norm, 0) << r.step;
  }
  EXPECT_GT(reports[2].distillation, 0.0);  // and moves away from it
  EXPECT_NEAR(reports[2].loss, reports[2].recognition + 5 * reports[2].distillation,
              1e-5 * reports[2].loss);

  const auto ckpt = run.dir.path / "run.ckpt";
  {
    auto first = make(o, run.teacher, sample_faces(3));
    first->train_step();
    first->train_step();
    first->save_checkpoint(ckpt);
  }
  auto resumed = make(o, run.teacher, sample_faces(3));
  resumed->load_checkpoint(ckpt);
  EXPECT_EQ(resumed->step(), 2);
  const CoTrainStepReport last = resumed->train_step();
  EXPECT_EQ(last.loss, reports[2].loss);
  EXPECT_EQ(state(*resumed), state(*straight));

  // Another λ is another run: its checkpoint is refused, naming the option.
  CoTrainOptions other = o;
  other.lambda = 0;
  auto refused = make(other, run.teacher, sample_faces(3));
  test::expect_invalid_argument([&] { refused->load_checkpoint(ckpt); }, "cotrain.lambda");
}

TEST(CoTrainer, FrozenLayerGroupsStayAsTheyAre) {
  Workspace run;
  CoTrainOptions o = tiny_options();
  o.steps = 1;
  o.layers = kLateLayers;
  auto t = make(o, run.teacher, sample_faces(2));
  const auto before = t->student().named_parameters();
  std::vector<std::vector<float>> values;
  for (const auto& [name, v] : before) values.push_back(v.value().download());
  t->train_step();
  std::size_t changed = 0, late = 0;
  for (std::size_t i = 0; i < before.size(); ++i) {
    const bool is_late = layer_group_of(before[i].first, 1) == kLateLayers;
    const bool moved = before[i].second.value().download() != values[i];
    late += is_late ? 1 : 0;
    if (!is_late) {
      EXPECT_FALSE(moved) << before[i].first;
    }
    changed += moved ? 1 : 0;
  }
  EXPECT_GT(late, 0u);
  EXPECT_GT(changed, 0u);
}

TEST(CoTrainer, FineTuneAlignFirstAndUnpairedTakeSteps) {
  Workspace run;
  CoTrainOptions o = tiny_options();
  o.steps = 1;
  o.lambda = 0;  // fine-tune: the distillation is reported but not in the loss
  {
    auto t = make(o, run.teacher, sample_faces(2));
    const CoTrainStepReport r = t->train_step();
    EXPECT_EQ(r.loss, r.recognition);
  }
  o.lambda = 1;
  o.order = CoTrainOrder::align_first;
  {
    auto t = make(o, run.teacher, sample_faces(2));
    const CoTrainStepReport r = t->train_step();
    EXPECT_TRUE(std::isfinite(r.loss) && r.loss > 0);
    const CoTrainEvalReport e = t->evaluate();  // scored on the aligned 150² crops
    EXPECT_TRUE(std::isfinite(e.student.psnr));
  }
  // Unpaired: frames only (here the clean clip three times); the held-out
  // clips stay paired.
  o.order = CoTrainOrder::restore_first;
  std::vector<CoTrainFace> unpaired;
  for (CoTrainFace f : sample_faces(2)) {
    for (int t = 0; t < 3; ++t) f.frames.push_back(f.clean);
    f.clean = HostTensor{};
    unpaired.push_back(std::move(f));
  }
  // A clip in which the detector finds no face (flat grey) is left out.
  CoTrainFace grey = unpaired.front();
  grey.source = "grey";
  for (HostTensor& im : grey.frames) std::fill(im.values.begin(), im.values.end(), 128.f);
  unpaired.push_back(grey);
  auto t = make(o, run.teacher, unpaired);
  const CoTrainStepReport r = t->train_step();
  EXPECT_TRUE(std::isfinite(r.loss) && r.loss > 0);
  EXPECT_EQ(t->options_metadata().at("cotrain.data"), "unpaired");
  EXPECT_EQ(t->faceless_clips(), std::vector<std::string>{"grey"});
  // An identity whose every clip is faceless is left out with its held-out
  // faces.
  {
    std::vector<CoTrainFace> three;
    for (CoTrainFace f : sample_faces(3)) {
      for (int k = 0; k < 3; ++k) f.frames.push_back(f.clean);
      f.clean = HostTensor{};
      three.push_back(std::move(f));
    }
    for (HostTensor& im : three[2].frames) std::fill(im.values.begin(), im.values.end(), 90.f);
    Device& dev = test::device();
    CoTrainer lost(dev, o, run.teacher, three, sample_faces(3), sim::load_shipped_blur_models(dev));
    EXPECT_EQ(lost.identities().size(), 2u);
    EXPECT_EQ(lost.faceless_clips(), std::vector<std::string>{three[2].source});
    EXPECT_EQ(lost.faceless_identities(), std::vector<std::string>{three[2].identity});
    EXPECT_TRUE(std::isfinite(lost.train_step().loss));
  }
  // With one identity left, nothing can train.
  unpaired.erase(unpaired.begin());
  test::expect_invalid_argument([&] { make(o, run.teacher, unpaired); },
                                "1 training identities (1 clips without a detectable face");
}

TEST(CoTrainer, BadOptionsAndFacesAreClearErrors) {
  const auto bad = [](auto edit, const std::string& words) {
    CoTrainOptions o = tiny_options();
    edit(o);
    test::expect_invalid_argument([&] { o.validate(); }, words);
  };
  bad([](CoTrainOptions& o) { o.batch = 1; }, "--batch");
  bad([](CoTrainOptions& o) { o.lambda = -1; }, "--lambda");
  bad([](CoTrainOptions& o) { o.lambda = std::nanf(""); }, "--lambda");
  bad([](CoTrainOptions& o) { o.window = 100; }, "--window");
  bad([](CoTrainOptions& o) { o.pool = 1; }, "--pool");
  bad([](CoTrainOptions& o) { o.d_over_r0_hi = 50; }, "D/r0");
  bad([](CoTrainOptions& o) { o.adaface.m = 2; }, "m");
  test::expect_invalid_argument([] { (void)parse_layer_groups("early,top"); }, "top");
  test::expect_invalid_argument([] { (void)parse_order("restore-last"); }, "restore-last");
  EXPECT_EQ(parse_layer_groups("late,early"), unsigned(kEarlyLayers | kLateLayers));
  EXPECT_EQ(layer_groups_name(kEarlyLayers | kMiddleLayers), "early,middle");
  EXPECT_EQ(layer_group_of("intro.weight", 3), unsigned(kEarlyLayers));
  EXPECT_EQ(layer_group_of("encoders.0.0.conv1.weight", 3), unsigned(kEarlyLayers));
  EXPECT_EQ(layer_group_of("encoders.1.0.conv1.weight", 3), unsigned(kMiddleLayers));
  EXPECT_EQ(layer_group_of("middle.0.beta", 3), unsigned(kMiddleLayers));
  EXPECT_EQ(layer_group_of("decoders.2.0.gamma", 3), unsigned(kLateLayers));
  EXPECT_EQ(layer_group_of("decoders.0.0.gamma", 3), unsigned(kMiddleLayers));
  EXPECT_EQ(layer_group_of("ending.bias", 3), unsigned(kLateLayers));

  Workspace run;
  const CoTrainOptions o = tiny_options();
  // One identity only.
  std::vector<CoTrainFace> one = sample_faces(2);
  one[1].identity = one[0].identity;
  test::expect_invalid_argument([&] { make(o, run.teacher, one); }, "2 identities");
  // A clip of another size.
  std::vector<CoTrainFace> sizes = sample_faces(2);
  sizes[1].clean.shape = {48, 48 * 4, 3};
  test::expect_invalid_argument([&] { make(o, run.teacher, sizes); }, sizes[1].source);
  // A held-out face of an identity that does not train.
  Device& dev = test::device();
  std::vector<CoTrainFace> val = sample_faces(3);
  test::expect_invalid_argument(
      [&] {
        CoTrainer t(dev, o, run.teacher, sample_faces(2), val, sim::load_shipped_blur_models(dev));
      },
      "face2");
  // A clip with no face in it.
  std::vector<CoTrainFace> blank = sample_faces(2);
  std::fill(blank[1].clean.values.begin(), blank[1].clean.values.end(), 128.f);
  auto t = make(o, run.teacher, blank);
  test::expect_invalid_argument([&] { t->prepare(); }, "no face found in " + blank[1].source);
}

}  // namespace
}  // namespace vkjr2::jr2
