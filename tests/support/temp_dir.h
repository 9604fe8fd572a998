// A directory of a test's own under the system's temporary directory, removed with everything in it
// when the owner goes out of scope: every directory the tests make (scratch_dir() holds one too).
#pragma once

#include <stdlib.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>

namespace moreau::test_support {

// A new directory under the system's temporary directory (TMPDIR), removed with its contents when the
// TempDir goes out of scope, however the test left it (a failed assertion returns early).
class TempDir {
 public:
  TempDir() = default;  // owns nothing (yet): a place to move one into
  // Under `base`: the system's temporary directory unless a test needs another file system.
  explicit TempDir(const std::string& tag, const std::filesystem::path& base = std::filesystem::temp_directory_path()) {
    std::string pattern = (base / ("moreau-" + tag + "-XXXXXX")).string();
    if (!mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed for " + pattern);
    path_ = pattern;
  }
  TempDir(TempDir&& other) noexcept : path_(std::move(other.path_)) { other.path_.clear(); }
  TempDir& operator=(TempDir&& other) noexcept {
    if (this != &other) {
      remove();
      path_ = std::move(other.path_);
      other.path_.clear();
    }
    return *this;
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir() { remove(); }

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  void remove() {
    if (path_.empty()) return;
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
    path_.clear();
  }
  std::filesystem::path path_;
};

}  // namespace moreau::test_support
