// Where a file installed with Moreau is found at run time: the loadable modules (the raster module
// libmoreau_render_gl.so, the URDF module libmoreau_urdf.so) and the helper executable moreau-remote.
// One order everywhere: the path in an environment variable, when one is named and set; next to the
// running executable; ../lib/moreau/ from it (an installed tree: bin/ and lib/moreau/); the path in the
// build tree the file was built at.
#pragma once

#include <initializer_list>
#include <string>
#include <vector>

namespace moreau::platform {

// The candidate paths of `file_name`, in the order above. `env_var` and `build_path` may be null.
std::vector<std::string> install_candidates(const char* file_name, const char* env_var, const char* build_path);

// dlopen()s (RTLD_NOW | RTLD_LOCAL) the first candidate that exists, loads and defines every symbol of
// `symbols`; returns its handle, or null with `tried` listing each candidate and why it was passed over.
void* open_module(const std::vector<std::string>& candidates, std::initializer_list<const char*> symbols, std::string& tried);

}  // namespace moreau::platform
