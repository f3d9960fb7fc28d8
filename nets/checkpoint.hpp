// Checkpoints: a Module's parameters and buffers, plus an optimizer's state
// and step count, in one safetensors file (opens in other tools: tensors
// "model.<name>" and "optim.<name>" in F32, "optim.steps" in U32;
// metadata records the format and the optimizer's learning rate). Loading
// into a freshly built module and optimizer resumes training bit-exactly.
#pragma once

#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/optimizer.hpp>

#include <filesystem>
#include <map>
#include <string>

namespace vkjr2::nets {

// Writes atomically. `optimizer` may be null (weights only). Waits for the
// device (downloads every tensor).
void save_checkpoint(const std::filesystem::path& path, const Module& module,
                     const Optimizer* optimizer,
                     const std::map<std::string, std::string>& metadata = {});

// Restores every parameter and buffer of `module` (each must be present with
// its shape; extra tensors in the file are an error too, so a checkpoint of
// another network is not half-loaded) and, when `optimizer` is not null, its
// state, step count and learning rate. Returns the file's metadata.
std::map<std::string, std::string> load_checkpoint(const std::filesystem::path& path,
                                                   Module& module, Optimizer* optimizer);

}  // namespace vkjr2::nets
