// A directory of this test process's own, for the files a test writes. CTest runs tests as separate
// processes, several at once (-j), so two tests that wrote to the same fixed name under /tmp could
// remove or overwrite each other's files; under scratch_dir() they never share one. Made on first use
// under the system's temporary directory, removed with its contents when the process exits.
#pragma once

#include <string>

#include "temp_dir.h"  // beside this file

namespace moreau::test_support {

inline const std::string& scratch_dir() {
  static const TempDir dir("test");
  static const std::string path = dir.path().string();
  return path;
}

}  // namespace moreau::test_support
