#include <vkjr2/runtime/stream.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "internal/device_core.hpp"

namespace vkjr2 {
namespace {

constexpr VkPipelineStageFlags kWorkStages =
    VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
constexpr VkAccessFlags kWriteAccess = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
constexpr VkAccessFlags kAnyAccess = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT |
                                     VK_ACCESS_UNIFORM_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT |
                                     VK_ACCESS_TRANSFER_WRITE_BIT;

const char* kind_name(BindingKind kind) {
  switch (kind) {
    case BindingKind::storage:
      return "storage";
    case BindingKind::texel:
      return "texel";
    case BindingKind::uniform:
      return "uniform";
  }
  return "?";
}

std::uint32_t format_bytes_of(VkFormat format) {
  switch (format) {
    case VK_FORMAT_R32_SFLOAT:
    case VK_FORMAT_R32_UINT:
    case VK_FORMAT_R32_SINT:
    case VK_FORMAT_R16G16_SFLOAT:
      return 4;
    case VK_FORMAT_R32G32_SFLOAT:
    case VK_FORMAT_R16G16B16A16_SFLOAT:
      return 8;
    case VK_FORMAT_R32G32B32A32_SFLOAT:
    case VK_FORMAT_R32G32B32A32_UINT:
    case VK_FORMAT_R32G32B32A32_SINT:
      return 16;
    case VK_FORMAT_R16_SFLOAT:
      return 2;
    default:
      return 0;
  }
}

// A range of a buffer touched by a recorded command since the last barrier.
// The most bindings one kernel may declare (the dispatch path's fixed arrays).
constexpr std::size_t kMaxBindings = 16;

struct Touch {
  VkBuffer buffer;
  VkDeviceSize begin;
  VkDeviceSize end;
  bool write;
};

}  // namespace

struct Stream::Impl {
  Device device;
  detail::DeviceCore* core;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  VkFence fence = VK_NULL_HANDLE;
  HostCommands* host = nullptr;  // records into the host's command buffers when set
  enum class State { idle, recording, submitted } state = State::idle;

  std::vector<Touch> pending;  // accesses not yet separated by a barrier
  bool wrote = false;          // any write recorded (needs a host-read barrier)
  std::vector<std::shared_ptr<detail::Storage>> keep;
  std::size_t dispatch_count = 0;
  std::size_t barrier_count = 0;

  // Descriptor pools, where push descriptors are unavailable.
  std::vector<VkDescriptorPool> pools;
  std::size_t pool_index = 0;

  // Profiling: a timestamp pair per dispatch.
  VkQueryPool queries = VK_NULL_HANDLE;
  std::uint32_t query_capacity = 0;
  std::uint32_t wanted_capacity = 256;
  std::vector<std::string> timed;

  explicit Impl(const Device& d) : device(d), core(&d.core()) {}

