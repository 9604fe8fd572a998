// Each `moreau` subcommand registers itself on the CLI11 app and sets the process exit code when it
// runs. main.cc only wires them together.
#pragma once

#include <CLI/CLI.hpp>

namespace moreau::cli {

// The exit code of the subcommand that ran: 0 success, 1 the run or request failed, 2 bad input.
int& exit_code();

void register_run_command(CLI::App& app);
void register_plot_command(CLI::App& app);
void register_study_command(CLI::App& app);
void register_stress_command(CLI::App& app);
void register_sweep_command(CLI::App& app);
// moreau submit, status, result, figure, cancel, jobs, scenes (remote_commands.cc); moreau watch
// (watch_command.cc).
void register_remote_commands(CLI::App& app);
void register_watch_command(CLI::App& app);

}  // namespace moreau::cli
