// A directory of this test process's own, for the files a test writes. CTest runs tests as separate
// processes, several at once (-j), so two tests that wrote to the same fixed name under /tmp could
// remove or overwrite each other's files; under scratch_dir() they never share one. Made on first use
// under the system's temporary directory, removed with its contents when the process exits.
#pragma once

#include <stdlib.h>

#include <filesystem>
#include <stdexcept>
#include <string>

namespace moreau::test_support {

inline const std::string& scratch_dir() {
  struct Dir {
    std::string path;
    Dir() {
      std::string pattern = (std::filesystem::temp_directory_path() / "moreau-test-XXXXXX").string();
      if (!mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed for " + pattern);
      path = pattern;
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Dir dir;
  return dir.path;
}

}  // namespace moreau::test_support
