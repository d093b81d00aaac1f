#include "firmware/service/calibration_store.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "common/config/calibration.h"
#include "common/config/json_reader.h"
#include "common/protocol/sha256.h"

namespace mirrorscan::service {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void IoFail(const fs::path& path, const std::string& what) {
  throw std::runtime_error(path.string() + ": " + what + ": " + std::strerror(errno));
}

void WriteFileAtomically(const fs::path& path, const std::string& text) {
  const fs::path temp = path.string() + ".tmp";
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) IoFail(temp, "cannot create");
  size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      ::close(fd);
      ::unlink(temp.c_str());
      IoFail(temp, "cannot write");
    }
    written += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0) {
    ::close(fd);
    ::unlink(temp.c_str());
    IoFail(temp, "cannot fsync");
  }
  ::close(fd);
  if (::rename(temp.c_str(), path.c_str()) != 0) {
    ::unlink(temp.c_str());
    IoFail(path, "cannot rename the new file into place");
  }
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const int dir_fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir_fd >= 0) {
    ::fsync(dir_fd);
    ::close(dir_fd);
  }
}

std::string HexSha256(const std::string& text) {
  protocol::Sha256 sha;
  sha.Update(text);
  return sha.HexDigest();
}

}  // namespace

void ValidateCalibration(const nlohmann::json& calibration, const std::string& source) {
  // The schema's own parser (common/config/calibration.h), the same one the host uses:
  // every check the device needs before trusting an upload lives there.
  Calibration::Parse(calibration, source);
}

CalibrationStore::CalibrationStore(fs::path path) : path_(std::move(path)) {
  std::error_code ec;
  if (!fs::exists(path_, ec)) return;
  std::ifstream in(path_, std::ios::binary);
  if (!in) throw std::runtime_error(path_.string() + ": cannot open for reading");
  std::ostringstream text;
  text << in.rdbuf();
  try {
    ValidateCalibration(JsonReader::ParseText(text.str(), path_.string()), path_.string());
  } catch (const ConfigError& e) {
    const fs::path aside = path_.string() + ".invalid";
    in.close();
    if (::rename(path_.c_str(), aside.c_str()) != 0) IoFail(path_, "cannot set it aside");
    problem_ = std::string(e.what()) + " (set aside as " + aside.filename().string() + ")";
    return;
  }
  text_ = text.str();
  sha256_ = HexSha256(*text_);
}

std::optional<std::string> CalibrationStore::Get() const {
  std::lock_guard lock(mutex_);
  return text_;
}

std::string CalibrationStore::Sha256() const {
  std::lock_guard lock(mutex_);
  return sha256_;
}

std::string CalibrationStore::problem() const {
  std::lock_guard lock(mutex_);
  return problem_;
}

std::string CalibrationStore::Put(const std::string& text, const std::string& source) {
  ValidateCalibration(JsonReader::ParseText(text, source), source);
  const std::string sha = HexSha256(text);
  std::lock_guard lock(mutex_);
  WriteFileAtomically(path_, text);
  text_ = text;
  sha256_ = sha;
  problem_.clear();
  return sha;
}

}  // namespace mirrorscan::service
