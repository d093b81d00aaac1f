#include "common/config/json_reader.h"

#include <cmath>
#include <fstream>
#include <sstream>

namespace mirrorscan {

JsonReader::JsonReader(const nlohmann::json& value, std::string file, std::string path)
    : value_(value), file_(std::move(file)), path_(std::move(path)) {
  if (!value_.is_object()) {
    throw ConfigError(file_ + ": " + (path_.empty() ? std::string("top level") : path_) +
                      ": expected an object");
  }
}

nlohmann::json JsonReader::ParseFile(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ConfigError(file.string() + ": cannot open file");
  std::stringstream text;
  text << in.rdbuf();
  return ParseText(text.str(), file.string());
}

nlohmann::json JsonReader::ParseText(const std::string& text, const std::string& file) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw ConfigError(file + ": not valid JSON at byte " + std::to_string(e.byte));
  } catch (const nlohmann::json::exception&) {
    // A number beyond double's range is out_of_range, not a parse_error.
    throw ConfigError(file + ": not valid JSON (a number out of range)");
  }
}

std::string JsonReader::KeyPath(const std::string& key) const {
  if (path_.empty()) return key;
  if (!key.empty() && key[0] == '[') return path_ + key;
  return path_ + "." + key;
}

void JsonReader::Fail(const std::string& key, const std::string& problem) const {
  throw ConfigError(file_ + ": " + KeyPath(key) + ": " + problem);
}

const nlohmann::json* JsonReader::Find(const std::string& key) const {
  const auto it = value_.find(key);
  if (it == value_.end() || it->is_null()) return nullptr;
  return &*it;
}

bool JsonReader::Has(const std::string& key) const { return Find(key) != nullptr; }

JsonReader JsonReader::Object(const std::string& key) const {
  const nlohmann::json* v = Find(key);
  if (!v) Fail(key, "missing");
  if (!v->is_object()) Fail(key, "expected an object");
  return JsonReader(*v, file_, KeyPath(key));
}

std::vector<JsonReader> JsonReader::Objects(const std::string& key) const {
  const nlohmann::json* v = Find(key);
  if (!v) Fail(key, "missing");
  if (!v->is_array()) Fail(key, "expected an array of objects");
  std::vector<JsonReader> result;
  for (size_t i = 0; i < v->size(); ++i) {
    const std::string item = KeyPath(key) + "[" + std::to_string(i) + "]";
    if (!(*v)[i].is_object()) throw ConfigError(file_ + ": " + item + ": expected an object");
    result.emplace_back((*v)[i], file_, item);
  }
  return result;
}

double JsonReader::Number(const std::string& key, std::optional<double> fallback, double min,
                          double max) const {
  const nlohmann::json* v = Find(key);
  if (!v) {
    if (fallback) return *fallback;
    Fail(key, "missing (expected a number)");
  }
  if (!v->is_number()) Fail(key, "expected a number");
  const double x = v->get<double>();
  if (!std::isfinite(x)) Fail(key, "must be finite");
  if (x < min || x > max) {
    std::ostringstream range;
    range << "must be in [" << min << ", " << max << "], got " << x;
    Fail(key, range.str());
  }
  return x;
}

int JsonReader::Integer(const std::string& key, std::optional<int> fallback, int min,
                        int max) const {
  const nlohmann::json* v = Find(key);
  if (!v) {
    if (fallback) return *fallback;
    Fail(key, "missing (expected an integer)");
  }
  if (!v->is_number_integer()) Fail(key, "expected an integer");
  const auto x = v->get<long long>();
  if (x < min || x > max) {
    Fail(key, "must be in [" + std::to_string(min) + ", " + std::to_string(max) + "], got " +
                  std::to_string(x));
  }
  return static_cast<int>(x);
}

bool JsonReader::Bool(const std::string& key, std::optional<bool> fallback) const {
  const nlohmann::json* v = Find(key);
  if (!v) {
    if (fallback) return *fallback;
    Fail(key, "missing (expected true or false)");
  }
  if (!v->is_boolean()) Fail(key, "expected true or false");
  return v->get<bool>();
}

std::string JsonReader::String(const std::string& key, std::optional<std::string> fallback) const {
  const nlohmann::json* v = Find(key);
  if (!v) {
    if (fallback) return *fallback;
    Fail(key, "missing (expected a string)");
  }
  if (!v->is_string()) Fail(key, "expected a string");
  return v->get<std::string>();
}

std::string JsonReader::Choice(const std::string& key, const std::vector<std::string>& choices,
                               std::optional<std::string> fallback) const {
  const std::string s = String(key, fallback);
  for (const auto& c : choices)
    if (c == s) return s;
  std::string list;
  for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
  Fail(key, "\"" + s + "\" is not one of: " + list);
}

std::vector<double> JsonReader::Numbers(const std::string& key, size_t size,
                                        std::optional<std::vector<double>> fallback) const {
  const nlohmann::json* v = Find(key);
  if (!v) {
    if (fallback) return *fallback;
    Fail(key, "missing (expected " + std::to_string(size) + " numbers)");
  }
  if (!v->is_array() || v->size() != size) {
    Fail(key, "expected an array of " + std::to_string(size) + " numbers");
  }
  std::vector<double> result;
  for (const auto& x : *v) {
    if (!x.is_number() || !std::isfinite(x.get<double>())) {
      Fail(key, "expected an array of " + std::to_string(size) + " finite numbers");
    }
    result.push_back(x.get<double>());
  }
  return result;
}

void JsonReader::AllowOnly(std::initializer_list<const char*> keys) const {
  for (const auto& item : value_.items()) {
    bool known = false;
    for (const char* k : keys) known = known || item.key() == k;
    if (!known) {
      std::string list;
      for (const char* k : keys) list += (list.empty() ? "" : ", ") + std::string(k);
      Fail(item.key(), "unknown key (expected one of: " + list + ")");
    }
  }
}

}  // namespace mirrorscan
