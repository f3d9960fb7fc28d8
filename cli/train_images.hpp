// The clean images of the restorer's training and of its held-out sets
// (vkjr2 restore-train, vkjr2 wave-clips): every image, and video_frames
// frames (every 10th) of every video, directly inside each folder (default:
// Debian's opencv-doc sample data; video_frames 0: no videos). Every val_every-th image by name is
// held out; video frames always train. Unreadable files are reported and left out; images smaller
// than crop² are counted and left out.
#pragma once

#include <vkjr2/jr2/restore_train.hpp>

#include <string>
#include <vector>

namespace vkjr2::cli {

inline constexpr const char* kDefaultTrainImages = "/usr/share/doc/opencv-doc/examples/data";

// Throws UsageError (naming `command`) when no training or no held-out image is left.
void load_train_images(const std::string& command, const std::vector<std::string>& folders,
                       int val_every, int video_frames, int crop,
                       std::vector<jr2::TrainImage>& train, std::vector<jr2::TrainImage>& val);

}  // namespace vkjr2::cli
