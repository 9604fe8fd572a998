// moreau watch: subscribes to the LCM channels of running jobs (docs/streaming.md) and shows their
// live state as a table updated in place, with events as lines; --log records what it sees as an LCM
// log, --figure keeps a PNG of the state up to date.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>
#include <moreau/description_t.hpp>
#include <moreau/job_event_t.hpp>
#include <moreau/lcm_url.h>
#include <moreau/state_t.hpp>

#include "commands.h"
#include "remote_command_list.h"
#include "terminal_text.h"
#include "moreau/platform/number_text.h"
#include "moreau/render/figures.h"
#include "moreau/render/render.h"

namespace moreau::cli {
namespace {

using Clock = std::chrono::steady_clock;

std::atomic<bool> g_interrupted{false};
void on_interrupt(int) { g_interrupted = true; }

struct WatchOptions {
  std::string lcm_url;
  std::string channel;
  std::string job;
  std::string log;
  std::string figure;
  bool until_finished = false;
  double timeout = 0;
  bool plain = false;
};

// What is known of one job.
struct JobView {
  std::string id;
  moreau::state_t last;
  bool has_state = false;
  std::int64_t states = 0;
  std::string status = "streaming";
  // For --figure: the states seen, thinned by 2 whenever they reach kMaxPoints.
  render::TimeSeriesData series;
  std::int64_t keep_every = 1;
  std::int64_t seen = 0;
  std::optional<double> converged_time;
  std::optional<moreau::description_t> description;  // names and kind of system, once one arrived
};

constexpr std::size_t kMaxPoints = 20000;
// Impacts marked on the live figure; the server publishes at most kMaxImpactEvents of them anyway.
constexpr std::size_t kMaxImpactMarks = 10000;

// Numbers on the live lines: 6 significant digits unless said otherwise.
std::string fmt(double v, int digits = 6) { return platform::significant(v, digits); }

std::string vec(const std::vector<double>& x) {
  std::string s = "[";
  for (std::size_t i = 0; i < x.size() && i < 4; ++i) s += (i ? ", " : "") + fmt(x[i], 5);
  if (x.size() > 4) s += ", ...";
  return s + "]";
}

class Watcher {
 public:
  explicit Watcher(const WatchOptions& o) : o_(o), tty_(!o.plain && isatty(STDOUT_FILENO)) {}

  int run() {
    if (const std::string why = lcm_url_problem(o_.lcm_url); !why.empty()) {
      std::cerr << "moreau: cannot open LCM URL '" << o_.lcm_url << "': " << why << "\n";
      return 2;
    }
    lcm::LCM lc(o_.lcm_url);
    if (!lc.good()) {
      std::cerr << "moreau: cannot open LCM URL '" << o_.lcm_url << "'\n";
      return 2;
    }
    if (!o_.log.empty()) {
      log_ = std::make_unique<lcm::LogFile>(o_.log, "w");
      if (!log_->good()) {
        std::cerr << "moreau: cannot write LCM log '" << o_.log << "'\n";
        return 2;
      }
    }
    std::string channel = o_.channel;
    if (channel.empty()) {
      std::string id = o_.job;
      for (char& c : id) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      channel = id.empty() ? "MOREAU_(STATE|EVENT|DESC)_.*" : "MOREAU_(STATE|EVENT|DESC)_" + id;
    }
    // subscribeFunction rather than the member-function subscribe(), which LCM 1.3.1 and GCC 12's
    // UndefinedBehaviorSanitizer do not agree on.
    lc.subscribeFunction(channel, &Watcher::on_message, this);
    // Before "listening on": whoever waits for that line may interrupt at once.
    std::signal(SIGINT, on_interrupt);
    std::signal(SIGTERM, on_interrupt);
    std::cerr << "moreau watch: listening on " << channel << " (" << (o_.lcm_url.empty() ? "LCM_DEFAULT_URL or LCM's default" : o_.lcm_url)
              << ")" << std::endl;
    const auto start = Clock::now();
    std::string why_stopped = "interrupted";
    auto last_figure = Clock::now();
    int code = 0;
    while (!g_interrupted && !(o_.until_finished && finished_)) {
      if (o_.timeout > 0 && std::chrono::duration<double>(Clock::now() - start).count() >= o_.timeout) {
        why_stopped = "timed out after " + fmt(o_.timeout) + " s";
        if (o_.until_finished) {
          std::cerr << "moreau watch: no job finished within " << o_.timeout << " s\n";
          code = 1;
        }
        break;
      }
      if (lc.handleTimeout(50) < 0) {
        if (g_interrupted) break;  // the signal interrupted the wait: Ctrl-C is how a watch ends
        why_stopped = "LCM receive failed";
        std::cerr << "moreau watch: LCM receive failed\n";
        code = 1;
        break;
      }
      if (dirty_ && Clock::now() - last_draw_ >= std::chrono::milliseconds(50)) draw();
      if (!o_.figure.empty() && figure_dirty_ && Clock::now() - last_figure >= std::chrono::seconds(1)) {
        write_figure();
        last_figure = Clock::now();
      }
    }
    // Whatever is still queued (the final states and events).
    while (lc.handleTimeout(0) > 0) {
    }
    if (dirty_) draw();
    if (!o_.figure.empty() && figure_dirty_) write_figure();
    if (log_) log_.reset();
    if (o_.until_finished && finished_ && !g_interrupted) why_stopped = "a job finished";
    summarize(why_stopped);
    return code;
  }

