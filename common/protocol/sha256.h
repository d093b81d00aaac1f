#pragma once

// SHA-256 through OpenSSL's libcrypto (EVP), for archive checksums and token comparison.

#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

namespace mirrorscan::protocol {

class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;

  void Update(std::span<const uint8_t> bytes);
  void Update(std::string_view bytes);
  // Ends the hash; Update after this throws.
  std::array<uint8_t, 32> Digest();
  std::string HexDigest();  // lower-case, 64 characters

  static std::string Hex(std::string_view bytes);
  // Throws std::runtime_error naming the file when it cannot be read.
  static std::string HexOfFile(const std::filesystem::path& path);

 private:
  void* context_;  // EVP_MD_CTX
  bool finished_ = false;
};

// Constant-time equality of two secrets of any lengths (compares their SHA-256 digests with
// CRYPTO_memcmp, so neither content nor length leaks through timing).
bool SecretsEqual(std::string_view a, std::string_view b);

}  // namespace mirrorscan::protocol
