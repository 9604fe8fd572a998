#include <exception>
#include <iostream>

#include "commands.h"

namespace moreau::cli {

int run_app(CLI::App& app, const Actions& actions, int argc, char** argv) {
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

}  // namespace moreau::cli
