// moreau campaign SPEC --out DIR [-j N] [--range BEGIN:END] : runs a robustness campaign (or its share);
// moreau campaign --scene SCENE --vary PATH=VALUES... [--set PATH=VALUE]... --out DIR : a parameter sweep,
//   which is the grid campaign over the --vary lists (written as DIR/campaign.json, then run as any spec);
// moreau campaign --collect DIR : checks that every sample is present once and writes the summary.
// The spec, the files and the statistics: analysis/include/moreau/analysis/campaign.h and docs/campaigns.md.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <string_view>
#include <tuple>
#include <optional>
#include <cctype>
#include <vector>
#include <chrono>
#include <csignal>
#include <fstream>
#include <cstdio>
#include <iostream>
#include <memory>
#include <mutex>
#include <thread>

#include "commands.h"
#include "moreau/render/render.h"
#include "moreau/analysis/campaign.h"
#include "moreau/analysis/campaign_figures.h"
#include "moreau/scene/simulation.h"
#include "moreau/scene/scene.h"

namespace moreau::cli {
namespace {

namespace fs = std::filesystem;

std::atomic<bool> g_stop{false};
extern "C" void on_interrupt(int) { g_stop.store(true); }

struct CampaignOptions {
  std::string spec_path, out_dir, collect_dir, range, task;
  // A sweep: the scene, its --vary lists and --set overrides (in place of SPEC).
  std::string scene_path;
  std::vector<std::string> vary, overrides;
  int jobs = 0;
  bool quiet = false;
  // --slurm: a job array of `tasks` tasks and a dependent collect job, with sbatch's own options passed on.
  bool slurm = false;
  int tasks = 16;
  int cpus_per_task = 1;
  std::string account, partition, time_limit;
};

// K/T: task K of T.
std::pair<std::int64_t, std::int64_t> parse_task(const std::string& text) {
  long long k = -1, t = 0;
  char slash = 0;
  std::istringstream in(text);
  if (!(in >> k >> slash >> t) || slash != '/' || t < 1 || k < 0 || k >= t || !in.eof())
    throw std::runtime_error("--task must be K/T with 0 <= K < T, got '" + text + "'");
  return {k, t};
}

// The worker threads: -j, else Slurm's allocation (SLURM_CPUS_PER_TASK), else every core.
int worker_count(int jobs) {
  if (jobs > 0) return jobs;
  if (const char* slurm = std::getenv("SLURM_CPUS_PER_TASK")) {
    const int n = std::atoi(slurm);
    if (n > 0) return n;
  }
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

// 'text' for a bash script.
std::string shell_quote(const std::string& text) {
  std::string q = "'";
  for (char c : text) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// A word of an #SBATCH line. sbatch reads those lines with rules of its own (Slurm's _get_argument):
// whitespace ends a word unless quoted ("..." or '...'), a backslash takes the next character as it is
// (but does not keep a space), an unquoted '#' ends the line, and a line holding "hetjob" or "packjob"
// anywhere separates the components of a heterogeneous job. A word of other characters than
// [A-Za-z0-9/._%=:,+@-] is written in double quotes, its '"' and '\' escaped; nullopt for a word that
// cannot be written (a control character, or one of those two words): the option then goes on sbatch's
// command line alone. The command line has every option anyway, and overrides the script's.
std::optional<std::string> sbatch_word(const std::string& text) {
  std::string lower;
  bool plain = true;
  for (const char c : text) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f) return std::nullopt;
    lower += static_cast<char>(std::tolower(u));
    plain = plain && ((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                      std::string_view("/._%=:,+@-").find(c) != std::string_view::npos);
  }
  if (lower.find("hetjob") != std::string::npos || lower.find("packjob") != std::string::npos) return std::nullopt;
  if (plain) return text;
  std::string w = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') w += '\\';
    w += c;
  }
  return w + "\"";
}

// A path as a literal part of Slurm's --output file name pattern, where '%' starts a replacement
// symbol (%A, %a, %j): '%%' is a '%'.
std::string slurm_pattern_literal(const std::string& path) {
  std::string out;
  for (const char c : path) out += c == '%' ? std::string("%%") : std::string(1, c);
  return out;
}

// --out for a Slurm campaign: any path a file system takes, but for control characters (a newline would
// end a line of the batch script) and backslashes (in an --output file name a backslash turns off
// Slurm's replacement symbols, so every task would write one log). Everything else is quoted.
void check_slurm_path(const std::string& path) {
  for (const char c : path) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7f)
      throw std::runtime_error(
          "--out: the directory's path holds a control character (a newline, a tab, ...), which a Slurm batch "
          "script cannot carry: use another directory");
    if (c == '\\')
      throw std::runtime_error(
          "--out: the directory's path holds a backslash, which turns off Slurm's file name patterns "
          "(%A, %a, %j) of the task logs: use another directory");
  }
}

