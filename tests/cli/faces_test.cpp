// `vkjr2 detect | embed | verify | identify` on face-api's sample photos and
// the face crops of the parity references, as a user runs them.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "support/cli_files.hpp"
#include "support/parity.hpp"
#include "support/run_cli.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using vkjr2::test::parse_json;
using vkjr2::test::run_cli;
using vkjr2::test::TempDir;

fs::path sample_photo(int n) {
  return vkjr2::test::parity_dir().parent_path() / "face-api-1.7.15" / "demo" /
         ("sample" + std::to_string(n) + ".jpg");
}

fs::path chip150(const std::string& name) {
  return vkjr2::test::parity_dir() / (name + "_150.npy");
}

TEST(CliFaces, DetectFindsTheFacesOfSample1AndDraws) {
  ASSERT_TRUE(fs::exists(sample_photo(1))) << "run scripts/setup (fetches face-api's demo photos)";
  TempDir tmp("detect");
  const fs::path drawn = tmp.path / "boxes.png";
  const auto r = run_cli("detect " + sample_photo(1).string() + " --json --draw " + drawn.string());
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  ASSERT_TRUE(j.contains("faces")) << r.output;
  EXPECT_EQ(j["faces"].size(), 3u) << r.output;
  EXPECT_EQ(j["faces"][0]["landmarks"].size(), 68u);
  EXPECT_TRUE(fs::exists(drawn));
  EXPECT_FALSE(cv::imread(drawn.string()).empty()) << "the drawn PNG does not decode";
  // An existing output is not replaced without --force (a usage error, exit 2).
  const auto again = run_cli("detect " + sample_photo(1).string() + " --draw " + drawn.string());
  EXPECT_EQ(again.code, 2) << again.output;
  EXPECT_NE(again.output.find("--force"), std::string::npos) << again.output;
}

TEST(CliFaces, DetectOnAVideoAndOnAFaceFreeImage) {
  TempDir tmp("video");
  const fs::path video = tmp.path / "faces.avi";
  {
    const cv::Mat photo = cv::imread(sample_photo(2).string());
    ASSERT_FALSE(photo.empty()) << "run scripts/setup";
    cv::Mat small;
    cv::resize(photo, small, cv::Size(640, 427));
    cv::VideoWriter w(video.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 5, small.size());
    ASSERT_TRUE(w.isOpened());
    for (int i = 0; i < 3; ++i) w.write(small);
  }
  const auto r = run_cli("detect " + video.string() + " --every 2 --json");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  ASSERT_EQ(j["frames"].size(), 2u) << r.output;  // frames 0 and 2
  EXPECT_GE(j["frames"][0]["faces"].size(), 1u) << r.output;

  const fs::path grey = tmp.path / "grey.png";
  cv::imwrite(grey.string(), cv::Mat(96, 128, CV_8UC3, cv::Scalar(128, 128, 128)));
  const auto none = run_cli("detect " + grey.string());
  EXPECT_EQ(none.code, 0) << none.output;
  EXPECT_NE(none.output.find("0 faces"), std::string::npos) << none.output;
}

TEST(CliFaces, EmbedAlignedChipAndRejectCorruptImages) {
  const auto r = run_cli("embed " + chip150("sample1_f0").string() + " --aligned --json");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  ASSERT_EQ(j.size(), 1u) << r.output;
  EXPECT_EQ(j[0]["faces"][0]["descriptor"].size(), 128u);

  TempDir tmp("corrupt");
  // A folder stands for its images, in name order.
  const fs::path folder = tmp.path / "chips";
  fs::create_directories(folder);
  fs::copy_file(chip150("sample1_f0"), folder / "b.npy");
  fs::copy_file(chip150("sample1_f0"), folder / "a.npy");
  const auto f = run_cli("embed " + folder.string() + " --aligned --json");
  ASSERT_EQ(f.code, 0) << f.output;
  const json fj = parse_json(f.output);
  ASSERT_EQ(fj.size(), 2u) << f.output;
  EXPECT_EQ(fj[0]["input"], (folder / "a.npy").string());
  EXPECT_EQ(fj[1]["faces"][0]["descriptor"], j[0]["faces"][0]["descriptor"]);
  fs::create_directories(tmp.path / "empty");
  const auto empty = run_cli("embed " + (tmp.path / "empty").string());
  EXPECT_EQ(empty.code, 2) << empty.output;
  EXPECT_NE(empty.output.find("holds no image"), std::string::npos) << empty.output;

  const fs::path bad = tmp.path / "broken.jpg";
  std::ofstream(bad) << "\xff\xd8\xff\xe0 this is not really a JPEG";
  const auto e = run_cli("embed " + bad.string());
  EXPECT_EQ(e.code, 1) << e.output;
  EXPECT_NE(e.output.find("cannot decode"), std::string::npos) << e.output;
  EXPECT_EQ(e.output.find("terminate"), std::string::npos) << e.output;
  const auto missing = run_cli("embed " + (tmp.path / "nope.png").string());
  EXPECT_EQ(missing.code, 2) << missing.output;
}

TEST(CliFaces, VerifySameAndDifferentFaces) {
  const auto same = run_cli("verify " + chip150("sample1_f0").string() + " " +
                            chip150("sample1_f0").string() + " --aligned --json");
  ASSERT_EQ(same.code, 0) << same.output;
  EXPECT_TRUE(parse_json(same.output)["same_person"].get<bool>()) << same.output;
  const auto diff = run_cli("verify " + chip150("sample1_f0").string() + " " +
                            chip150("sample1_f1").string() + " --aligned --json");
  ASSERT_EQ(diff.code, 0) << diff.output;
  EXPECT_GT(parse_json(diff.output)["distance"].get<double>(), 0.3) << diff.output;
  // Bad inputs: a missing file (command line) and a truncated array (runtime).
  TempDir tmp("verify_bad");
  const auto missing =
      run_cli("verify " + chip150("sample1_f0").string() + " " + (tmp.path / "x.npy").string());
  EXPECT_EQ(missing.code, 2) << missing.output;
  const fs::path cut = tmp.path / "cut.npy";
  {
    std::ifstream src(chip150("sample1_f0"), std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(src)), std::istreambuf_iterator<char>());
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  const auto truncated =
      run_cli("verify " + chip150("sample1_f0").string() + " " + cut.string() + " --aligned");
  EXPECT_EQ(truncated.code, 1) << truncated.output;
  EXPECT_NE(truncated.output.find(cut.string()), std::string::npos) << truncated.output;
}

TEST(CliFaces, IdentifyRanksTheProbeIdentityFirst) {
  TempDir tmp("gallery");
  for (const char* id : {"sample1_f0", "sample1_f1", "sample2_f0"}) {
    fs::create_directories(tmp.path / id);
    fs::copy_file(chip150(id), tmp.path / id / "a.npy");
  }
  const auto r = run_cli("identify " + chip150("sample1_f1").string() + " --gallery " +
                         tmp.path.string() + " --aligned --json --top 2");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  ASSERT_EQ(j["candidates"].size(), 2u) << r.output;
  EXPECT_EQ(j["candidates"][0]["identity"], "sample1_f1") << r.output;

  TempDir empty("empty_gallery");
  fs::create_directories(empty.path / "nobody");
  const auto e = run_cli("identify " + chip150("sample1_f1").string() + " --gallery " +
                         empty.path.string() + " --aligned");
  EXPECT_EQ(e.code, 1) << e.output;
  EXPECT_NE(e.output.find("no usable face image"), std::string::npos) << e.output;
}

}  // namespace
