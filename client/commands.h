// Each `moreau` subcommand registers itself on the CLI11 app, with the action that runs it once its
// options are parsed; the action returns the process exit code. main.cc runs the one that was chosen.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace moreau::cli {

// What a subcommand does, by subcommand. An action returns the exit code: 0 success, 1 the run or
// request failed, 2 bad input.
inline constexpr const char* kVersion = "moreau 0.1.0";

using Actions = std::map<const CLI::App*, std::function<int()>>;

void register_run_command(CLI::App& app, Actions& actions);
void register_plot_command(CLI::App& app, Actions& actions);
void register_study_command(CLI::App& app, Actions& actions);
void register_stress_command(CLI::App& app, Actions& actions);
void register_campaign_command(CLI::App& app, Actions& actions);
void register_inspect_command(CLI::App& app, Actions& actions);
// moreau submit, status, result, figure, cancel, jobs, scenes (remote_commands.cc); moreau watch
// (watch_command.cc).
// These two are registered by the helper moreau-remote (remote_main.cc, remote_command_list.h).
void register_remote_commands(CLI::App& app, Actions& actions);
void register_watch_command(CLI::App& app, Actions& actions);

// Parses the command line and runs the chosen subcommand's action; returns the process exit code.
// Shared by `moreau` and moreau-remote (app.cc).
int run_app(CLI::App& app, const Actions& actions, int argc, char** argv);

// On stderr, one line per parameter that the scene declares and no expression reads (likely a misspelt
// name; the report says so too): "PREFIX: warning: parameter 'x' is not read by any expression".
void warn_unread_parameters(const char* prefix, const std::vector<std::string>& names);

}  // namespace moreau::cli
