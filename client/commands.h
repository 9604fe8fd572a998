// Each `moreau` subcommand registers itself on the CLI11 app, with the action that runs it once its
// options are parsed; the action returns the process exit code. main.cc runs the one that was chosen.
#pragma once

#include <functional>
#include <map>

#include <CLI/CLI.hpp>

namespace moreau::cli {

// What a subcommand does, by subcommand. An action returns the exit code: 0 success, 1 the run or
// request failed, 2 bad input.
using Actions = std::map<const CLI::App*, std::function<int()>>;

void register_run_command(CLI::App& app, Actions& actions);
void register_plot_command(CLI::App& app, Actions& actions);
void register_study_command(CLI::App& app, Actions& actions);
void register_stress_command(CLI::App& app, Actions& actions);
void register_sweep_command(CLI::App& app, Actions& actions);
// moreau submit, status, result, figure, cancel, jobs, scenes (remote_commands.cc); moreau watch
// (watch_command.cc).
void register_remote_commands(CLI::App& app, Actions& actions);
void register_watch_command(CLI::App& app, Actions& actions);

}  // namespace moreau::cli
