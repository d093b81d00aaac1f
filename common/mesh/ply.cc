#include "common/mesh/ply.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>

#include "common/mesh/mesh_io.h"

namespace mirrorscan::ply {
namespace {

bool ParseType(const std::string& name, Type* type) {
  // Both spellings of the specification (char, uchar, ...; int8, uint8, ...).
  static const std::pair<const char*, Type> kNames[] = {
      {"char", Type::kInt8},      {"int8", Type::kInt8},       {"uchar", Type::kUint8},
      {"uint8", Type::kUint8},    {"short", Type::kInt16},     {"int16", Type::kInt16},
      {"ushort", Type::kUint16},  {"uint16", Type::kUint16},   {"int", Type::kInt32},
      {"int32", Type::kInt32},    {"uint", Type::kUint32},     {"uint32", Type::kUint32},
      {"float", Type::kFloat32},  {"float32", Type::kFloat32}, {"double", Type::kFloat64},
      {"float64", Type::kFloat64}};
  for (const auto& [text, value] : kNames) {
    if (name == text) {
      *type = value;
      return true;
    }
  }
  return false;
}

size_t SizeOf(Type type) {
  switch (type) {
    case Type::kInt8:
    case Type::kUint8:
      return 1;
    case Type::kInt16:
    case Type::kUint16:
      return 2;
    case Type::kInt32:
    case Type::kUint32:
    case Type::kFloat32:
      return 4;
    case Type::kFloat64:
      return 8;
  }
  return 0;
}

template <typename T>
double Load(const char* at, bool swap) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, at, sizeof(T));
  if (swap) std::reverse(bytes, bytes + sizeof(T));
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return static_cast<double>(value);
}

double LoadBinary(Type type, const char* at, bool swap) {
  switch (type) {
    case Type::kInt8:
      return Load<int8_t>(at, swap);
    case Type::kUint8:
      return Load<uint8_t>(at, swap);
    case Type::kInt16:
      return Load<int16_t>(at, swap);
    case Type::kUint16:
      return Load<uint16_t>(at, swap);
    case Type::kInt32:
      return Load<int32_t>(at, swap);
    case Type::kUint32:
      return Load<uint32_t>(at, swap);
    case Type::kFloat32:
      return Load<float>(at, swap);
    case Type::kFloat64:
      return Load<double>(at, swap);
  }
  return 0.0;
}

// The rows of a binary file's data.
class BinaryCursor {
 public:
  BinaryCursor(const std::string& data, bool swap) : data_(data), swap_(swap) {}
  bool Next(Type type, double* value) {
    const size_t size = SizeOf(type);
    if (data_.size() - at_ < size) return false;
    *value = LoadBinary(type, data_.data() + at_, swap_);
    at_ += size;
    return true;
  }

 private:
  const std::string& data_;
  size_t at_ = 0;
  bool swap_;
};

// The whitespace-separated numbers of an ASCII file's data, parsed as written (a float
// property's text is not rounded to float).
class AsciiCursor {
 public:
  explicit AsciiCursor(const std::string& data)
      : at_(data.data()), end_(data.data() + data.size()) {}
  bool Next(Type, double* value) {
    while (at_ < end_ && std::isspace(static_cast<unsigned char>(*at_))) ++at_;
    if (at_ == end_) return false;
    if (*at_ == '+') ++at_;  // from_chars takes no leading plus
    const auto [end, error] = std::from_chars(at_, end_, *value);
    if (error != std::errc() || (end < end_ && !std::isspace(static_cast<unsigned char>(*end)))) {
      return false;
    }
    at_ = end;
    return true;
  }

 private:
  const char* at_;
  const char* end_;
};

