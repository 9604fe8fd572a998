// moreau-remote: the commands of `moreau` that talk to a moreau-server or to LCM (remote_command_list.h).
// `moreau submit ...` runs this with the same command line; it can be run directly too.
#include "commands.h"

int main(int argc, char** argv) {
  CLI::App app{"Moreau: jobs on a moreau-server, and live state over LCM"};
  app.require_subcommand(1);
  app.set_version_flag("--version", moreau::cli::kVersion);
  moreau::cli::Actions actions;
  moreau::cli::register_remote_commands(app, actions);
  moreau::cli::register_watch_command(app, actions);
  return moreau::cli::run_app(app, actions, argc, argv);
}
