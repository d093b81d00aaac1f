#pragma once

#include <filesystem>
#include <initializer_list>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace mirrorscan {

// Every configuration error names the file and the key: "scene.json: cameras[1].fx: ...".
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Read-only view of one JSON object inside a file, tracking the key path for errors.
class JsonReader {
 public:
  JsonReader(const nlohmann::json& value, std::string file, std::string path = "");

  // Parses a file; a missing file or a syntax error is a ConfigError naming the file.
  static nlohmann::json ParseFile(const std::filesystem::path& file);
  static nlohmann::json ParseText(const std::string& text, const std::string& file);

  bool Has(const std::string& key) const;
  JsonReader Object(const std::string& key) const;
  std::vector<JsonReader> Objects(const std::string& key) const;

  double Number(const std::string& key, std::optional<double> fallback = std::nullopt,
                double min = -std::numeric_limits<double>::infinity(),
                double max = std::numeric_limits<double>::infinity()) const;
  int Integer(const std::string& key, std::optional<int> fallback = std::nullopt,
              int min = std::numeric_limits<int>::min(),
              int max = std::numeric_limits<int>::max()) const;
  bool Bool(const std::string& key, std::optional<bool> fallback = std::nullopt) const;
  std::string String(const std::string& key,
                     std::optional<std::string> fallback = std::nullopt) const;
  // One of `choices`; the error lists them.
  std::string Choice(const std::string& key, const std::vector<std::string>& choices,
                     std::optional<std::string> fallback = std::nullopt) const;
  std::vector<double> Numbers(const std::string& key, size_t size,
                              std::optional<std::vector<double>> fallback = std::nullopt) const;

  // Unknown keys are errors, so a typo never silently becomes a default.
  void AllowOnly(std::initializer_list<const char*> keys) const;

  [[noreturn]] void Fail(const std::string& key, const std::string& problem) const;
  std::string KeyPath(const std::string& key) const;
  const std::string& file() const { return file_; }
  const nlohmann::json& value() const { return value_; }

 private:
  const nlohmann::json* Find(const std::string& key) const;

  const nlohmann::json& value_;
  std::string file_;
  std::string path_;
};

}  // namespace mirrorscan
