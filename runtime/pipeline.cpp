// Pipelines: created lazily, cached per device keyed by (shader, specialization
// constants); descriptor set layouts shared per binding signature.
#include <vkjr2/runtime/shaders.hpp>

#include <algorithm>
#include <cstring>
#include <string>
#include <utility>

#include "internal/device_core.hpp"

namespace vkjr2::detail {
namespace {

VkDescriptorType descriptor_type(BindingKind kind) {
  switch (kind) {
    case BindingKind::storage:
      return VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    case BindingKind::texel:
      return VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
    case BindingKind::uniform:
      return VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  }
  return VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
}

}  // namespace

VkShaderModule DeviceCore::shader_module(std::string_view name) {
  if (auto it = modules_.find(name); it != modules_.end()) return it->second;
  const auto words = shaders::find(name);
  if (words.empty()) {
    throw Error("load shader", "no embedded shader named '" + std::string(name) + "'",
                "add shaders/" + std::string(name) + ".comp and rebuild");
  }
  VkShaderModuleCreateInfo ci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  ci.codeSize = words.size_bytes();
  ci.pCode = words.data();
  VkShaderModule module = VK_NULL_HANDLE;
  check(vkCreateShaderModule(device, &ci, nullptr, &module),
        "create shader module " + std::string(name));
  modules_.emplace(std::string(name), module);
  return module;
}

VkDescriptorSetLayout DeviceCore::set_layout(const std::vector<BindingKind>& bindings) {
  if (auto it = set_layouts_.find(bindings); it != set_layouts_.end()) return it->second;
  std::vector<VkDescriptorSetLayoutBinding> b(bindings.size());
  for (std::uint32_t i = 0; i < bindings.size(); ++i) {
    b[i].binding = i;
    b[i].descriptorType = descriptor_type(bindings[i]);
    b[i].descriptorCount = 1;
    b[i].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
  }
  VkDescriptorSetLayoutCreateInfo ci{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  if (push_descriptors) ci.flags = VK_DESCRIPTOR_SET_LAYOUT_CREATE_PUSH_DESCRIPTOR_BIT_KHR;
  ci.bindingCount = static_cast<std::uint32_t>(b.size());
  ci.pBindings = b.data();
  VkDescriptorSetLayout layout = VK_NULL_HANDLE;
  check(vkCreateDescriptorSetLayout(device, &ci, nullptr, &layout), "create descriptor set layout");
  set_layouts_.emplace(bindings, layout);
  return layout;
}

std::size_t PipelineKeyHash::operator()(const PipelineKeyView& k) const noexcept {
  // FNV-1a over the shader name, then the constants.
  std::uint64_t h = 14695981039346656037ull;
  const auto mix = [&h](std::uint64_t v) { h = (h ^ v) * 1099511628211ull; };
  for (const char c : k.shader) mix(static_cast<unsigned char>(c));
  mix(k.spec.size());
  for (const std::uint32_t v : k.spec) mix(v);
  return static_cast<std::size_t>(h);
}

const Pipeline& DeviceCore::pipeline(const KernelDef& kernel, std::span<const std::uint32_t> spec) {
  std::lock_guard lock(pipelines_mutex_);
  if (auto it = pipelines_.find(PipelineKeyView{kernel.shader, spec}); it != pipelines_.end()) {
    return it->second;
  }
  if (spec.size() > kMaxSpecConstants) {
    throw InvalidArgument(
        "create pipeline " + std::string(kernel.shader),
        std::to_string(spec.size()) + " specialization constants, more than " +
            std::to_string(kMaxSpecConstants),
        "pass fewer or raise kMaxSpecConstants in runtime/internal/device_core.hpp");
  }
  PipelineKey key;
  key.shader = std::string(kernel.shader);
  std::copy(spec.begin(), spec.end(), key.spec.begin());
  key.spec_count = spec.size();

  if (kernel.push_bytes > info.max_push_constant_bytes) {
    throw InvalidArgument("create pipeline " + std::string(kernel.shader),
                          "push constants of " + std::to_string(kernel.push_bytes) +
                              " bytes exceed the device limit of " +
                              std::to_string(info.max_push_constant_bytes));
  }
  Pipeline p;
  p.set_layout = set_layout(kernel.bindings);
  std::string layout_key;
  for (BindingKind k : kernel.bindings) layout_key += static_cast<char>('0' + int(k));
  layout_key += "/" + std::to_string(kernel.push_bytes);
  if (auto it = pipeline_layouts_.find(layout_key); it != pipeline_layouts_.end()) {
    p.layout = it->second;
  } else {
    VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, kernel.push_bytes};
    VkPipelineLayoutCreateInfo ci{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    ci.setLayoutCount = 1;
    ci.pSetLayouts = &p.set_layout;
    ci.pushConstantRangeCount = kernel.push_bytes > 0 ? 1 : 0;
    ci.pPushConstantRanges = &range;
    check(vkCreatePipelineLayout(device, &ci, nullptr, &p.layout), "create pipeline layout");
    pipeline_layouts_.emplace(layout_key, p.layout);
  }

  std::vector<VkSpecializationMapEntry> entries(spec.size());
  for (std::uint32_t i = 0; i < spec.size(); ++i) {
    entries[i] = {i, static_cast<std::uint32_t>(i * sizeof(std::uint32_t)), sizeof(std::uint32_t)};
  }
  VkSpecializationInfo spec_info{};
  spec_info.mapEntryCount = static_cast<std::uint32_t>(entries.size());
  spec_info.pMapEntries = entries.data();
  spec_info.dataSize = spec.size_bytes();
  spec_info.pData = spec.data();

  VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  ci.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
  ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  ci.stage.module = shader_module(kernel.shader);
  ci.stage.pName = "main";
  ci.stage.pSpecializationInfo = spec.empty() ? nullptr : &spec_info;
  ci.layout = p.layout;
  check(vkCreateComputePipelines(device, pipeline_cache_, 1, &ci, nullptr, &p.pipeline),
        "create pipeline " + std::string(kernel.shader));
  return pipelines_.emplace(std::move(key), p).first->second;
}

// ---- staging ---------------------------------------------------------------

void DeviceCore::ensure_staging(VkDeviceSize bytes) {
  if (!staging_allocator_) {
    staging_allocator_ = std::make_unique<Allocator>(
        device, choose_staging_memory(physical_device),
        VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, 64ull << 20, 256,
        info.max_memory_allocation_bytes, false);
  }
  if (staging_.size >= bytes) return;
  staging_allocator_->release(staging_);
  staging_ = {};
  staging_ = staging_allocator_->allocate(bytes, "staging buffer");
}

void DeviceCore::one_shot_copy(VkBuffer src, VkDeviceSize src_offset, VkBuffer dst,
                               VkDeviceSize dst_offset, VkDeviceSize size) {
  check(vkResetCommandBuffer(transfer_cmd_, 0), "reset command buffer");
  VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  check(vkBeginCommandBuffer(transfer_cmd_, &begin), "begin command buffer");
  // Order after earlier submissions' compute and transfer writes.
  VkMemoryBarrier before{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  before.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  before.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  vkCmdPipelineBarrier(transfer_cmd_,
                       VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &before, 0, nullptr, 0, nullptr);
  VkBufferCopy region{src_offset, dst_offset, size};
  vkCmdCopyBuffer(transfer_cmd_, src, dst, 1, &region);
  VkMemoryBarrier after{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  after.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  after.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(transfer_cmd_, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0,
                       1, &after, 0, nullptr, 0, nullptr);
  check(vkEndCommandBuffer(transfer_cmd_), "end command buffer");
  VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &transfer_cmd_;
  {
    std::lock_guard lock(queue_mutex);
    check(vkQueueSubmit(queue, 1, &submit, transfer_fence_), "submit staging copy");
  }
  check(vkWaitForFences(device, 1, &transfer_fence_, VK_TRUE, UINT64_MAX), "wait staging copy");
  check(vkResetFences(device, 1, &transfer_fence_), "reset fence");
}

void DeviceCore::copy_host_to_buffer(const void* data, VkBuffer dst, VkDeviceSize dst_offset,
                                     VkDeviceSize size) {
  constexpr VkDeviceSize kChunk = 32ull << 20;
  std::lock_guard lock(staging_mutex_);
  ensure_staging(std::min(size, kChunk));
  const auto* bytes = static_cast<const std::byte*>(data);
  for (VkDeviceSize done = 0; done < size; done += kChunk) {
    const VkDeviceSize n = std::min(kChunk, size - done);
    std::memcpy(staging_.block->mapped + staging_.offset, bytes + done, n);
    one_shot_copy(staging_.block->buffer, staging_.offset, dst, dst_offset + done, n);
  }
}

void DeviceCore::copy_buffer_to_host(VkBuffer src, VkDeviceSize src_offset, void* data,
                                     VkDeviceSize size) {
  constexpr VkDeviceSize kChunk = 32ull << 20;
  std::lock_guard lock(staging_mutex_);
  ensure_staging(std::min(size, kChunk));
  auto* bytes = static_cast<std::byte*>(data);
  for (VkDeviceSize done = 0; done < size; done += kChunk) {
    const VkDeviceSize n = std::min(kChunk, size - done);
    one_shot_copy(src, src_offset + done, staging_.block->buffer, staging_.offset, n);
    std::memcpy(bytes + done, staging_.block->mapped + staging_.offset, n);
  }
}

}  // namespace vkjr2::detail
