// A host application embedding vkjr2 in its own Vulkan video pipeline.
// The host owns everything Vulkan: instance, device, queue, buffers, command
// buffers, semaphores and fences (host_vulkan.hpp, plain Vulkan). Per frame:
//
//   1. OpenCV decodes the frame straight into the host's mapped buffer
//      `decoded` (BGR, 8-bit) and converts it into `staging` (RGB planes,
//      float 0..255), both the host's memory;
//   2. the host's own command buffer copies `staging` → `frame` on the GPU
//      and signals the semaphore `frame_ready`;
//   3. vkjr2 wraps `frame` (Tensor::wrap, no copy) and runs the face stack
//      (detect → landmarks → align → descriptor), recording into the host's
//      command buffer (HostQueue below, a vkjr2::HostCommands): its first
//      submission waits for `frame_ready`, each one signals the host's fence.
//
//   vkjr2_host_pipeline VIDEO [--max-frames N] [--check] [--save DIR]
//
// --check runs the same frames through vkjr2's own Device and Stream and
// fails when a descriptor differs by more than 1e-4. --save writes each
// frame as DIR/frame_N.npy (float32 HWC RGB 0..255, what `vkjr2 embed`
// reads) and its descriptors as DIR/frame_N.txt (a face per line). VKJR2_VALIDATION=1 puts
// the host's instance under the validation layer (synchronization validation
// on); any message fails the run. Walked through in docs/api.md.
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/runtime/tensor.hpp>

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "host_vulkan.hpp"

namespace {

struct Args {
  std::string video;
  int max_frames = 3;
  bool check = false;
  std::string save_dir;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--max-frames" && i + 1 < argc) {
      a.max_frames = std::stoi(argv[++i]);
    } else if (arg == "--check") {
      a.check = true;
    } else if (arg == "--save" && i + 1 < argc) {
      a.save_dir = argv[++i];
    } else if (a.video.empty() && arg[0] != '-') {
      a.video = arg;
    } else {
      throw vkjr2::InvalidArgument(
          "command line", "unexpected argument '" + arg + "'",
          "vkjr2_host_pipeline VIDEO [--max-frames N] [--check] [--save DIR]");
    }
  }
  if (a.video.empty()) {
    throw vkjr2::InvalidArgument("command line", "no video given", "vkjr2_host_pipeline VIDEO");
  }
  return a;
}

// The host's side of vkjr2::HostCommands: vkjr2 records into the host's
// command buffer; the host ends and submits it, adding its own semaphore
// wait to the first submission after a frame upload, and waits on its fence.
class HostQueue final : public vkjr2::HostCommands {
 public:
  explicit HostQueue(const host::Vulkan& vk) : vk_(vk), commands_(vk) {}

  // The next submission waits for `s` (e.g. the frame upload) before its
  // compute and transfer work.
  void wait_next_for(VkSemaphore s) { wait_for_ = s; }

  VkCommandBuffer begin() override {
    commands_.begin();
    return commands_.cmd;
  }
  void submit(VkCommandBuffer cmd) override {
    host::check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
    submit_batch(&cmd, 1);
    ++submissions;
  }
  void wait() override {
    host::check(vkWaitForFences(vk_.device, 1, &commands_.fence, VK_TRUE, UINT64_MAX),
                "vkWaitForFences");
    host::check(vkResetFences(vk_.device, 1, &commands_.fence), "vkResetFences");
  }
  // Consumes a semaphore wait that no vkjr2 submission took (the semaphore
  // must be waited before it is signalled again).
  void flush() {
    if (wait_for_ == VK_NULL_HANDLE) return;
    submit_batch(nullptr, 0);
    wait();
  }

  int submissions = 0;

 private:
  void submit_batch(const VkCommandBuffer* cmd, std::uint32_t count) {
    const VkPipelineStageFlags stage =
        VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
    VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
    si.waitSemaphoreCount = wait_for_ != VK_NULL_HANDLE ? 1 : 0;
    si.pWaitSemaphores = &wait_for_;
    si.pWaitDstStageMask = &stage;
    si.commandBufferCount = count;
    si.pCommandBuffers = cmd;
    // vkjr2 submits to this queue too (weights, downloads): same thread here;
    // a multi-threaded host would serialize its submissions with vkjr2's.
    host::check(vkQueueSubmit(vk_.queue, 1, &si, commands_.fence), "vkQueueSubmit");
    wait_for_ = VK_NULL_HANDLE;
  }

  const host::Vulkan& vk_;
  host::Commands commands_;
  VkSemaphore wait_for_ = VK_NULL_HANDLE;
};