// --account, --partition, --time: passed to sbatch as they are, so held to the characters Slurm's
// names and times use.
void check_sbatch_value(const char* option, const std::string& value) {
  if (value.empty()) return;
  const bool ok = value.size() <= 128 && std::all_of(value.begin(), value.end(), [](char c) {
                    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                           std::string_view("._,:+@-").find(c) != std::string_view::npos;
                  });
  if (!ok)
    throw std::runtime_error(std::string(option) +
                             " must be 1 to 128 of the letters, digits and . _ , : + @ - (a Slurm name or time), got '" +
                             value.substr(0, 64) + "'");
}

// The job id `sbatch --parsable` prints (ID or ID;CLUSTER): digits, or an error.
std::string job_id_of(const std::string& out, const char* what) {
  const std::string id = out.substr(0, out.find_first_of(";\n"));
  if (id.empty() || id.size() > 20 || !std::all_of(id.begin(), id.end(), [](char c) { return c >= '0' && c <= '9'; }))
    throw std::runtime_error(std::string("sbatch printed no job id for ") + what + " (got '" + out.substr(0, 80) + "')");
  return id;
}

// Runs argv (no shell) and returns its exit status and standard output.
std::pair<int, std::string> run_capture(const std::vector<std::string>& argv) {
  int fds[2];
  if (pipe(fds) != 0) throw std::runtime_error("pipe failed");
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    dup2(fds[1], 1);
    close(fds[0]);
    close(fds[1]);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execvp(args[0], args.data());
    std::fprintf(stderr, "moreau campaign: cannot run %s: %s\n", argv[0].c_str(), std::strerror(errno));
    _exit(127);
  }
  close(fds[1]);
  std::string out;
  char buf[4096];
  for (ssize_t n; (n = read(fds[0], buf, sizeof buf)) > 0;) out.append(buf, static_cast<std::size_t>(n));
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

