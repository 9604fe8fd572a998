// moreau: run scenes locally, draw figures, talk to a Moreau server.
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <iostream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "commands.h"
#ifdef MOREAU_HAVE_REMOTE_COMMANDS
#include "moreau/platform/install_paths.h"
#include "remote_command_list.h"
#endif

namespace {

#ifdef MOREAU_HAVE_REMOTE_COMMANDS
// Replaces this process with moreau-remote (found as install_paths.h says), given the same arguments;
// returns only if none could run.
int exec_remote_helper(int argc, char** argv) {
  std::vector<char*> args(argv, argv + argc);
  args.push_back(nullptr);
  std::string tried;
  for (const std::string& path : moreau::platform::install_candidates("moreau-remote", nullptr, MOREAU_REMOTE_BUILD_PATH)) {
    ::execv(path.c_str(), args.data());
    tried += "\n  " + path + ": " + std::strerror(errno);
  }
  std::cerr << "moreau: the server and LCM commands are in the helper moreau-remote, which could not be run:" << tried << "\n";
  return 1;
}

// Each remote command appears in `moreau --help`, and takes its command line as it is when CLI11 chooses
// it: the helper parses it (its own --help included).
void register_remote_command_stubs(CLI::App& app, moreau::cli::Actions& actions, int argc, char** argv) {
  for (const moreau::cli::RemoteCommand& c : moreau::cli::kRemoteCommands) {
    auto* cmd = app.add_subcommand(std::string(c.name), std::string(c.description));
    cmd->set_help_flag();
    cmd->prefix_command();
    actions[cmd] = [argc, argv] { return exec_remote_helper(argc, argv); };
  }
}
#endif

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Moreau: simulation of nonsmooth dynamical systems (set-valued controllers, friction, impacts)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", moreau::cli::kVersion);
  moreau::cli::Actions actions;
  using Register = void (*)(CLI::App&, moreau::cli::Actions&);
  constexpr std::pair<std::string_view, Register> kLocalCommands[] = {
      {"run", moreau::cli::register_run_command},         {"plot", moreau::cli::register_plot_command},
      {"study", moreau::cli::register_study_command},     {"stress", moreau::cli::register_stress_command},
      {"inspect", moreau::cli::register_inspect_command}, {"campaign", moreau::cli::register_campaign_command}};
  // Only the command named first is registered when there is one: building every command's options is a
  // visible share of a short run's start-up (README, "Performance"). --help, --version, a mistyped name:
  // all of them, so that help and errors list every command.
  const std::string_view first = argc > 1 ? argv[1] : "";
  for (const auto& [name, add] : kLocalCommands)
    if (name == first) {
      add(app, actions);
      return moreau::cli::run_app(app, actions, argc, argv);
    }
#ifdef MOREAU_HAVE_REMOTE_COMMANDS
  for (const moreau::cli::RemoteCommand& c : moreau::cli::kRemoteCommands)
    if (c.name == first) return exec_remote_helper(argc, argv);
#endif
  for (const auto& [name, add] : kLocalCommands) add(app, actions);
#ifdef MOREAU_HAVE_REMOTE_COMMANDS
  register_remote_command_stubs(app, actions, argc, argv);
#endif
  return moreau::cli::run_app(app, actions, argc, argv);
}