  // One line on stderr when the watch ends: why, and what it saw.
  void summarize(const std::string& why) const {
    int ended = 0;
    for (const auto& [id, j] : jobs_) ended += j.status == "done" || j.status == "failed" || j.status == "cancelled";
    std::cerr << "moreau watch: " << why << "; received " << states_received_ << " states and " << events_received_ << " events of "
              << jobs_.size() << (jobs_.size() == 1 ? " job" : " jobs") << " (" << ended << " ended)\n";
  }

  static void on_message(const lcm::ReceiveBuffer* rbuf, const std::string& channel, Watcher* self) { self->handle(rbuf, channel); }

  void handle(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    if (log_) {
      lcm::LogEvent e;
      e.eventnum = events_logged_++;
      e.timestamp = rbuf->recv_utime;
      e.channel = channel;
      e.datalen = static_cast<std::int32_t>(rbuf->data_size);
      e.data = rbuf->data;
      log_->writeEvent(&e);
    }
    const int size = static_cast<int>(rbuf->data_size);
    moreau::state_t s;
    moreau::job_event_t ev;
    moreau::description_t desc;
    if (s.decode(rbuf->data, 0, size) == size) {
      ++states_received_;
      on_state(s);
    } else if (ev.decode(rbuf->data, 0, size) == size) {
      ++events_received_;
      on_event(ev);
    } else if (desc.decode(rbuf->data, 0, size) == size) {
      view(desc.job_id).description = desc;  // labels the live figure
    }
  }

 private:
  JobView& view(const std::string& id) {
    auto it = jobs_.find(id);
    if (it == jobs_.end()) {
      it = jobs_.emplace(id, JobView{}).first;
      it->second.id = id;
      order_.push_back(id);
    }
    return it->second;
  }

  void on_state(const moreau::state_t& s) {
    JobView& j = view(s.job_id);
    j.last = s;
    j.has_state = true;
    ++j.states;
    dirty_ = true;
    if (!o_.figure.empty()) {
      if (j.seen++ % j.keep_every == 0) {
        auto& d = j.series;
        if (d.q.empty()) {
          d.q.resize(static_cast<std::size_t>(s.n));
          d.v.resize(static_cast<std::size_t>(s.n));
          d.energy_label = "E = 1/2 <M v, v>";
        }
        d.t.push_back(s.t);
        d.h.push_back(s.h);
        d.energy.push_back(s.energy);
        for (std::size_t i = 0; i < d.q.size() && i < s.q.size(); ++i) {
          d.q[i].push_back(s.q[i]);
          d.v[i].push_back(s.v[i]);
        }
        if (d.t.size() >= kMaxPoints) thin(j);
      }
      figure_dirty_ = true;
    }
    if (!tty_ && Clock::now() - last_plain_[s.job_id] >= std::chrono::seconds(1)) {
      last_plain_[s.job_id] = Clock::now();
      // Job ids, kinds and texts come from whoever publishes on the channel: shown as visible text.
      std::printf("%s  step %-10lld t = %-12s h = %-10s E = %-12s q = %s  v = %s\n", terminal_safe(s.job_id.substr(0, 8)).c_str(),
                  static_cast<long long>(s.step), fmt(s.t).c_str(), fmt(s.h, 3).c_str(), fmt(s.energy).c_str(), vec(s.q).c_str(),
                  vec(s.v).c_str());
      std::fflush(stdout);
    }
  }

  static void thin(JobView& j) {
    auto half = [](std::vector<double>& x) {
      std::size_t k = 0;
      for (std::size_t i = 0; i < x.size(); i += 2) x[k++] = x[i];
      x.resize(k);
    };
    auto& d = j.series;
    half(d.t);
    half(d.h);
    half(d.energy);
    for (auto& q : d.q) half(q);
    for (auto& v : d.v) half(v);
    j.keep_every *= 2;
  }

  void on_event(const moreau::job_event_t& e) {
    JobView& j = view(e.job_id);
    if (e.kind == "finished" || e.kind == "failed" || e.kind == "cancelled") {
      j.status = e.kind;
      finished_ = true;
    }
    // "converged" comes when the rest is detected; "convergence_withdrawn" takes it back (docs/streaming.md).
    // Impacts from their events, at the step's own time: the states arrive every 1/64 s of simulated time,
    // so between two of them an impact would show only as a rounded corner.
    if (e.kind == "impact" && j.series.impact_times.size() < kMaxImpactMarks) j.series.impact_times.push_back(e.t);
    if (e.kind == "converged") j.converged_time = e.t;
    if (e.kind == "convergence_withdrawn") j.converged_time.reset();
    clear_table();
    std::printf("%s  %-9s step %lld, t = %s: %s\n", terminal_safe(e.job_id.substr(0, 8)).c_str(), terminal_safe(e.kind).c_str(),
                static_cast<long long>(e.step), fmt(e.t).c_str(), terminal_safe(e.text).c_str());
    std::fflush(stdout);
    dirty_ = true;
    figure_dirty_ = figure_dirty_ || !o_.figure.empty();
  }

