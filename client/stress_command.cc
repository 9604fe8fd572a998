// moreau stress: the documented suite of stiff and extreme cases (docs/stress.md), one line per case.
#include <iostream>

#include "commands.h"
#include "moreau/analysis/stress.h"

namespace moreau::cli {

void register_stress_command(CLI::App& app, Actions& actions) {
  auto* cmd = app.add_subcommand("stress", "Run the stiff and extreme cases and check what the theory promises");
  auto filter = std::make_shared<std::string>();
  auto verbose = std::make_shared<bool>(false);
  cmd->add_option("--case", *filter, "Run only the cases whose name contains this");
  cmd->add_flag("-v,--verbose", *verbose, "Print each case's description and the theory it relies on");
  actions[cmd] = [filter, verbose]() -> int {
    int failed = 0, ran = 0;
    for (const auto& c : scene::stress_cases()) {
      if (!filter->empty() && c.name.find(*filter) == std::string::npos) continue;
      if (*verbose) std::cout << "# " << c.name << ": " << c.what << "\n#   " << c.theory << "\n";
      const scene::StressOutcome o = scene::run_stress_case(c);
      std::cout << scene::format_outcome(o) << std::endl;
      ++ran;
      failed += !o.failures.empty();
    }
    std::cout << ran - failed << " passed, " << failed << " failed" << std::endl;
    return failed ? 1 : 0;
  };
}

}  // namespace moreau::cli
