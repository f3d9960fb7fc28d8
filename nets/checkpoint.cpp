#include <vkjr2/nets/checkpoint.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/error.hpp>

#include <bit>
#include <charconv>
#include <cstdio>
#include <set>

namespace vkjr2::nets {
namespace {

constexpr const char* kFormat = "vkjr2-checkpoint-1";

std::vector<std::int64_t> dims_of(const Tensor& t) {
  const auto d = t.shape().dims();
  return {d.begin(), d.end()};
}

std::string lr_text(float lr) {
  // The exact bits, so a resumed run uses the very same float.
  char buf[32];
  std::snprintf(buf, sizeof buf, "%08x", std::bit_cast<std::uint32_t>(lr));
  return buf;
}

}  // namespace

void save_checkpoint(const std::filesystem::path& path, const Module& module,
                     const Optimizer* optimizer,
                     const std::map<std::string, std::string>& metadata) {
  std::vector<SafetensorsRecord> records;
  const auto add = [&](const std::string& name, const Tensor& t) {
    const std::vector<float> values = t.download();
    records.push_back(SafetensorsRecord::f32(name, dims_of(t), values));
  };
  for (const auto& [name, v] : module.named_parameters()) add("model." + name, v.value());
  for (const auto& [name, v] : module.named_buffers()) add("model." + name, v.value());
  std::map<std::string, std::string> meta = metadata;
  meta["format"] = kFormat;
  if (optimizer != nullptr) {
    for (const auto& [name, t] : optimizer->state()) add("optim." + name, t);
    const std::uint32_t steps = optimizer->steps();
    records.push_back(SafetensorsRecord::u32("optim.steps", {1}, std::span(&steps, 1)));
    meta["optim.lr_bits"] = lr_text(optimizer->lr());
  }
  write_safetensors(path, records, meta);
}

std::map<std::string, std::string> load_checkpoint(const std::filesystem::path& path,
                                                   Module& module, Optimizer* optimizer) {
  const SafetensorsFile file = read_safetensors(path);
  const std::string where = path.string();
  if (auto it = file.metadata.find("format"); it == file.metadata.end() || it->second != kFormat) {
    throw InvalidArgument(
        "load_checkpoint",
        where + " is not a vkjr2 checkpoint (metadata format " + "is not \"" + kFormat + "\")",
        "pass a file written by save_checkpoint");
  }
  std::set<std::string> used;
  const auto restore = [&](const std::string& name, const Tensor& t) {
    const SafetensorsRecord* r = file.find(name);
    if (r == nullptr) {
      throw InvalidArgument("load_checkpoint", where + " has no tensor '" + name + "'",
                            "the checkpoint was written for another network or optimizer");
    }
    if (r->shape != dims_of(t)) {
      throw InvalidArgument("load_checkpoint",
                            where + ": '" + name + "' has shape " + shape_str(r->shape) +
                                ", the network expects " + t.shape().str(),
                            "the checkpoint was written for another configuration");
    }
    if (r->dtype != StDType::F32) {
      throw InvalidArgument("load_checkpoint", where + ": '" + name + "' is not F32",
                            "pass a file written by save_checkpoint");
    }
    t.upload(r->to_float());
    used.insert(name);
  };
  for (const auto& [name, v] : module.named_parameters()) {
    restore("model." + name, v.value());
    v.mark_modified();
    v.zero_grad();
  }
  for (const auto& [name, v] : module.named_buffers()) {
    restore("model." + name, v.value());
    v.mark_modified();
  }
  if (optimizer != nullptr) {
    for (const auto& [name, t] : optimizer->state()) restore("optim." + name, t);
    const SafetensorsRecord* steps = file.find("optim.steps");
    auto lr = file.metadata.find("optim.lr_bits");
    if (steps == nullptr || lr == file.metadata.end()) {
      throw InvalidArgument("load_checkpoint", where + " holds no optimizer state",
                            "pass nullptr as the optimizer to load weights only");
    }
    const std::vector<std::uint32_t> count = steps->as_u32();
    if (count.size() != 1) {
      throw InvalidArgument("load_checkpoint", where + ": 'optim.steps' must hold one value",
                            "pass a file written by save_checkpoint");
    }
    optimizer->set_steps(count[0]);
    std::uint32_t lr_bits = 0;
    const auto [end, ec] =
        std::from_chars(lr->second.data(), lr->second.data() + lr->second.size(), lr_bits, 16);
    if (ec != std::errc() || end != lr->second.data() + lr->second.size()) {
      throw InvalidArgument("load_checkpoint", where + ": metadata optim.lr_bits is not hex",
                            "pass a file written by save_checkpoint");
    }
    optimizer->set_lr(std::bit_cast<float>(lr_bits));
    used.insert("optim.steps");
  }
  for (const auto& r : file.tensors) {
    const bool optim_part = r.name.rfind("optim.", 0) == 0;
    if (!used.contains(r.name) && !(optim_part && optimizer == nullptr)) {
      throw InvalidArgument("load_checkpoint",
                            where + " has a tensor '" + r.name + "' this network does not have",
                            "the checkpoint was written for another network");
    }
  }
  return file.metadata;
}

}  // namespace vkjr2::nets
