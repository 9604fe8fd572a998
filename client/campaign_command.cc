// moreau campaign SPEC --out DIR [-j N] [--range BEGIN:END] : runs a robustness campaign (or its share);
// moreau campaign --collect DIR : checks that every sample is present once and writes the summary.
// The spec, the files and the statistics: scene/include/moreau/scene/campaign.h and docs/campaigns.md.
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <fstream>
#include <cstdio>
#include <iostream>
#include <memory>
#include <mutex>
#include <thread>

#include "commands.h"
#include "moreau/scene/campaign.h"
#include "moreau/scene/scene.h"

namespace moreau::cli {
namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_interrupt(int) { g_stop.store(true); }

struct CampaignOptions {
  std::string spec_path, out_dir, collect_dir, range;
  int jobs = 0;
  bool quiet = false;
};

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
  const auto [begin, end] = parse_range(opt.range, spec.samples);
  scene::CampaignRunOptions run;
  run.begin = begin;
  run.end = end;
  run.workers = opt.jobs > 0 ? opt.jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
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
    std::fprintf(stderr, "\r[%.*s%*s] %lld/%lld samples  %.0f/s  %.0f s left   ", filled, "##############################", width - filled, "",
                 static_cast<long long>(done), static_cast<long long>(total), rate, left);
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
    std::fprintf(stderr, "moreau campaign: stopped; every finished sample is kept in %s: run the same command again to go on\n", opt.out_dir.c_str());
    return 130;
  }
  if (r.summarized) {
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
  auto* cmd = app.add_subcommand("campaign", "Run a robustness campaign: a scene over sampled uncertain inputs, with a verdict (docs/campaigns.md)");
  cmd->add_option("spec", opt->spec_path, "Campaign spec (JSON)");
  cmd->add_option("--out", opt->out_dir, "Directory of the campaign's results (resumable: run again to go on)");
  cmd->add_option("-j,--jobs", opt->jobs, "Worker threads (default: every core)");
  cmd->add_option("--range", opt->range, "Only samples BEGIN:END (END exclusive), e.g. one task's share");
  cmd->add_option("--collect", opt->collect_dir, "Check that every sample of DIR is present once and write its summary");
  cmd->add_flag("--quiet", opt->quiet, "No progress bar");
  actions[cmd] = [opt]() -> int {
    try {
      if (!opt->collect_dir.empty()) {
        const nlohmann::json summary = scene::collect_campaign(opt->collect_dir);
        std::cout << scene::format_campaign_summary(summary);
        return 0;
      }
      if (opt->spec_path.empty() || opt->out_dir.empty()) throw std::runtime_error("a campaign needs SPEC and --out DIR (or --collect DIR)");
      return run(*opt);
    } catch (const scene::SceneError& e) {
      std::cerr << "moreau campaign: " << opt->spec_path << ": " << e.what() << "\n";
      return 2;
    } catch (const std::exception& e) {
      std::cerr << "moreau campaign: " << e.what() << "\n";
      return 2;
    }
  };
}

}  // namespace moreau::cli
