#include "train_images.hpp"

#include <vkjr2/runtime/error.hpp>

#include <filesystem>

#include "checks.hpp"
#include "log.hpp"
#include "media.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;

// Frames of a video used for training: every kVideoStride-th, --video-frames of them.
constexpr std::size_t kVideoStride = 10;

}  // namespace

void load_train_images(const std::string& command, const std::vector<std::string>& folders,
                       int val_every, int video_frames, int crop,
                       std::vector<jr2::TrainImage>& train, std::vector<jr2::TrainImage>& val) {
  std::vector<std::string> dirs = folders;
  if (dirs.empty()) dirs.emplace_back(kDefaultTrainImages);
  std::size_t small = 0, image_index = 0;
  for (const std::string& d : dirs) {
    if (dirs.size() == 1 && d == kDefaultTrainImages && !fs::is_directory(d)) {
      throw UsageError(command, std::string(kDefaultTrainImages) + " does not exist",
                       "install Debian's opencv-doc (scripts/setup) or pass --images DIR");
    }
    check_input_folder(d, "--images");
    for (const fs::path& p : list_files(d, [&](const fs::path& f) {
           return is_image_path(f) || (video_frames > 0 && is_video_path(f));
         })) {
      // A file that cannot be read is reported and left out (Debian's
      // opencv-doc ships a truncated tree.avi).
      try {
        if (is_video_path(p)) {
          std::vector<jr2::TrainImage> frames;
          read_video(p, kVideoStride, std::size_t(video_frames),
                     [&](std::size_t i, const Image& im) {
                       if (im.shape[0] >= crop && im.shape[1] >= crop) {
                         frames.push_back({p.filename().string() + "#" + std::to_string(i), im});
                       }
                     });
          for (auto& f : frames) train.push_back(std::move(f));
          continue;
        }
        Image im = read_image(p);
        if (im.shape[0] < crop || im.shape[1] < crop) {
          ++small;
          continue;
        }
        const bool held_out = val_every > 0 && image_index % std::size_t(val_every) == 0;
        ++image_index;
        (held_out ? val : train).push_back({p.filename().string(), std::move(im)});
      } catch (const Error& e) {
        log_warn(describe_error(e) + " (left out)");
      }
    }
  }
  if (small > 0) {
    log_info(std::to_string(small) + " images smaller than the " + std::to_string(crop) +
             "² crop were left out");
  }
  if (train.empty() || val.empty()) {
    throw UsageError(command,
                     std::to_string(train.size()) + " training and " + std::to_string(val.size()) +
                         " held-out images of at least " + std::to_string(crop) + "² pixels",
                     "pass --images folders with more images (or lower --crop, --val-every)");
  }
}

}  // namespace vkjr2::cli
