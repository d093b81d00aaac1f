#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "common/scan_format/scan_format.h"

namespace mirrorscan {

namespace {

[[noreturn]] void ThrowErrno(const std::filesystem::path& path, const std::string& what) {
  throw ScanFormatError(path.string() + ": " + what + ": " + std::strerror(errno));
}

// fsync the directory too: a new file's entry is not durable until its directory is.
void SyncDirectoryOf(const std::filesystem::path& path) {
  std::filesystem::path dir = path.parent_path();
  if (dir.empty()) dir = ".";
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) ThrowErrno(dir, "cannot open directory to sync it");
  const int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) ThrowErrno(dir, "fsync");
}

}  // namespace

class ScanFileWriter::FileSink : public ByteSink {
 public:
  FileSink(const std::filesystem::path& path, bool overwrite) : path_(path) {
    const int flags = O_WRONLY | O_CREAT | O_CLOEXEC | (overwrite ? O_TRUNC : O_EXCL);
    fd_ = ::open(path.c_str(), flags, 0644);
    if (fd_ < 0) ThrowErrno(path, "cannot create scan archive");
  }
  ~FileSink() override {
    if (fd_ >= 0) ::close(fd_);
  }
  FileSink(const FileSink&) = delete;
  FileSink& operator=(const FileSink&) = delete;

  void Write(std::span<const uint8_t> bytes) override {
    while (!bytes.empty()) {
      const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
      if (n < 0) {
        if (errno == EINTR) continue;
        ThrowErrno(path_, "write");
      }
      bytes = bytes.subspan(static_cast<size_t>(n));
    }
  }
  void Sync() override {
    if (::fsync(fd_) != 0) ThrowErrno(path_, "fsync");
  }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

ScanFileWriter::ScanFileWriter(const std::filesystem::path& path, ScanFileWriterOptions options)
    : path_(path),
      options_(options),
      sink_(std::make_unique<FileSink>(path, options.overwrite)),
      writer_(*sink_) {}

ScanFileWriter::~ScanFileWriter() = default;

void ScanFileWriter::Begin(const nlohmann::json& header) { writer_.Begin(header); }

void ScanFileWriter::AppendFrame(const FrameRecord& frame) {
  writer_.AppendFrame(frame);
  if (options_.fsync_every_frames > 0 &&
      writer_.frames_written() % options_.fsync_every_frames == 0) {
    sink_->Sync();
  }
}

void ScanFileWriter::Finish(const nlohmann::json& footer) {
  writer_.Finish(footer);
  if (options_.fsync_on_finish) {
    sink_->Sync();
    SyncDirectoryOf(path_);
  }
}

ScanArchive ReadScanFile(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) ThrowErrno(path, "cannot open scan archive");
  struct FdCloser {
    int fd;
    ~FdCloser() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) ThrowErrno(path, "fstat");
  if (!S_ISREG(st.st_mode)) throw ScanFormatError(path.string() + ": not a regular file");

  std::vector<uint8_t> bytes;
  size_t size = 0;
  for (;;) {
    bytes.resize(size + (1 << 20));
    const ssize_t n = ::read(fd, bytes.data() + size, bytes.size() - size);
    if (n < 0) {
      if (errno == EINTR) continue;
      ThrowErrno(path, "read");
    }
    if (n == 0) break;
    size += static_cast<size_t>(n);
  }
  bytes.resize(size);
  try {
    return ReadScan(bytes);
  } catch (const ScanFormatError& e) {
    throw ScanFormatError(path.string() + ": " + e.what());
  }
}

}  // namespace mirrorscan