template <typename Cursor>
void ReadAll(Cursor cursor, const std::filesystem::path& file, const std::vector<Element>& elements,
             const std::function<void(size_t, size_t, const Row&)>& row) {
  for (size_t e = 0; e < elements.size(); ++e) {
    const Element& element = elements[e];
    Row values(element.properties.size());
    for (size_t r = 0; r < element.count; ++r) {
      auto fail = [&] {
        return MeshIoError(file.string() + ": cut off or malformed in element \"" + element.name +
                           "\" (row " + std::to_string(r) + " of " + std::to_string(element.count) +
                           ")");
      };
      for (size_t p = 0; p < element.properties.size(); ++p) {
        const Property& property = element.properties[p];
        std::vector<double>& value = values[p];
        double count = 1.0;
        if (property.is_list) {
          // A length that is no whole number (a float type, a negative value) or absurdly
          // long is malformed.
          if (!cursor.Next(property.count_type, &count) || !(count >= 0.0) || count > (1 << 20) ||
              count != std::floor(count)) {
            throw fail();
          }
        }
        value.resize(static_cast<size_t>(count));
        for (double& v : value) {
          if (!cursor.Next(property.type, &v)) throw fail();
        }
      }
      row(e, r, values);
    }
  }
}

}  // namespace

int Element::Find(const std::string& property) const {
  for (size_t p = 0; p < properties.size(); ++p) {
    if (properties[p].name == property) return static_cast<int>(p);
  }
  return -1;
}

Reader::Reader(const std::filesystem::path& file) : file_(file) {
  std::error_code error;
  if (!std::filesystem::exists(file, error)) throw MeshIoError(file.string() + ": no such file");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw MeshIoError(file.string() + ": cannot read");
  std::string line;
  if (!std::getline(in, line) || (line != "ply" && line != "ply\r")) {
    throw MeshIoError(file.string() + ": not a PLY file");
  }
  bool has_format = false;
  int line_number = 1;
  auto bad = [&](const std::string& why) {
    return MeshIoError(file.string() + ": PLY header line " + std::to_string(line_number) + ": " +
                       why);
  };
  while (true) {
    if (!std::getline(in, line))
      throw MeshIoError(file.string() + ": PLY header has no end_header");
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (keyword == "end_header") break;
    if (keyword.empty() || keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "format") {
      std::string format, version;
      words >> format >> version;
      if (format == "ascii") {
        format_ = Format::kAscii;
      } else if (format == "binary_little_endian") {
        format_ = Format::kBinaryLittleEndian;
      } else if (format == "binary_big_endian") {
        format_ = Format::kBinaryBigEndian;
      } else {
        throw bad("unknown format \"" + format + "\"");
      }
      has_format = true;
    } else if (keyword == "element") {
      Element element;
      long long count = -1;
      if (!(words >> element.name >> count) || count < 0) throw bad("bad element line");
      element.count = static_cast<size_t>(count);
      elements_.push_back(element);
    } else if (keyword == "property") {
      if (elements_.empty()) throw bad("a property before any element");
      Property property;
      std::string type;
      words >> type;
      if (type == "list") {
        std::string count_type, entry_type;
        words >> count_type >> entry_type;
        property.is_list = true;
        if (!ParseType(count_type, &property.count_type) ||
            !ParseType(entry_type, &property.type)) {
          throw bad("unknown list type \"" + count_type + " " + entry_type + "\"");
        }
      } else if (!ParseType(type, &property.type)) {
        throw bad("unknown property type \"" + type + "\"");
      }
      if (!(words >> property.name)) throw bad("a property without a name");
      elements_.back().properties.push_back(property);
    } else {
      throw bad("unknown keyword \"" + keyword + "\"");
    }
  }
  if (!has_format) throw MeshIoError(file.string() + ": PLY header has no format line");
  std::ostringstream rest;
  rest << in.rdbuf();
  data_ = std::move(rest).str();
}

int Reader::Find(const std::string& element) const {
  for (size_t e = 0; e < elements_.size(); ++e) {
    if (elements_[e].name == element) return static_cast<int>(e);
  }
  return -1;
}

void Reader::ReadRows(const std::function<void(size_t, size_t, const Row&)>& row) const {
  if (format_ == Format::kAscii) {
    ReadAll(AsciiCursor(data_), file_, elements_, row);
  } else {
    const bool big = format_ == Format::kBinaryBigEndian;
    ReadAll(BinaryCursor(data_, big != (std::endian::native == std::endian::big)), file_, elements_,
            row);
  }
}

}  // namespace mirrorscan::ply