// --slurm: writes DIR/campaign.json, the array's batch script, and submits the tasks whose blocks miss
// samples (all of them the first time) and a collect job that runs once they all succeeded.
int submit_to_slurm(const CampaignOptions& opt) {
  const scene::CampaignSpec spec = scene::CampaignSpec::from_file(opt.spec_path);
  warn_unread_parameters("moreau campaign", spec.unread_parameters);
  if (opt.tasks < 1 || opt.tasks > 100000) throw std::runtime_error("--tasks must be in [1, 100000]");
  if (opt.cpus_per_task < 1) throw std::runtime_error("--cpus-per-task must be at least 1");
  const std::int64_t tasks = std::min<std::int64_t>(opt.tasks, spec.samples);
  const fs::path dir = fs::absolute(opt.out_dir);
  // What reaches the batch script and sbatch's command line: the name is one of the spec's safe set
  // (the spec reader refuses others at /name), the paths are checked and quoted, sbatch's own options
  // are checked. Nothing is written or submitted before.
  if (!scene::is_campaign_name(spec.name)) throw std::runtime_error("/name: not a campaign name");
  check_slurm_path(dir.string());
  check_sbatch_value("--account", opt.account);
  check_sbatch_value("--partition", opt.partition);
  check_sbatch_value("--time", opt.time_limit);
  // The directory is claimed now (a different campaign there is refused before anything is submitted).
  scene::claim_campaign_directory(spec, dir.string());
  const std::vector<std::int64_t> missing = scene::missing_per_task(dir.string(), spec, tasks);
  std::string array;
  std::int64_t to_run = 0, samples_missing = 0;
  for (std::int64_t k = 0; k < tasks; ++k) {
    if (missing[static_cast<std::size_t>(k)] == 0) continue;
    array += (array.empty() ? "" : ",") + std::to_string(k);
    ++to_run;
    samples_missing += missing[static_cast<std::size_t>(k)];
  }
  const std::string moreau = fs::read_symlink("/proc/self/exe").string();
  fs::create_directories(dir / "slurm");
  const fs::path script = dir / "slurm" / "campaign.sbatch";
  // The array's options: on sbatch's command line (an argument each, no shell between), and the same in
  // the script's #SBATCH lines, escaped for sbatch's reader, for a resubmission by hand.
  const std::vector<std::string> array_options = {"--job-name=moreau-" + spec.name,
                                                  "--output=" + slurm_pattern_literal((dir / "slurm").string()) + "/task-%A_%a.out",
                                                  "--cpus-per-task=" + std::to_string(opt.cpus_per_task), "--requeue"};
  {
    std::ofstream out(script, std::ios::trunc);
    out << "#!/bin/bash\n"
        << "# Written by moreau campaign --slurm: task K of the array runs block K of " << tasks << " (docs/campaigns.md).\n";
    for (const std::string& o : array_options) {
      if (const auto word = sbatch_word(o))
        out << "#SBATCH " << *word << "\n";
      else
        out << "# " << o.substr(0, o.find('=')) << " is on sbatch's command line (sbatch cannot read its value in this script)\n";
    }
    out << "set -euo pipefail\n"
        << "exec " << shell_quote(moreau) << " campaign " << shell_quote((dir / "campaign.json").string()) << " --out "
        << shell_quote(dir.string()) << " --task \"${SLURM_ARRAY_TASK_ID}/" << tasks << "\" --quiet\n";
    if (!out) throw std::runtime_error("cannot write '" + script.string() + "'");
  }
  std::vector<std::string> common;
  if (!opt.account.empty()) common.push_back("--account=" + opt.account);
  if (!opt.partition.empty()) common.push_back("--partition=" + opt.partition);
  if (!opt.time_limit.empty()) common.push_back("--time=" + opt.time_limit);
  std::string array_job;
  if (to_run > 0) {
    std::vector<std::string> argv = {"sbatch", "--parsable", "--array=" + array};
    argv.insert(argv.end(), array_options.begin(), array_options.end());
    argv.insert(argv.end(), common.begin(), common.end());
    argv.push_back(script.string());
    const auto [rc, out] = run_capture(argv);
    if (rc != 0) throw std::runtime_error("sbatch failed (exit " + std::to_string(rc) + ") for the job array");
    array_job = job_id_of(out, "the job array");
  }
  std::vector<std::string> argv = {"sbatch", "--parsable", "--job-name=moreau-" + spec.name + "-collect",
                                   "--output=" + slurm_pattern_literal((dir / "slurm").string()) + "/collect-%j.out"};
  if (!array_job.empty()) argv.push_back("--dependency=afterok:" + array_job);
  argv.insert(argv.end(), common.begin(), common.end());
  argv.push_back("--wrap=exec " + shell_quote(moreau) + " campaign --collect " + shell_quote(dir.string()));
  const auto [rc, out] = run_capture(argv);
  if (rc != 0) throw std::runtime_error("sbatch failed (exit " + std::to_string(rc) + ") for the collect job");
  const std::string collect_job = job_id_of(out, "the collect job");
  if (to_run > 0)
    std::printf("moreau campaign: submitted job array %s: %lld of %lld tasks (%lld samples missing of %lld), and collect job %s after it\n",
                array_job.c_str(), static_cast<long long>(to_run), static_cast<long long>(tasks), static_cast<long long>(samples_missing),
                static_cast<long long>(spec.samples), collect_job.c_str());
  else
    std::printf("moreau campaign: every sample is present; submitted collect job %s\n", collect_job.c_str());
  std::printf("moreau campaign: results in %s (task logs in %s); run the same command again to resubmit only missing samples\n",
              dir.string().c_str(), (dir / "slurm").string().c_str());
  return 0;
}

// The campaign's figures (write_campaign_figures), their paths on stderr.
void write_figures(const std::string& dir) {
  for (const std::string& path : scene::write_campaign_figures(dir)) std::fprintf(stderr, "moreau campaign: figure %s\n", path.c_str());
}