void print_faces(int frame, const char* label, const std::vector<vkjr2::jr2::Face>& faces) {
  std::printf("frame %d (%s): %zu face(s)\n", frame, label, faces.size());
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const auto& f = faces[i];
    std::printf("  #%zu score %.4f box (%.1f, %.1f, %.1f x %.1f) descriptor [", i, double(f.score),
                f.box.x, f.box.y, f.box.width, f.box.height);
    for (std::size_t k = 0; k < 4 && k < f.descriptor.size(); ++k) {
      std::printf("%s%.5f", k > 0 ? ", " : "", double(f.descriptor[k]));
    }
    std::printf(", ...]\n");
  }
}

// `planes` [3, H, W] as a float32 H×W×3 .npy (format version 1.0).
void write_npy(const std::string& path, const float* planes, int h, int w) {
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(h) +
                       ", " + std::to_string(w) + ", 3), }";
  header.append(63 - (10 + header.size()) % 64, ' ');  // total length a multiple of 64
  header += '\n';
  std::vector<float> hwc(std::size_t(h) * std::size_t(w) * 3);
  const std::size_t hw = std::size_t(h) * std::size_t(w);
  for (std::size_t i = 0; i < hw; ++i) {
    for (std::size_t c = 0; c < 3; ++c) hwc[3 * i + c] = planes[c * hw + i];
  }
  std::ofstream out(path, std::ios::binary);
  const auto len = static_cast<std::uint16_t>(header.size());
  out.write("\x93NUMPY\x01\x00", 8);
  const char len_le[2] = {char(len & 0xff), char(len >> 8)};
  out.write(len_le, 2);
  out << header;
  out.write(reinterpret_cast<const char*>(hwc.data()), std::streamsize(hwc.size() * sizeof(float)));
  if (!out) throw vkjr2::Error("--save", path + " cannot be written", "check the folder");
}

void write_descriptors(const std::string& path, const std::vector<vkjr2::jr2::Face>& faces) {
  std::ofstream out(path);
  out.precision(9);
  for (const auto& f : faces) {
    for (std::size_t k = 0; k < f.descriptor.size(); ++k)
      out << (k > 0 ? " " : "") << f.descriptor[k];
    out << '\n';
  }
  if (!out) throw vkjr2::Error("--save", path + " cannot be written", "check the folder");
}

// The largest |difference| between two frames' descriptors; infinity when
// the faces differ in number.
double max_difference(const std::vector<vkjr2::jr2::Face>& a,
                      const std::vector<vkjr2::jr2::Face>& b) {
  if (a.size() != b.size()) return INFINITY;
  double worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].descriptor.size() != b[i].descriptor.size()) return INFINITY;
    for (std::size_t k = 0; k < a[i].descriptor.size(); ++k) {
      worst = std::max(worst, std::abs(double(a[i].descriptor[k]) - b[i].descriptor[k]));
    }
  }
  return worst;
}

