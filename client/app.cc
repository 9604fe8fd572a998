#include <exception>
#include <iostream>

#include "commands.h"
#include "terminal_text.h"

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

void warn_unread_parameters(const char* prefix, const std::vector<std::string>& names) {
  for (const std::string& p : names)
    std::cerr << prefix << ": warning: parameter '" << terminal_safe(p) << "' is not read by any expression of the scene\n";
}

}  // namespace moreau::cli
