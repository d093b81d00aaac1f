#include "common/protocol/sha256.h"

#include <fstream>
#include <stdexcept>
#include <vector>

#include <openssl/crypto.h>
#include <openssl/evp.h>

namespace mirrorscan::protocol {
namespace {

EVP_MD_CTX* Context(void* context) { return static_cast<EVP_MD_CTX*>(context); }

}  // namespace

Sha256::Sha256() : context_(EVP_MD_CTX_new()) {
  if (context_ == nullptr || EVP_DigestInit_ex(Context(context_), EVP_sha256(), nullptr) != 1) {
    EVP_MD_CTX_free(Context(context_));
    throw std::runtime_error("SHA-256: OpenSSL could not initialise a digest");
  }
}

Sha256::~Sha256() { EVP_MD_CTX_free(Context(context_)); }

void Sha256::Update(std::span<const uint8_t> bytes) {
  if (finished_) throw std::logic_error("Sha256::Update after Digest");
  if (EVP_DigestUpdate(Context(context_), bytes.data(), bytes.size()) != 1) {
    throw std::runtime_error("SHA-256: digest update failed");
  }
}

void Sha256::Update(std::string_view bytes) {
  Update(std::span(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()));
}

std::array<uint8_t, 32> Sha256::Digest() {
  if (finished_) throw std::logic_error("Sha256::Digest called twice");
  std::array<uint8_t, 32> digest{};
  unsigned int length = 0;
  if (EVP_DigestFinal_ex(Context(context_), digest.data(), &length) != 1 || length != 32) {
    throw std::runtime_error("SHA-256: digest final failed");
  }
  finished_ = true;
  return digest;
}

std::string Sha256::HexDigest() {
  const auto digest = Digest();
  return Hex(std::string_view(reinterpret_cast<const char*>(digest.data()), digest.size()));
}

std::string Sha256::Hex(std::string_view bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string hex;
  hex.reserve(bytes.size() * 2);
  for (const char c : bytes) {
    const auto b = static_cast<uint8_t>(c);
    hex.push_back(kDigits[b >> 4]);
    hex.push_back(kDigits[b & 15]);
  }
  return hex;
}

std::string Sha256::HexOfFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path.string() + ": cannot open for reading");
  Sha256 sha;
  std::vector<char> buffer(1 << 16);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    sha.Update(std::string_view(buffer.data(), static_cast<size_t>(in.gcount())));
  }
  if (in.bad()) throw std::runtime_error(path.string() + ": read error");
  return sha.HexDigest();
}

bool SecretsEqual(std::string_view a, std::string_view b) {
  Sha256 sha_a;
  sha_a.Update(a);
  Sha256 sha_b;
  sha_b.Update(b);
  const auto da = sha_a.Digest();
  const auto db = sha_b.Digest();
  return CRYPTO_memcmp(da.data(), db.data(), da.size()) == 0;
}

}  // namespace mirrorscan::protocol