// One --vary list as a grid input's distribution: FIRST:LAST:COUNT (COUNT evenly spaced numbers, the
// grid's own {low, high, count}), or v1,v2,... (each a JSON value, else a string; separated by ';'
// instead when a value holds commas, as arrays do: [0,1];[1,0]).
nlohmann::json grid_distribution(const std::string& vary) {
  const std::size_t eq = vary.find('=');
  if (eq == std::string::npos || eq == 0) throw std::runtime_error("--vary '" + vary + "' is not PATH=VALUES");
  const std::string path = vary.substr(0, eq), list = vary.substr(eq + 1);
  auto number = [&](const std::string& text) {
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || end != text.c_str() + text.size()) throw std::runtime_error("--vary " + path + ": '" + text + "' is not a number");
    if (!std::isfinite(v)) throw std::runtime_error("--vary " + path + ": '" + text + "' is not a finite number");
    return v;
  };
  const char sep = list.find(';') != std::string::npos ? ';' : ',';
  if (sep == ',' && std::count(list.begin(), list.end(), ':') == 2 && list.find('[') == std::string::npos) {
    std::stringstream ss(list);
    std::string a, b, c;
    std::getline(ss, a, ':');
    std::getline(ss, b, ':');
    std::getline(ss, c, ':');
    const double low = number(a), high = number(b);
    char* end = nullptr;
    const long count = std::strtol(c.c_str(), &end, 10);
    if (c.empty() || *end != '\0' || count < 1 || count > 1'000'000)
      throw std::runtime_error("--vary " + path + ": COUNT must be a whole number in [1, 1000000], got '" + c + "'");
    if (count == 1) return {{"type", "grid"}, {"values", {low}}};
    return {{"type", "grid"}, {"low", low}, {"high", high}, {"count", count}};
  }
  nlohmann::json values = nlohmann::json::array();
  std::stringstream ss(list);
  for (std::string item; std::getline(ss, item, sep);) {
    if (item.empty()) continue;
    nlohmann::json v = nlohmann::json::parse(item, nullptr, false);
    if (v.is_discarded()) {
      // Not JSON: a number that overflows, or a string (an expression, a name).
      char* end = nullptr;
      std::strtod(item.c_str(), &end);
      if (end == item.c_str() + item.size()) number(item);
      v = item;
    }
    values.push_back(std::move(v));
  }
  if (values.empty()) throw std::runtime_error("--vary " + path + ": no values");
  return {{"type", "grid"}, {"values", std::move(values)}};
}

// A sweep's spec: the grid campaign over the --vary lists, its scene read from --scene with --set applied
// and inlined, written into the output directory (claimed there: another campaign is refused). Returns
// the path of that campaign.json, which the run then reads as any spec.
std::string write_grid_spec(const CampaignOptions& opt) {
  if (opt.vary.empty()) throw std::runtime_error("--scene needs at least one --vary PATH=VALUES");
  nlohmann::json scene = scene::read_scene_file(opt.scene_path);
  for (const std::string& o : opt.overrides) scene::apply_override(scene, o);
  // The name: the scene file's, held to the names a spec takes (other characters become '_').
  std::string stem = fs::path(opt.scene_path).stem().string().substr(0, scene::kMaxCampaignNameLength - 6);
  for (char& c : stem)
    if (!scene::is_campaign_name(std::string(1, c))) c = '_';
  nlohmann::json doc = {{"name", (stem.empty() ? std::string("scene") : stem) + "-sweep"},
                        {"description", "a parameter sweep of " + opt.scene_path + ": the grid over the --vary lists"},
                        {"scene", std::move(scene)},
                        {"inputs", nlohmann::json::array()},
                        {"sampler", "grid"}};
  for (const std::string& v : opt.vary)
    doc["inputs"].push_back({{"path", v.substr(0, v.find('='))}, {"distribution", grid_distribution(v)}});
  scene::CampaignSpec spec;
  try {
    spec = scene::CampaignSpec::from_json(doc, fs::path(opt.scene_path).parent_path().string());
  } catch (const scene::SceneError& e) {
    // Pointers into the spec this command wrote name what the user gave instead: a --vary, or the scene.
    const std::string& p = e.pointer();
    if (p.rfind("/inputs/", 0) == 0) {
      const std::size_t k = std::stoul(p.substr(8));
      throw std::runtime_error("--vary " + opt.vary[k] + ": " + e.reason());
    }
    if (p == "/inputs" || p == "/samples") throw std::runtime_error("--vary: " + e.reason());
    if (p.rfind("/scene", 0) == 0) throw scene::SceneError(p.size() > 6 ? p.substr(6) : "/", e.reason());
    throw;
  }
  scene::claim_campaign_directory(spec, opt.out_dir);
  return (fs::path(opt.out_dir) / "campaign.json").string();
}

