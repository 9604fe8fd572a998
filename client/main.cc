// moreau: run scenes locally, draw figures, talk to a Moreau server.
#include <exception>
#include <iostream>

#include "commands.h"

int main(int argc, char** argv) {
  CLI::App app{"Moreau: simulation of nonsmooth dynamical systems (set-valued controllers, friction, impacts)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "moreau 0.1.0");
  moreau::cli::Actions actions;
  moreau::cli::register_run_command(app, actions);
  moreau::cli::register_plot_command(app, actions);
  moreau::cli::register_study_command(app, actions);
  moreau::cli::register_stress_command(app, actions);
  moreau::cli::register_sweep_command(app, actions);
#ifdef MOREAU_HAVE_REMOTE_COMMANDS
  moreau::cli::register_remote_commands(app, actions);
  moreau::cli::register_watch_command(app, actions);
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    return actions.at(app.get_subcommands().at(0))();
  } catch (const std::exception& e) {
    // Subcommands report bad input themselves (exit status 2); anything else that escapes them is a
    // failure to report, not a reason to abort.
    std::cerr << "moreau: " << e.what() << "\n";
    return 1;
  }
}