  void clear_table() {
    if (tty_ && drawn_lines_ > 0) {
      std::printf("\x1b[%dA\x1b[J", drawn_lines_);
      drawn_lines_ = 0;
    }
  }

  // The table: one row per job, redrawn in place (on a terminal).
  void draw() {
    last_draw_ = Clock::now();
    dirty_ = false;
    if (!tty_) return;
    clear_table();
    std::printf("%-8s  %-10s %10s %12s %10s %12s  %s\n", "job", "status", "step", "t", "h", "energy", "q / v");
    int lines = 1;
    for (const auto& id : order_) {
      const JobView& j = jobs_.at(id);
      if (!j.has_state) continue;
      std::printf("%-8s  %-10s %10lld %12s %10s %12s  %s / %s\n", terminal_safe(id.substr(0, 8)).c_str(), terminal_safe(j.status).c_str(),
                  static_cast<long long>(j.last.step), fmt(j.last.t).c_str(), fmt(j.last.h, 3).c_str(), fmt(j.last.energy).c_str(),
                  vec(j.last.q).c_str(), vec(j.last.v).c_str());
      ++lines;
    }
    drawn_lines_ = lines;
    std::fflush(stdout);
  }

  // The state figure of the most recent job, written to a temporary file and renamed.
  void write_figure() {
    figure_dirty_ = false;
    for (auto it = order_.rbegin(); it != order_.rend(); ++it) {
      JobView& j = jobs_.at(*it);
      if (j.series.t.size() < 2) continue;
      try {
        render::TimeSeriesData d = j.series;
        d.converged_time = j.converged_time;
        if (j.description) {
          d.q_names = j.description->q_names;
          d.v_names = j.description->v_names;
          d.energy_label = j.description->energy;
          if (j.description->system == "lure") {
            d.q_title = "State x";
            d.q_axis = "x";
            d.v_title = "State rate dx/dt";
            d.v_axis = "dx/dt";
            d.state_space = true;
          }
        }
        render::FigureOptions opt;
        opt.title = "job " + j.id.substr(0, 8) + " (live, " + j.status + ")";
        const std::string tmp = o_.figure + ".tmp";
        const render::Figure figure = render::state_figure(d, opt);
        if (o_.figure.size() > 4 && o_.figure.compare(o_.figure.size() - 4, 4, ".svg") == 0) {
          std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
          out << render::render_svg(figure);
          if (!out.flush()) throw std::runtime_error("cannot write '" + tmp + "'");
        } else {
          render::render_png(figure, tmp);
        }
        std::filesystem::rename(tmp, o_.figure);
      } catch (const std::exception& e) {
        clear_table();
        std::fprintf(stderr, "moreau watch: figure: %s\n", e.what());
      }
      return;
    }
  }

  const WatchOptions& o_;
  bool tty_;
  std::unique_ptr<lcm::LogFile> log_;
  std::int64_t events_logged_ = 0;
  std::int64_t states_received_ = 0, events_received_ = 0;
  std::map<std::string, JobView> jobs_;
  std::vector<std::string> order_;
  std::map<std::string, Clock::time_point> last_plain_;
  bool finished_ = false, dirty_ = false, figure_dirty_ = false;
  int drawn_lines_ = 0;
  Clock::time_point last_draw_{};
};

}  // namespace

void register_watch_command(CLI::App& app, Actions& actions) {
  auto o = std::make_shared<WatchOptions>();
  auto* cmd = app.add_subcommand("watch", std::string(remote_command_description("watch")));
  cmd->add_option("--lcm-url", o->lcm_url, "LCM URL (default: LCM_DEFAULT_URL, else LCM's default)");
  cmd->add_option("--channel", o->channel, "Channel regex (default MOREAU_(STATE|EVENT|DESC)_.*)");
  cmd->add_option("--job", o->job, "Only this job's channels");
  cmd->add_option("--log", o->log, "Record every message received as an LCM log (lcm-logplayer can replay it)");
  cmd->add_option(
      "--figure", o->figure,
      "Keep a figure of the latest job's state up to date (once a second; PNG, or SVG for a .svg name), impacts marked from their events");
  cmd->add_flag("--until-finished", o->until_finished, "Exit when a job has finished, failed or been cancelled");
  cmd->add_option("--timeout", o->timeout, "Stop after this many seconds (exit 1 with --until-finished if none finished)");
  cmd->add_flag("--plain", o->plain, "Lines instead of a table redrawn in place (the default when not on a terminal)");
  actions[cmd] = [o] { return Watcher(*o).run(); };
}

}  // namespace moreau::cli
