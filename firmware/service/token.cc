#include "firmware/service/token.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <openssl/rand.h>

#include "common/protocol/sha256.h"

namespace mirrorscan::service {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void Fail(const fs::path& file, const std::string& problem) {
  throw std::runtime_error("token file " + file.string() + ": " + problem);
}

std::string Errno() { return std::strerror(errno); }

std::string GenerateToken(const fs::path& file) {
  std::array<unsigned char, 32> random{};
  if (RAND_bytes(random.data(), static_cast<int>(random.size())) != 1) {
    Fail(file, "OpenSSL could not generate random bytes");
  }
  return protocol::Sha256::Hex(
      std::string_view(reinterpret_cast<const char*>(random.data()), random.size()));
}

void WriteNewTokenFile(const fs::path& file, const std::string& token) {
  const fs::path dir = file.parent_path();
  if (!dir.empty() && !fs::exists(dir)) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) Fail(file, "cannot create its directory: " + ec.message());
    fs::permissions(dir, fs::perms::owner_all, ec);
  }
  // O_EXCL: two daemons starting at once never overwrite each other's token.
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) Fail(file, "cannot create: " + Errno());
  const std::string text = token + "\n";
  const bool ok = ::write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size()) &&
                  ::fsync(fd) == 0;
  const std::string error = ok ? "" : Errno();
  ::close(fd);
  if (!ok) {
    ::unlink(file.c_str());
    Fail(file, "cannot write: " + error);
  }
}

}  // namespace

std::string LoadOrCreateTokenFile(const fs::path& file) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) {
    if (errno != ENOENT) Fail(file, Errno());
    const std::string token = GenerateToken(file);
    WriteNewTokenFile(file, token);
    return token;
  }
  if (!S_ISREG(st.st_mode)) Fail(file, "not a regular file");
  if ((st.st_mode & 077) != 0) {
    std::ostringstream mode;
    mode << std::oct << (st.st_mode & 0777);
    Fail(file, "readable or writable by others (mode 0" + mode.str() + "); chmod 600 it");
  }
  std::ifstream in(file);
  std::string token;
  if (!in || !std::getline(in, token)) Fail(file, "cannot read");
  if (!board::IsValidServiceToken(token)) {
    Fail(file, std::string("expected one line of ") + board::kServiceTokenRule);
  }
  return token;
}

std::string ResolveServiceToken(const board::ServiceConfig& service) {
  if (!service.token.empty()) return service.token;
  return LoadOrCreateTokenFile(service.token_file);
}

}  // namespace mirrorscan::service
