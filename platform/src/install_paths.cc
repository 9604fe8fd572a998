#include "moreau/platform/install_paths.h"

#include <dlfcn.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>

namespace moreau::platform {

std::vector<std::string> install_candidates(const char* file_name, const char* env_var, const char* build_path) {
  std::vector<std::string> out;
  if (env_var)
    if (const char* env = std::getenv(env_var); env && *env) out.emplace_back(env);
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    out.push_back((exe.parent_path() / file_name).string());
    out.push_back((exe.parent_path().parent_path() / "lib" / "moreau" / file_name).string());
  }
  if (build_path) out.emplace_back(build_path);
  return out;
}

void* open_module(const std::vector<std::string>& candidates, std::initializer_list<const char*> symbols, std::string& tried) {
  for (const std::string& path : candidates) {
    if (::access(path.c_str(), R_OK) != 0) {
      tried += "\n  " + path + " (not found)";
      continue;
    }
    // RTLD_LOCAL: a module's own copies of shared code stay its own.
    void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      tried += "\n  " + path + ": " + ::dlerror();
      continue;
    }
    bool complete = true;
    for (const char* symbol : symbols) complete = complete && ::dlsym(handle, symbol) != nullptr;
    if (complete) return handle;
    tried += "\n  " + path + ": not the module of this build (an entry point is missing)";
    ::dlclose(handle);
  }
  return nullptr;
}

}  // namespace moreau::platform
