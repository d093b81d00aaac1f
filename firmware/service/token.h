#pragma once

// The device API's bearer token (docs/device-api.md, "Authentication").

#include <filesystem>
#include <string>

#include "firmware/board/board_config.h"

namespace mirrorscan::service {

// Reads the token from `file`; if the file does not exist, generates a random one
// (32 bytes from OpenSSL's RAND_bytes, hex) and writes it there with mode 0600 (the parent
// directory is created with mode 0700). A file readable by group or others, a file that
// is not a valid token, or any I/O failure is a std::runtime_error naming the file.
std::string LoadOrCreateTokenFile(const std::filesystem::path& file);

// The token a board's "service" section asks for: the fixed `token`, or the token file's.
std::string ResolveServiceToken(const board::ServiceConfig& service);

}  // namespace mirrorscan::service