int run(const Args& a) {
  const char* env = std::getenv("VKJR2_VALIDATION");
  const bool validation = env != nullptr && std::string(env) == "1";

  cv::VideoCapture capture(a.video);
  if (!capture.isOpened()) {
    throw vkjr2::Error("open video", a.video + " cannot be opened", "pass a video OpenCV reads");
  }
  const int w = int(capture.get(cv::CAP_PROP_FRAME_WIDTH));
  const int h = int(capture.get(cv::CAP_PROP_FRAME_HEIGHT));
  const auto pixels = VkDeviceSize(w) * VkDeviceSize(h);
  const VkDeviceSize frame_bytes = 3 * pixels * sizeof(float);

  // ---- the host's Vulkan objects ------------------------------------------
  host::Vulkan vk(validation);
  const VkBufferUsageFlags usage =
      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
      VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  host::Buffer decoded(vk, (3 * pixels + 3) / 4 * 4, VK_BUFFER_USAGE_TRANSFER_SRC_BIT);
  host::Buffer staging(vk, frame_bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT);
  host::Buffer frame(vk, frame_bytes, usage);  // what vkjr2 reads
  host::Commands upload(vk);
  const VkSemaphore frame_ready = vk.make_semaphore();
  HostQueue queue(vk);

  // OpenCV headers over the host's mapped memory: decoding and conversion
  // write straight into the host's buffers.
  cv::Mat bgr(h, w, CV_8UC3, decoded.mapped);
  std::vector<cv::Mat> planes;
  for (int c = 0; c < 3; ++c) {
    planes.emplace_back(h, w, CV_32F, static_cast<float*>(staging.mapped) + c * pixels);
  }

  int exit_code = 0;
  {
    // ---- vkjr2 on the host's device ---------------------------------------
    vkjr2::ExternalDevice ext;
    ext.instance = vk.instance;
    ext.physical_device = vk.physical;
    ext.device = vk.device;
    ext.queue_family = vk.family;
    ext.queue = vk.queue;
    ext.enabled_extensions = vk.device_extensions;
    const vkjr2::Device device(ext);
    std::printf("host device: %s (adopted by vkjr2)\n", device.info().name.c_str());
    const vkjr2::jr2::FaceAnalyzer analyzer(device);
    vkjr2::Stream stream(device, queue);  // records into the host's command buffer
    const vkjr2::Shape shape{1, 3, h, w};
    const vkjr2::Tensor image = vkjr2::Tensor::wrap(device, frame.buffer, 0, shape);
    const vkjr2::jr2::FaceOptions options;

    // ---- the reference: vkjr2's own device and stream ---------------------
    std::optional<vkjr2::Device> own;
    std::unique_ptr<vkjr2::jr2::FaceAnalyzer> own_analyzer;
    std::unique_ptr<vkjr2::Stream> own_stream;
    if (a.check) {
      own.emplace();
      own_analyzer = std::make_unique<vkjr2::jr2::FaceAnalyzer>(*own);
      own_stream = std::make_unique<vkjr2::Stream>(*own);
    }

    double worst = 0;
    int frames = 0, faces_total = 0;
    for (; frames < a.max_frames; ++frames) {
      // 1. decode into the host's mapped buffer (OpenCV writes into the
      //    Mat's memory when size and type match), convert into `staging`.
      if (!capture.read(bgr)) break;
      if (bgr.data != decoded.mapped) {
        throw vkjr2::Error("decode", "OpenCV reallocated the frame", "check the video's format");
      }
      std::vector<cv::Mat> bgr_planes;
      cv::split(bgr, bgr_planes);
      for (int c = 0; c < 3; ++c)
        bgr_planes[std::size_t(2 - c)].convertTo(planes[std::size_t(c)], CV_32F);

      // 2. the host's GPU copy staging → frame, signalling frame_ready.
      upload.begin();
      // After vkjr2's reads of the previous frame (earlier submissions).
      VkMemoryBarrier after_reads{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
      after_reads.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
      vkCmdPipelineBarrier(
          upload.cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
          VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &after_reads, 0, nullptr, 0, nullptr);
      const VkBufferCopy region{0, 0, frame_bytes};
      vkCmdCopyBuffer(upload.cmd, staging.buffer, frame.buffer, 1, &region);
      host::check(vkEndCommandBuffer(upload.cmd), "vkEndCommandBuffer");
      VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
      si.commandBufferCount = 1;
      si.pCommandBuffers = &upload.cmd;
      si.signalSemaphoreCount = 1;
      si.pSignalSemaphores = &frame_ready;
      host::check(vkQueueSubmit(vk.queue, 1, &si, upload.fence), "vkQueueSubmit");
      queue.wait_next_for(frame_ready);

      // 3. vkjr2's face stack on the host's buffer and command buffers.
      const auto faces = analyzer.analyze(stream, image, options);
      queue.flush();
      // The upload finished before vkjr2's first submission started; the
      // staging buffer may be written again.
      host::check(vkWaitForFences(vk.device, 1, &upload.fence, VK_TRUE, UINT64_MAX), "wait");
      host::check(vkResetFences(vk.device, 1, &upload.fence), "vkResetFences");
      print_faces(frames, "host pipeline", faces);
      if (!a.save_dir.empty()) {
        const std::string stem = a.save_dir + "/frame_" + std::to_string(frames);
        write_npy(stem + ".npy", static_cast<const float*>(staging.mapped), h, w);
        write_descriptors(stem + ".txt", faces);
      }
      faces_total += int(faces.size());

      if (a.check) {
        const std::span<const float> values(static_cast<const float*>(staging.mapped),
                                            std::size_t(3 * pixels));
        const auto reference =
            own_analyzer->analyze(*own_stream, vkjr2::Tensor::from(*own, shape, values), options);
        const double d = max_difference(faces, reference);
        std::printf(
            "frame %d: vkjr2-owned device finds %zu face(s); max |descriptor difference| %.3g\n",
            frames, reference.size(), d);
        worst = std::max(worst, d);
      }
    }
    std::printf("%d frame(s), %d face(s), %d submissions of the host's command buffer\n", frames,
                faces_total, queue.submissions);
    if (frames == 0) {
      std::fprintf(stderr, "vkjr2_host_pipeline: %s has no frames\n", a.video.c_str());
      exit_code = 1;
    }
    if (a.check) {
      const bool ok = worst <= 1e-4;
      std::printf(
          "check: max |descriptor difference| host pipeline vs vkjr2-owned device %.3g (%s, "
          "tolerance 1e-4)\n",
          worst, ok ? "ok" : "FAILED");
      if (!ok) exit_code = 1;
      if (own->validation_message_count() > 0) exit_code = 1;
    }
  }  // vkjr2's objects go first; the host's stay alive and are the host's to destroy
  vkDestroySemaphore(vk.device, frame_ready, nullptr);
  if (vk.validation_messages > 0) {
    std::fprintf(stderr, "vkjr2_host_pipeline: %d validation message(s)\n", vk.validation_messages);
    exit_code = 1;
  }
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parse(argc, argv));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vkjr2_host_pipeline: %s\n", e.what());
    return 1;
  }
}