// BEGIN:END (END exclusive; either may be left out).
std::pair<std::int64_t, std::int64_t> parse_range(const std::string& text, std::int64_t samples) {
  if (text.empty()) return {0, samples};
  const auto colon = text.find(':');
  auto number = [&](const std::string& s, std::int64_t fallback) -> std::int64_t {
    if (s.empty()) return fallback;
    std::size_t used = 0;
    long long v = 0;
    try {
      v = std::stoll(s, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != s.size() || v < 0) throw std::runtime_error("--range must be BEGIN:END with whole numbers >= 0, got '" + text + "'");
    return v;
  };
  if (colon == std::string::npos) throw std::runtime_error("--range must be BEGIN:END, got '" + text + "'");
  const std::int64_t b = number(text.substr(0, colon), 0), e = number(text.substr(colon + 1), samples);
  if (b > e || e > samples)
    throw std::runtime_error("--range " + text + " is not within the campaign's " + std::to_string(samples) + " samples");
  return {b, e};
}

int run(const CampaignOptions& opt) {
  const scene::CampaignSpec spec = scene::CampaignSpec::from_file(opt.spec_path);
  warn_unread_parameters("moreau campaign", spec.unread_parameters);
  if (!opt.range.empty() && !opt.task.empty()) throw std::runtime_error("--range and --task exclude each other");
  std::int64_t begin = 0, end = spec.samples;
  if (!opt.task.empty()) {
    const auto [k, t] = parse_task(opt.task);
    std::tie(begin, end) = scene::task_range(spec.samples, k, t);
  } else {
    std::tie(begin, end) = parse_range(opt.range, spec.samples);
  }
  scene::CampaignRunOptions run;
  run.begin = begin;
  run.end = end;
  // A share of the samples (--task, --range) writes its own part file, so that shares may run at once
  // into one directory; --collect then writes the summary.
  run.part = !opt.task.empty() || !opt.range.empty();
  run.workers = worker_count(opt.jobs);
  run.stop = &g_stop;
  const bool tty = !opt.quiet && isatty(STDERR_FILENO);
  const auto start = std::chrono::steady_clock::now();
  double last_draw = -1.0;
  std::int64_t first_done = -1;
  run.progress = [&](std::int64_t done, std::int64_t total) {
    if (first_done < 0) first_done = done - 1;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!tty || (elapsed - last_draw < 0.2 && done < total)) return;
    last_draw = elapsed;
    const double rate = static_cast<double>(done - first_done) / std::max(elapsed, 1e-9);
    const double left = rate > 0 ? static_cast<double>(total - done) / rate : 0.0;
    const int width = 30, filled = total ? static_cast<int>(width * done / total) : width;
    std::fprintf(stderr, "\r[%.*s%*s] %lld/%lld samples  %.0f/s  %.0f s left   ", filled, "##############################", width - filled,
                 "", static_cast<long long>(done), static_cast<long long>(total), rate, left);
    std::fflush(stderr);
  };
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);  // Slurm's scancel and pre-emption send SIGTERM first
  const scene::CampaignRunResult r = scene::run_campaign(spec, opt.out_dir, run);
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (tty) std::fprintf(stderr, "\n");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::fprintf(stderr, "moreau campaign: %s: samples %lld to %lld: %lld run in %.1f s, %lld already done\n", spec.name.c_str(),
               static_cast<long long>(begin), static_cast<long long>(end), static_cast<long long>(r.ran), seconds,
               static_cast<long long>(r.skipped));
  if (r.stopped) {
    std::fprintf(stderr, "moreau campaign: stopped; every finished sample is kept in %s: run the same command again to go on\n",
                 opt.out_dir.c_str());
    return 130;
  }
  if (r.summarized) {
    write_figures(opt.out_dir);
    std::ifstream summary(opt.out_dir + "/summary.txt");
    std::cout << summary.rdbuf();
  } else {
    std::fprintf(stderr, "moreau campaign: the range is done; once every range is, `moreau campaign --collect %s` writes the summary\n",
                 opt.out_dir.c_str());
  }
  return 0;
}

}  // namespace