  void begin() {
    if (state == State::recording) return;
    if (state == State::submitted) {
      throw Error("Stream", "recording while earlier work is still in flight",
                  "call wait() before recording more");
    }
    if (host != nullptr) {
      cmd = host->begin();
      if (cmd == VK_NULL_HANDLE) {
        throw InvalidArgument("Stream (HostCommands::begin)", "returned no command buffer",
                              "return a primary command buffer in the recording state");
      }
    } else {
      VkCommandBufferBeginInfo info{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
      info.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
      check(vkBeginCommandBuffer(cmd, &info), "begin command buffer");
    }
    state = State::recording;
    // Order this submission after earlier ones' compute and transfer work.
    full_barrier();
    if (core->profile) {
      if (query_capacity < wanted_capacity) {
        if (queries != VK_NULL_HANDLE) vkDestroyQueryPool(core->device, queries, nullptr);
        VkQueryPoolCreateInfo qi{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
        qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
        qi.queryCount = wanted_capacity;
        check(vkCreateQueryPool(core->device, &qi, nullptr, &queries), "create query pool");
        query_capacity = wanted_capacity;
      }
      vkCmdResetQueryPool(cmd, queries, 0, query_capacity);
    }
  }

  void full_barrier() {
    VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = kWriteAccess;
    b.dstAccessMask = kAnyAccess;
    vkCmdPipelineBarrier(cmd, kWorkStages, kWorkStages, 0, 1, &b, 0, nullptr, 0, nullptr);
    pending.clear();
  }

  // Inserts a barrier when `touches` conflict with accesses since the last
  // one (read-after-write, write-after-read, write-after-write), then records
  // them.
  void track(std::span<const Touch> touches) {
    bool hazard = false;
    for (const Touch& t : touches) {
      for (const Touch& p : pending) {
        if (p.buffer == t.buffer && p.begin < t.end && t.begin < p.end && (p.write || t.write)) {
          hazard = true;
          break;
        }
      }
      if (hazard) break;
    }
    if (hazard) {
      full_barrier();
      ++barrier_count;
    }
    for (const Touch& t : touches) {
      pending.push_back(t);
      wrote = wrote || t.write;
    }
  }

  VkDescriptorSet allocate_set(VkDescriptorSetLayout layout) {
    for (;;) {
      if (pool_index == pools.size()) {
        const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1024},
                                              {VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER, 512},
                                              {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 256}};
        VkDescriptorPoolCreateInfo info{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
        info.maxSets = 256;
        info.poolSizeCount = 3;
        info.pPoolSizes = sizes;
        VkDescriptorPool pool_handle = VK_NULL_HANDLE;
        check(vkCreateDescriptorPool(core->device, &info, nullptr, &pool_handle),
              "create descriptor pool");
        pools.push_back(pool_handle);
      }
      VkDescriptorSetAllocateInfo info{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
      info.descriptorPool = pools[pool_index];
      info.descriptorSetCount = 1;
      info.pSetLayouts = &layout;
      VkDescriptorSet set = VK_NULL_HANDLE;
      const VkResult r = vkAllocateDescriptorSets(core->device, &info, &set);
      if (r == VK_SUCCESS) return set;
      if (r != VK_ERROR_OUT_OF_POOL_MEMORY && r != VK_ERROR_FRAGMENTED_POOL) {
        check(r, "allocate descriptor set");
      }
      ++pool_index;  // this pool is full: move on to the next
    }
  }

  void finish_wait() {
    if (state != State::submitted) return;
    VkResult r = VK_SUCCESS;
    if (host != nullptr) {
      try {
        host->wait();
      } catch (...) {
        reset();
        throw;
      }
    } else {
      r = vkWaitForFences(core->device, 1, &fence, VK_TRUE, UINT64_MAX);
    }
    state = State::idle;
    if (r == VK_SUCCESS && core->profile && !timed.empty()) {
      std::vector<std::uint64_t> stamps(timed.size() * 2);
      const VkResult qr = vkGetQueryPoolResults(
          core->device, queries, 0, static_cast<std::uint32_t>(stamps.size()),
          stamps.size() * sizeof(std::uint64_t), stamps.data(), sizeof(std::uint64_t),
          VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
      if (qr == VK_SUCCESS) {
        for (std::size_t i = 0; i < timed.size(); ++i) {
          const double ns =
              double(stamps[2 * i + 1] - stamps[2 * i]) * core->info.timestamp_period_ns;
          core->add_kernel_time(timed[i], ns);
        }
      }
    }
    reset();
    check(r, "wait for stream");
  }

  void reset() noexcept {
    if (host != nullptr) {
      cmd = VK_NULL_HANDLE;  // the host's, reset or freed by the host
    } else {
      vkResetFences(core->device, 1, &fence);
      vkResetCommandPool(core->device, pool, 0);
    }
    for (std::size_t i = 0; i < pools.size() && i <= pool_index; ++i) {
      vkResetDescriptorPool(core->device, pools[i], 0);
    }
    pool_index = 0;
    pending.clear();
    keep.clear();
    timed.clear();
    wrote = false;
    dispatch_count = 0;
    barrier_count = 0;
    state = State::idle;
  }

  ~Impl() {
    if (state == State::submitted) {
      if (host != nullptr) {
        try {
          host->wait();
        } catch (...) {  // NOLINT(bugprone-empty-catch): destructors never throw
        }
      } else {
        vkWaitForFences(core->device, 1, &fence, VK_TRUE, UINT64_MAX);
      }
    }
    for (VkDescriptorPool p : pools) vkDestroyDescriptorPool(core->device, p, nullptr);
    if (queries != VK_NULL_HANDLE) vkDestroyQueryPool(core->device, queries, nullptr);
    if (fence != VK_NULL_HANDLE) vkDestroyFence(core->device, fence, nullptr);
    if (pool != VK_NULL_HANDLE) vkDestroyCommandPool(core->device, pool, nullptr);
  }
};

Stream::Stream(const Device& device) : impl_(std::make_unique<Impl>(device)) {
  VkCommandPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pool_info.flags = VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
  pool_info.queueFamilyIndex = impl_->core->queue_family;
  check(vkCreateCommandPool(impl_->core->device, &pool_info, nullptr, &impl_->pool),
        "create command pool");
  VkCommandBufferAllocateInfo cmd_info{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  cmd_info.commandPool = impl_->pool;
  cmd_info.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  cmd_info.commandBufferCount = 1;
  check(vkAllocateCommandBuffers(impl_->core->device, &cmd_info, &impl_->cmd),
        "allocate command buffer");
  VkFenceCreateInfo fence_info{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  check(vkCreateFence(impl_->core->device, &fence_info, nullptr, &impl_->fence), "create fence");
}

Stream::Stream(const Device& device, HostCommands& host) : impl_(std::make_unique<Impl>(device)) {
  impl_->host = &host;
}

Stream::~Stream() = default;
Stream::Stream(Stream&&) noexcept = default;
Stream& Stream::operator=(Stream&&) noexcept = default;

const Device& Stream::device() const { return impl_->device; }
bool Stream::recording() const { return impl_->state == Impl::State::recording; }
bool Stream::host_commands() const { return impl_->host != nullptr; }
std::size_t Stream::dispatches() const { return impl_->dispatch_count; }
std::size_t Stream::barriers() const { return impl_->barrier_count; }

void Stream::keep_alive(const Tensor& t) {
  if (t.storage()) impl_->keep.push_back(t.storage());
}

void Stream::dispatch_raw(const KernelDef& kernel, std::initializer_list<Arg> args,
                          const void* push, std::uint32_t push_bytes, Groups groups,
                          std::initializer_list<std::uint32_t> spec) {
  Impl& s = *impl_;
  const DeviceInfo& info = s.core->info;
  // Nothing on this path allocates unless it throws: the error texts are
  // built only then, the bindings live in fixed arrays, and the pipeline is
  // found without building a key (DeviceCore::pipeline).
  const auto op = [&kernel] { return "dispatch " + std::string(kernel.shader); };
  // Asserted at dispatch: binding count and kinds, push-constant size, limits.
  if (args.size() != kernel.bindings.size()) {
    throw InvalidArgument(op(), "got " + std::to_string(args.size()) + " tensors for " +
                                    std::to_string(kernel.bindings.size()) + " bindings");
  }
  if (args.size() > kMaxBindings) {
    throw InvalidArgument(op(),
                          "the kernel declares " + std::to_string(args.size()) +
                              " bindings, more than the runtime's " + std::to_string(kMaxBindings),
                          "split the kernel or raise kMaxBindings in runtime/stream.cpp");
  }
  if (push_bytes != kernel.push_bytes) {
    throw InvalidArgument(op(), "push constants are " + std::to_string(push_bytes) +
                                    " bytes, the kernel declares " +
                                    std::to_string(kernel.push_bytes));
  }
  if (groups.x == 0 || groups.y == 0 || groups.z == 0) {
    throw InvalidArgument(op(), "empty dispatch (0 workgroups): an input has no elements",
                          "skip the op for empty inputs");
  }
  const std::uint32_t counts[3] = {groups.x, groups.y, groups.z};
  for (int i = 0; i < 3; ++i) {
    if (counts[i] > info.max_workgroup_count[i]) {
      throw InvalidArgument(op(),
                            "workgroup count " + std::to_string(counts[i]) + " on axis " +
                                std::to_string(i) + " exceeds the device limit " +
                                std::to_string(info.max_workgroup_count[i]),
                            "split the input into smaller batches");
    }
  }

  std::array<Touch, kMaxBindings> touches{};
  std::array<VkDescriptorBufferInfo, kMaxBindings> buffer_infos{};
  std::array<VkBufferView, kMaxBindings> views{};
  std::array<VkWriteDescriptorSet, kMaxBindings> writes{};
  std::uint32_t i = 0;
  for (const Arg& a : args) {
    const auto what = [&op, i] { return op() + " binding " + std::to_string(i); };
    if (a.kind != kernel.bindings[i]) {
      throw InvalidArgument(what(), std::string("is a ") + kind_name(kernel.bindings[i]) +
                                        " binding, got a " + kind_name(a.kind) + " argument");
    }
    if (!a.tensor.defined()) throw InvalidArgument(what(), "the tensor is undefined");
    if (a.tensor.storage()->core.get() != s.core) {
      throw InvalidArgument(what(), "the tensor lives on another device");
    }
    if (a.tensor.bytes() == 0) {
      throw InvalidArgument(what(), "tensor " + a.tensor.shape().str() + " is empty",
                            "skip the op for empty inputs");
    }
    const VkDeviceSize offset = a.tensor.vk_offset();
    const VkDeviceSize bytes = a.tensor.bytes();
    VkDeviceSize align = info.min_storage_buffer_offset_alignment;
    VkDeviceSize limit = info.max_storage_buffer_range;
    if (a.kind == BindingKind::uniform) {
      align = info.min_uniform_buffer_offset_alignment;
      limit = info.max_uniform_buffer_range;
    }
    if (a.kind == BindingKind::texel) {
      align = info.min_texel_buffer_offset_alignment;
      const std::uint32_t fb = format_bytes_of(a.format);
      if (fb == 0 || bytes % fb != 0) {
        throw InvalidArgument(what(), "texel format does not divide the tensor's " +
                                          std::to_string(bytes) + " bytes");
      }
      limit = info.max_texel_buffer_elements * fb;
    }
    if (bytes > limit) {
      throw InvalidArgument(what(),
                            "tensor " + a.tensor.shape().str() + " is " + format_bytes(bytes) +
                                ", over the device's " + kind_name(a.kind) + " binding limit of " +
                                format_bytes(limit),
                            "split it into chunks (e.g. fewer images per batch)");
    }
    if (align > 0 && offset % align != 0) {
      throw InvalidArgument(what(),
                            "view offset " + std::to_string(offset) +
                                " bytes is not a multiple of the device's alignment " +
                                std::to_string(align),
                            "start views at aligned element offsets");
    }
    touches[i] = {a.tensor.vk_buffer(), offset, offset + bytes, a.access != Access::read};

    VkWriteDescriptorSet& w = writes[i];
    w = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w.dstBinding = i;
    w.descriptorCount = 1;
    if (a.kind == BindingKind::texel) {
      views[i] = a.tensor.texel_view(a.format);
      w.descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
      w.pTexelBufferView = &views[i];
    } else {
      buffer_infos[i] = {a.tensor.vk_buffer(), offset, bytes};
      w.descriptorType = a.kind == BindingKind::uniform ? VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER
                                                        : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
      w.pBufferInfo = &buffer_infos[i];
    }
    ++i;
  }

  const std::uint32_t n_bindings = i;
  const detail::Pipeline& p =
      s.core->pipeline(kernel, std::span<const std::uint32_t>(spec.begin(), spec.size()));
  s.begin();
  s.track(std::span<const Touch>(touches.data(), n_bindings));
  vkCmdBindPipeline(s.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, p.pipeline);
  if (s.core->push_descriptors) {
    s.core->cmd_push_descriptor_set(s.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, p.layout, 0, n_bindings,
                                    writes.data());
  } else {
    VkDescriptorSet set = s.allocate_set(p.set_layout);
    for (std::uint32_t b = 0; b < n_bindings; ++b) writes[b].dstSet = set;
    vkUpdateDescriptorSets(s.core->device, n_bindings, writes.data(), 0, nullptr);
    vkCmdBindDescriptorSets(s.cmd, VK_PIPELINE_BIND_POINT_COMPUTE, p.layout, 0, 1, &set, 0,
                            nullptr);
  }
  if (push_bytes > 0) {
    vkCmdPushConstants(s.cmd, p.layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, push_bytes, push);
  }
  const bool time_it = s.core->profile && 2 * (s.timed.size() + 1) <= s.query_capacity;
  if (s.core->profile && !time_it) s.wanted_capacity = s.query_capacity * 2;
  const auto q = static_cast<std::uint32_t>(2 * s.timed.size());
  if (time_it) vkCmdWriteTimestamp(s.cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, s.queries, q);
  vkCmdDispatch(s.cmd, groups.x, groups.y, groups.z);
  if (time_it) {
    vkCmdWriteTimestamp(s.cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, s.queries, q + 1);
    s.timed.emplace_back(kernel.shader);
  }
  for (const Arg& a : args) s.keep.push_back(a.tensor.storage());
  ++s.dispatch_count;
}

void Stream::copy(const Tensor& src, const Tensor& dst) {
  if (!src.defined() || !dst.defined()) {
    throw InvalidArgument("Stream::copy", "a tensor is undefined");
  }
  if (src.bytes() != dst.bytes()) {
    throw InvalidArgument("Stream::copy", "source " + src.shape().str() + " has " +
                                              std::to_string(src.bytes()) + " bytes, destination " +
                                              dst.shape().str() + " has " +
                                              std::to_string(dst.bytes()));
  }
  if (src.bytes() == 0) return;
  Impl& s = *impl_;
  s.begin();
  const Touch touches[] = {{src.vk_buffer(), src.vk_offset(), src.vk_offset() + src.bytes(), false},
                           {dst.vk_buffer(), dst.vk_offset(), dst.vk_offset() + dst.bytes(), true}};
  s.track(touches);
  VkBufferCopy region{src.vk_offset(), dst.vk_offset(), src.bytes()};
  vkCmdCopyBuffer(s.cmd, src.vk_buffer(), dst.vk_buffer(), 1, &region);
  s.keep.push_back(src.storage());
  s.keep.push_back(dst.storage());
}

void Stream::fill(const Tensor& dst, std::uint32_t bits) {
  if (!dst.defined()) throw InvalidArgument("Stream::fill", "the tensor is undefined");
  if (dst.bytes() == 0) return;
  if (dst.bytes() % 4 != 0 || dst.vk_offset() % 4 != 0) {
    throw InvalidArgument("Stream::fill", "fill needs a multiple of 4 bytes at a 4-byte offset");
  }
  Impl& s = *impl_;
  s.begin();
  const Touch touches[] = {{dst.vk_buffer(), dst.vk_offset(), dst.vk_offset() + dst.bytes(), true}};
  s.track(touches);
  vkCmdFillBuffer(s.cmd, dst.vk_buffer(), dst.vk_offset(), dst.bytes(), bits);
  s.keep.push_back(dst.storage());
}

void Stream::fill(const Tensor& dst, float value) {
  fill(dst, std::bit_cast<std::uint32_t>(value));
}

void Stream::submit() { submit(SubmitSync{}); }

void Stream::submit(const SubmitSync& sync) {
  Impl& s = *impl_;
  const bool has_sync = !sync.wait_semaphores.empty() || !sync.signal_semaphores.empty() ||
                        sync.fence != VK_NULL_HANDLE;
  if (s.host != nullptr && has_sync) {
    throw InvalidArgument("Stream::submit", "semaphores or a fence for a stream on HostCommands",
                          "add them to the submission in HostCommands::submit");
  }
  if (!sync.wait_stages.empty() && sync.wait_stages.size() != sync.wait_semaphores.size()) {
    throw InvalidArgument("Stream::submit",
                          std::to_string(sync.wait_stages.size()) + " wait stage masks for " +
                              std::to_string(sync.wait_semaphores.size()) + " wait semaphores",
                          "give one stage mask per semaphore, or none");
  }
  if (s.state != Impl::State::recording && !has_sync) return;
  if (s.state == Impl::State::submitted) {
    throw Error("Stream::submit", "semaphores for a submission while earlier work is in flight",
                "call wait() first");
  }
  // Make results visible to the host (downloads, mapped reads).
  if (s.wrote) {
    VkMemoryBarrier b{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    b.srcAccessMask = kWriteAccess;
    b.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(s.cmd, kWorkStages, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &b, 0, nullptr, 0,
                         nullptr);
  }
  if (s.host != nullptr) {
    try {
      s.host->submit(s.cmd);  // the host ends and submits its buffer
    } catch (...) {
      s.reset();
      throw;
    }
    s.state = Impl::State::submitted;
    return;
  }
  const bool work = s.state == Impl::State::recording;
  if (work) check(vkEndCommandBuffer(s.cmd), "end command buffer");
  std::vector<VkPipelineStageFlags> stages = sync.wait_stages;
  stages.resize(sync.wait_semaphores.size(), kWorkStages);
  VkSubmitInfo info{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  info.waitSemaphoreCount = static_cast<std::uint32_t>(sync.wait_semaphores.size());
  info.pWaitSemaphores = sync.wait_semaphores.data();
  info.pWaitDstStageMask = stages.data();
  info.commandBufferCount = work ? 1 : 0;
  info.pCommandBuffers = &s.cmd;
  info.signalSemaphoreCount = static_cast<std::uint32_t>(sync.signal_semaphores.size());
  info.pSignalSemaphores = sync.signal_semaphores.data();
  VkResult r = VK_SUCCESS;
  VkResult r_fence = VK_SUCCESS;
  {
    std::lock_guard lock(s.core->queue_mutex);
    if (work) {
      r = vkQueueSubmit(s.core->queue, 1, &info, s.fence);
      // A fence of a later, empty submission also covers every earlier
      // submission to the queue: the host's fence signals when ours does.
      if (r == VK_SUCCESS && sync.fence != VK_NULL_HANDLE) {
        r_fence = vkQueueSubmit(s.core->queue, 0, nullptr, sync.fence);
      }
    } else {
      r = vkQueueSubmit(s.core->queue, 1, &info, sync.fence);
    }
  }
  if (r != VK_SUCCESS) {
    if (work) s.reset();
    check(r, "submit stream");
  }
  if (work) s.state = Impl::State::submitted;
  check(r_fence, "submit the host's fence");
}

void Stream::wait() { impl_->finish_wait(); }

}  // namespace vkjr2
