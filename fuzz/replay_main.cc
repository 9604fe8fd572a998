// The fuzz targets' main() outside libFuzzer: runs LLVMFuzzerTestOneInput once on each input given on the
// command line (a directory: every regular file in it, in name order), as libFuzzer does with a corpus
// before it mutates anything. With it every build compiles the targets, whatever the compiler, and CTest
// replays their seed corpora (fuzz/corpus/): a trap, an abort or a crash on a seed fails the test as it
// would stop the fuzzer. Mutation needs libFuzzer (clang, -DMOREAU_FUZZ=ON, scripts/fuzz.sh).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);
extern "C" __attribute__((weak)) int LLVMFuzzerInitialize(int* argc, char*** argv);
// A target that starts threads (the HTTP target's in-process server) stops them here, after the last
// input and before main returns: stopping them from an atexit handler instead runs after the destructors
// of the function-local statics constructed since that handler was registered, while a job thread may
// still use them (a crash seen once in 135 replays of the HTTP corpus, in a report's JSON).
extern "C" __attribute__((weak)) void MoreauFuzzerTeardown();

int main(int argc, char** argv) {
  if (LLVMFuzzerInitialize) LLVMFuzzerInitialize(&argc, &argv);
  namespace fs = std::filesystem;
  std::vector<fs::path> inputs;
  for (int i = 1; i < argc; ++i) {
    std::error_code ec;
    if (fs::is_directory(argv[i], ec)) {
      std::vector<fs::path> files;
      for (const fs::directory_entry& e : fs::directory_iterator(argv[i], ec))
        if (e.is_regular_file(ec)) files.push_back(e.path());
      std::sort(files.begin(), files.end());
      inputs.insert(inputs.end(), files.begin(), files.end());
    } else {
      inputs.emplace_back(argv[i]);
    }
  }
  for (const fs::path& path : inputs) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
      std::fprintf(stderr, "cannot read %s\n", path.c_str());
      return 1;
    }
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::fprintf(stderr, "%s (%zu bytes)\n", path.c_str(), bytes.size());
    LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  }
  if (MoreauFuzzerTeardown) MoreauFuzzerTeardown();
  std::printf("replayed %zu inputs\n", inputs.size());
  return inputs.empty() ? 1 : 0;  // an empty corpus replays nothing: a misconfigured test, not a pass
}
