#pragma once
// PLY files (Greg Turk's polygon format): the header's elements and properties, and the
// rows of an ASCII or binary (either byte order) file. mesh_io and cloud_io read their
// PLY files through it.
#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace mirrorscan::ply {

enum class Type { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

struct Property {
  std::string name;
  Type type = Type::kFloat32;  // of a list: its entries
  bool is_list = false;
  Type count_type = Type::kUint8;  // of a list: its length
};

struct Element {
  std::string name;
  size_t count = 0;
  std::vector<Property> properties;
  // The index of the property with this name, or -1.
  int Find(const std::string& property) const;
};

enum class Format { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

// One row of an element: values[p] holds property p's value (a scalar: one entry; a list:
// its entries), converted to double (exact for every PLY type).
using Row = std::vector<std::vector<double>>;

// A PLY file read whole into memory. Every error is a MeshIoError (common/mesh/mesh_io.h)
// whose message starts with the file name.
class Reader {
 public:
  explicit Reader(const std::filesystem::path& file);

  Format format() const { return format_; }
  const std::vector<Element>& elements() const { return elements_; }
  // The index of the element with this name, or -1.
  int Find(const std::string& element) const;
  // Every row of every element in file order: row(element index, row index, values).
  void ReadRows(const std::function<void(size_t, size_t, const Row&)>& row) const;

 private:
  std::filesystem::path file_;
  Format format_ = Format::kAscii;
  std::vector<Element> elements_;
  std::string data_;  // everything after end_header
};

}  // namespace mirrorscan::ply
