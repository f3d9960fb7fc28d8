#include <vkjr2/runtime/host_tensor.hpp>

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>
#include <utility>

namespace vkjr2 {

std::int64_t HostTensor::numel() const { return checked_numel(shape, "HostTensor shape"); }

std::string shape_str(std::span<const std::int64_t> shape) {
  std::string s = "[";
  for (std::size_t i = 0; i < shape.size(); ++i) {
    if (i) s += ", ";
    s += std::to_string(shape[i]);
  }
  return s + "]";
}

std::int64_t checked_numel(std::span<const std::int64_t> dims, std::string_view what,
                           std::int64_t max_numel) {
  std::int64_t n = 1;
  for (std::int64_t d : dims) {
    if (d < 0) {
      throw InvalidArgument("checked_numel",
                            std::string(what) + " has a negative dimension in " + shape_str(dims),
                            "dimensions must be >= 0");
    }
    std::int64_t next = 0;
    if (__builtin_mul_overflow(n, d, &next) || next > max_numel) {
      throw InvalidArgument("checked_numel",
                            std::string(what) + " shape " + shape_str(dims) +
                                " has more elements than the data can hold (limit " +
                                std::to_string(max_numel) + ")",
                            "the file is corrupt or was not written by a matching writer");
    }
    n = next;
  }
  return n;
}

std::vector<std::byte> read_file_bytes(const std::filesystem::path& path, std::string_view op) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw Error(std::string(op), "'" + path.string() + "' does not exist or is not a regular file",
                "check the path");
  }
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) {
    throw Error(std::string(op), "cannot open '" + path.string() + "': " + std::strerror(errno),
                "check the file's permissions");
  }
  const std::streamoff size = in.tellg();
  if (size < 0) {
    throw Error(std::string(op), "cannot determine the size of '" + path.string() + "'",
                "check that it is a regular file");
  }
  std::vector<std::byte> bytes(static_cast<std::size_t>(size));
  in.seekg(0);
  in.read(reinterpret_cast<char*>(bytes.data()), size);
  if (!in || in.gcount() != size) {
    throw Error(std::string(op), "short read from '" + path.string() + "'",
                "the file changed while being read or the disk failed; retry");
  }
  return bytes;
}

namespace {

class FdGuard {
 public:
  explicit FdGuard(int fd) : fd_(fd) {}
  FdGuard(const FdGuard&) = delete;
  FdGuard& operator=(const FdGuard&) = delete;
  ~FdGuard() {
    if (fd_ >= 0) ::close(fd_);
  }
  int get() const noexcept { return fd_; }
  int release() noexcept { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

}  // namespace

void write_file_atomic(const std::filesystem::path& path, std::span<const std::byte> bytes,
                       std::string_view op) {
  static std::atomic<unsigned> counter{0};
  const std::filesystem::path dir =
      path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  const std::filesystem::path tmp =
      dir / ("." + path.filename().string() + ".tmp." + std::to_string(::getpid()) + "." +
             std::to_string(counter.fetch_add(1)));
  auto fail = [&](const std::string& what) {
    const int err = errno;
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw Error(
        std::string(op), what + " while writing '" + path.string() + "': " + std::strerror(err),
        "check that the directory '" + dir.string() + "' exists, is writable and has free space");
  };
  FdGuard fd(::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644));
  if (fd.get() < 0) fail("cannot create the temporary file '" + tmp.string() + "'");
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd.get(), bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("write failed");
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd.get()) != 0) fail("fsync failed");
  if (::close(fd.release()) != 0) fail("close failed");
  if (::rename(tmp.c_str(), path.c_str()) != 0) fail("rename of the temporary file failed");
}

}  // namespace vkjr2