void register_campaign_command(CLI::App& app, Actions& actions) {
  auto opt = std::make_shared<CampaignOptions>();
  auto* cmd = app.add_subcommand("campaign",
                                 "Run a robustness campaign: a scene over sampled uncertain inputs, with a verdict (docs/campaigns.md)");
  cmd->add_option("spec", opt->spec_path, "Campaign spec (JSON)");
  cmd->add_option("--scene", opt->scene_path,
                  "A parameter sweep of this scene: the grid campaign over the --vary lists (in place of SPEC)");
  cmd->add_option("--vary", opt->vary, "With --scene: PATH=v1,v2,... or PATH=FIRST:LAST:COUNT (repeatable; the last varies fastest)");
  cmd->add_option("--set", opt->overrides, "With --scene: PATH=VALUE applied to the scene first (repeatable)");
  cmd->add_option("--out", opt->out_dir, "Directory of the campaign's results (resumable: run again to go on)");
  cmd->add_option("-j,--jobs", opt->jobs, "Worker threads (default: every core)");
  cmd->add_option("--range", opt->range, "Only samples BEGIN:END (END exclusive), written to a part file of their own (then --collect)");
  cmd->add_option("--collect", opt->collect_dir, "Check that every sample of DIR is present once and write its summary");
  cmd->add_flag("--quiet", opt->quiet, "No progress bar");
  cmd->add_option("--task", opt->task, "Only block K of T (K/T): one task of a split campaign, writing its own part file");
  cmd->add_flag("--slurm", opt->slurm, "Submit the campaign as a Slurm job array (sbatch) with a dependent collect job");
  cmd->add_option("--tasks", opt->tasks, "With --slurm: the number of array tasks (contiguous blocks of samples)")->capture_default_str();
  cmd->add_option("--cpus-per-task", opt->cpus_per_task, "With --slurm: CPUs per task (its worker threads)")->capture_default_str();
  cmd->add_option("--account", opt->account, "With --slurm: passed to sbatch");
  cmd->add_option("--partition", opt->partition, "With --slurm: passed to sbatch");
  cmd->add_option("--time", opt->time_limit, "With --slurm: passed to sbatch (a task's time limit)");
  actions[cmd] = [opt]() -> int {
    try {
      if (!opt->collect_dir.empty()) {
        const nlohmann::json summary = scene::collect_campaign(opt->collect_dir);
        write_figures(opt->collect_dir);
        std::cout << scene::format_campaign_summary(summary);
        return 0;
      }
      if (!opt->scene_path.empty()) {
        if (!opt->spec_path.empty()) throw std::runtime_error("give SPEC or --scene (a sweep), not both");
        if (opt->out_dir.empty()) throw std::runtime_error("a sweep needs --out DIR");
        opt->spec_path = write_grid_spec(*opt);
      } else if (!opt->vary.empty() || !opt->overrides.empty()) {
        throw std::runtime_error("--vary and --set go with --scene SCENE (a spec names its inputs itself)");
      }
      if (opt->spec_path.empty() || opt->out_dir.empty())
        throw std::runtime_error("a campaign needs SPEC and --out DIR (or --collect DIR)");
      return opt->slurm ? submit_to_slurm(*opt) : run(*opt);
    } catch (const scene::SceneError& e) {
      std::cerr << "moreau campaign: " << (opt->scene_path.empty() ? opt->spec_path : opt->scene_path) << ": " << e.what() << "\n";
      return 2;
    } catch (const std::exception& e) {
      std::cerr << "moreau campaign: " << e.what() << "\n";
      return 2;
    }
  };
}

}  // namespace moreau::cli
