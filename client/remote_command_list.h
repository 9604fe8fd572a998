// The commands that talk to a moreau-server (HTTP) or to LCM. They live in a helper executable,
// moreau-remote (remote_main.cc), so that `moreau run` and the other local commands never load the
// HTTP, TLS and LCM libraries: a process maps only what its command uses (docs/architecture.md).
// `moreau` lists them in its help and hands their command lines to the helper (main.cc).
#pragma once

#include <string_view>

namespace moreau::cli {

struct RemoteCommand {
  std::string_view name;
  std::string_view description;
};

inline constexpr RemoteCommand kRemoteCommands[] = {
    {"submit", "Submit a scene to a moreau-server; prints the job id"},
    {"status", "Show a job's state, progress and report"},
    {"result", "Print a finished job's report, or save its trajectory with --out"},
    {"figure", "Save a figure of a finished job (PNG, or SVG for a .svg file, drawn by the server)"},
    {"cancel", "Cancel a queued or running job"},
    {"jobs", "List the server's jobs"},
    {"scenes", "List the scenes a server ships"},
    {"watch", "Show the live state of streaming jobs (LCM)"},
};

// The description of a remote command by name (the helper registers the commands with these).
constexpr std::string_view remote_command_description(std::string_view name) {
  for (const RemoteCommand& c : kRemoteCommands)
    if (c.name == name) return c.description;
  return {};
}

}  // namespace moreau::cli
