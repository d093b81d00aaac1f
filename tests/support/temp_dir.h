#pragma once
// Scratch directories for tests.

#include <filesystem>
#include <string>

namespace mirrorscan::test_support {

// A new, empty directory /tmp/<name>.XXXXXX (mkdtemp: unique even across parallel
// processes of one test binary), removed with everything in it when this goes away.
class TempDir {
 public:
  explicit TempDir(const std::string& name);
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::filesystem::path& child) const {
    return path_ / child;
  }

 private:
  std::filesystem::path path_;
};

// An empty directory <name>_<pid> under the system's temporary directory (emptied first
// if a previous run left it), left in place afterwards for a look at what a test wrote.
std::filesystem::path FreshTempDir(const std::string& name);

}  // namespace mirrorscan::test_support
