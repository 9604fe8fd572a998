// Talking to a moreau-server (docs/api.md): moreau submit, status, result, figure, cancel, jobs, scenes.
// The server URL comes from --server, else MOREAU_SERVER, else http://127.0.0.1:8080; a token from
// --token, else MOREAU_TOKEN.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "remote_command_list.h"
#include "terminal_text.h"
#include "moreau/analysis/figure_kind.h"
#include "moreau/platform/number_text.h"
#include "moreau/scene/scene.h"

// After Eigen (through scene.h): httplib.h brings <resolv.h>, whose `_res` macro breaks Eigen.
#include <httplib.h>

namespace moreau::cli {
namespace {

using json = nlohmann::json;

struct Remote {
  std::string server;
  std::string token;
  bool json_output = false;

  void add_to(CLI::App* cmd) {
    cmd->add_option("--server", server, "Server URL (default: MOREAU_SERVER, else http://127.0.0.1:8080)");
    cmd->add_option("--token", token, "Bearer token (default: MOREAU_TOKEN)");
  }
  std::string url() const {
    if (!server.empty()) return server;
    if (const char* e = std::getenv("MOREAU_SERVER"); e && *e) return e;
    return "http://127.0.0.1:8080";
  }
  std::unique_ptr<httplib::Client> client() const {
    auto c = std::make_unique<httplib::Client>(url());
    c->set_tcp_nodelay(true);
    c->set_keep_alive(true);
    c->set_connection_timeout(5, 0);
    c->set_read_timeout(90, 0);
    std::string t = token;
    if (t.empty()) {
      if (const char* e = std::getenv("MOREAU_TOKEN"); e && *e) t = e;
    }
    if (!t.empty()) c->set_bearer_token_auth(t);
    return c;
  }
};

// A failed request: prints why and gives the exit code (2: the request was refused as invalid, 1 otherwise).
int report_failure(const Remote& remote, const httplib::Result& r, const std::string& what) {
  if (!r) {
    std::cerr << "moreau: cannot reach " << remote.url() << " (" << what << "): " << httplib::to_string(r.error()) << "\n";
    return 1;
  }
  std::string message = "HTTP " + std::to_string(r->status);
  const json body = json::parse(r->body, nullptr, false);
  if (body.is_object() && body.contains("error")) {
    message += ": " + body.value("error", "");
    if (body.contains("pointer"))
      message += " at " + body.value("pointer", "") + (body.value("where", "") == "request" ? " (request)" : "");
    if (body.contains("reason")) message += ": " + body.value("reason", "");
  }
  if (r->status == 429 && r->has_header("Retry-After")) message += " (retry after " + r->get_header_value("Retry-After") + " s)";
  if (r->status == 401)
    message += remote.token.empty() && !std::getenv("MOREAU_TOKEN")
                   ? " (this server needs a token: pass it with --token or the environment variable MOREAU_TOKEN)"
                   : " (the token given by --token or MOREAU_TOKEN was not accepted)";
  // The error, pointer, reason and Retry-After are the server's: shown as visible text (terminal_text.h).
  std::cerr << "moreau: " << terminal_safe(what) << ": " << terminal_safe(message) << "\n";
  return r->status == 400 || r->status == 404 || r->status == 409 || r->status == 413 || r->status == 415 ? 2 : 1;
}

bool ok(const httplib::Result& r, int status = 200) { return r && r->status == status; }

// The body of a successful response as JSON. Something that is not a moreau-server (a proxy's error page,
// another service on the port) can answer anything: that is a failed request, not a crash.
json body_json(const httplib::Result& r) {
  json j = json::parse(r->body, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object())
    throw std::runtime_error("the server's answer (HTTP " + std::to_string(r->status) + ", " + std::to_string(r->body.size()) +
                             " bytes) is not a JSON object: is it a moreau-server?");
  return j;
}

// j[key] when j is an object holding key, else null: operator[] on a const json with a missing key is
// undefined behaviour, and an answer may lack any field.
const json& field(const json& j, const char* key) {
  static const json null;
  if (!j.is_object()) return null;
  const auto it = j.find(key);
  return it == j.end() ? null : *it;
}

// j[key] as a string for a person to read: the server's text with control and bidirectional characters
// shown as escapes (terminal_safe), `otherwise` when absent.
std::string text(const json& j, const char* key, const char* otherwise) { return terminal_safe(j.value(key, std::string(otherwise))); }

// Runs a remote command; an exception (an answer of an unexpected shape) is a failed request: exit 1.
template <class F>
int guarded(F&& command) {
  try {
    return command();
  } catch (const std::exception& e) {
    std::cerr << "moreau: " << terminal_safe(e.what()) << "\n";  // may quote an answer's text
    return 1;
  }
}

// Numbers for a person: 10 significant digits.
std::string fmt(double v) { return platform::significant(v, 10); }

bool is_final(const std::string& state) { return state == "done" || state == "failed" || state == "cancelled"; }

// A few lines for a person: state, progress, and the report's main facts.
void print_job(const json& job) {
  std::cout << "job " << text(job, "id", "?") << "  " << text(job, "scene", "") << "  " << text(job, "state", "?");
  if (job.contains("reason")) std::cout << " (" << text(job, "reason", "") << ")";
  std::cout << "\n";
  if (job.contains("progress")) {
    const json& p = field(job, "progress");
    if (field(p, "t").is_number() && field(p, "fraction").is_number()) {
      std::cout << "  progress      t = " << fmt(p["t"].get<double>()) << " of [" << fmt(p.value("t0", 0.0)) << ", "
                << fmt(p.value("t_end", 0.0)) << "] (" << fmt(std::round(1000 * p["fraction"].get<double>()) / 10) << "%), step "
                << p.value("step", std::int64_t{0}) << "\n";
    }
  }
  if (field(job, "stream").is_object()) {
    std::cout << "  stream        " << text(job["stream"], "state_channel", "") << ", " << text(job["stream"], "event_channel", "") << "\n";
  }
  if (!field(job, "report").is_object()) return;
  const json& r = job["report"];
  std::cout << "  status        " << text(r, "status", "?") << ": " << r.value("steps", std::int64_t{0})
            << " steps to t = " << (field(r, "t_final").is_number() ? fmt(r["t_final"].get<double>()) : "?") << "\n";
  if (r.contains("message")) std::cout << "  message       " << text(r, "message", "") << "\n";
  if (r.contains("final"))
    std::cout << "  final state   q = " << terminal_safe_json(field(field(r, "final"), "q").dump())
              << ", v = " << terminal_safe_json(field(field(r, "final"), "v").dump()) << "\n";
  if (field(r, "converged_step").is_number() && field(r, "converged_time").is_number()) {
    std::cout << "  convergence   v == 0.0 exactly from step " << r["converged_step"].get<std::int64_t>()
              << " (t = " << fmt(r["converged_time"].get<double>()) << ") to the end\n";
  } else {
    std::cout << "  convergence   v is not exactly 0 at the last step\n";
  }
  const json& energy = field(r, "energy");
  if (field(energy, "initial").is_number() && field(energy, "final").is_number()) {
    std::cout << "  energy        E_0 = " << fmt(energy["initial"].get<double>()) << ", E_N = " << fmt(energy["final"].get<double>())
              << (r.value("energy_nonincreasing", false) ? " (non-increasing)" : "") << "\n";
  }
}

// Long-polls a job (collection "/v1/jobs/") or a study ("/v1/studies/") until it is final; draws a
// progress line on stderr when it is a terminal (a job's t, a study's rows of the table).
std::optional<json> wait_for(const Remote& remote, httplib::Client& c, const std::string& collection, const std::string& id, int& code) {
  const bool tty = isatty(STDERR_FILENO);
  bool drawn = false;
  while (true) {
    auto r = c.Get(collection + id + "?wait=" + (tty ? "0.5" : "30"));
    if (!ok(r)) {
      code = report_failure(remote, r, "status of " + id);
      return std::nullopt;
    }
    json job = body_json(r);
    const std::string state = job.value("state", "");
    const std::string shown = terminal_safe(state);
    if (is_final(state)) {
      if (drawn) std::fprintf(stderr, "\r%*s\r", 72, "");
      return job;
    }
    if (tty) {
      const json& p = job["progress"];
      const double f = p["fraction"].is_number() ? p["fraction"].get<double>() : 0.0;
      if (p.contains("rows"))
        std::fprintf(stderr, "\r%-8s %5.1f%%  rows %lld of %lld", shown.c_str(), 100.0 * f,
                     p["rows"].is_number() ? p["rows"].get<long long>() : 0LL,
                     p["rows_total"].is_number() ? p["rows_total"].get<long long>() : 0LL);
      else
        std::fprintf(stderr, "\r%-8s %5.1f%%  t = %-12.6g", shown.c_str(), 100.0 * f, p["t"].is_number() ? p["t"].get<double>() : 0.0);
      std::fflush(stderr);
      drawn = true;
    }
  }
}

// ---- submit ----

struct SubmitOptions {
  Remote remote;
  std::string scene;
  std::vector<std::string> overrides;
  bool wait = false;
  bool stream = false, realtime = false;
  std::optional<double> period;
  std::string channel;
  // --study: a server-side study (POST /v1/studies), with the options of `moreau study`.
  bool study = false;
  std::string ladder, schemes, regularization, csv;
  std::optional<double> reference_h, epsilon;
  std::optional<int> eval_points, repeats;
};

// A finished study in a few lines: its state, and each scheme's fitted order with the theory that applies.
void print_study(const json& study) {
  std::cout << "study " << text(study, "id", "?") << "  " << text(study, "scene", "?") << "  " << text(study, "state", "?") << "\n";
  if (study.contains("reason")) std::cout << "  reason        " << text(study, "reason", "") << "\n";
  const json& result = field(study, "result");
  if (!result.is_object()) return;
  std::cout << "  rows          " << field(result, "rows").size() << " (reference: " << text(result, "reference", "?") << ")\n";
  for (const auto& o : field(result, "orders")) {
    std::cout << "  order " << text(o, "scheme", "?") << ": q_max " << (o["q_max"].is_number() ? fmt(o["q_max"].get<double>()) : "n/a")
              << " (theory: " << text(o, "theory", "?") << ")\n";
  }
}

// The study settings of `moreau submit --study` (POST /v1/studies, "study"), as `moreau study` names them.
json study_settings(const SubmitOptions& o) {
  json settings = json::object();
  if (!o.ladder.empty()) settings["h"] = o.ladder;
  if (!o.schemes.empty()) settings["schemes"] = o.schemes;
  if (o.reference_h) settings["reference_h"] = *o.reference_h;
  if (o.epsilon) settings["epsilon"] = *o.epsilon;
  if (!o.regularization.empty()) settings["regularization"] = o.regularization;
  if (o.eval_points) settings["eval_points"] = *o.eval_points;
  if (o.repeats) settings["repeats"] = *o.repeats;
  return settings;
}

int submit(const SubmitOptions& o) {
  json request;
  // A file, or the name of a scene the server ships (GET /v1/scenes).
  std::error_code ec;
  if (std::filesystem::exists(o.scene, ec)) {
    try {
      request["scene"] = scene::read_scene_file(o.scene);
    } catch (const std::exception& e) {
      std::cerr << "moreau: " << e.what() << "\n";
      return 2;
    }
  } else if (o.scene.find('/') == std::string::npos && o.scene.find(".json") == std::string::npos) {
    request["scene"] = o.scene;
  } else {
    std::cerr << "moreau: no such scene file '" << o.scene << "'\n";
    return 2;
  }
  if (!o.overrides.empty()) request["overrides"] = o.overrides;
  const bool streamed = o.stream || o.realtime || o.period || !o.channel.empty();
  const json settings = study_settings(o);
  if ((!settings.empty() || !o.csv.empty()) && !o.study) {
    std::cerr << "moreau: --h, --schemes, --reference-h, --epsilon, --regularization, --eval-points, --repeats and --csv "
                 "are options of a study: add --study\n";
    return 2;
  }
  if (!o.csv.empty() && !o.wait) {
    std::cerr << "moreau: --csv writes the table of a finished study: add --wait\n";
    return 2;
  }
  if (o.study && streamed) {
    std::cerr << "moreau: a study is not streamed over LCM: --stream, --period, --realtime and --channel are for jobs\n";
    return 2;
  }
  if (o.study && !settings.empty()) request["study"] = settings;
  if (streamed) {
    json s = json::object();
    if (o.period) s["period"] = *o.period;
    if (o.realtime) s["realtime"] = true;
    if (!o.channel.empty()) s["channel"] = o.channel;
    request["stream"] = s;
  }
  const std::string collection = o.study ? "/v1/studies/" : "/v1/jobs/";
  const char* what = o.study ? "study" : "job";
  auto c = o.remote.client();
  auto r = c->Post(collection.substr(0, collection.size() - 1), request.dump(), "application/json");
  if (!ok(r, 202)) return report_failure(o.remote, r, std::string("submit ") + (o.study ? "study of " : "") + o.scene);
  const json accepted = body_json(r);
  const std::string id = accepted.value("id", "");
  if (!o.wait) {
    if (o.remote.json_output)
      std::cout << terminal_safe_json(accepted.dump(2)) << "\n";
    else
      std::cout << terminal_safe(id) << "\n";
    return 0;
  }
  if (!o.remote.json_output) std::cerr << "submitted " << (o.study ? "study " : "") << terminal_safe(id) << "\n";
  int code = 0;
  auto job = wait_for(o.remote, *c, collection, id, code);
  if (!job) return code;
  const bool done = job->value("state", "") == "done";
  if (o.study && done && !o.csv.empty()) {
    auto t = c->Get(collection + id + "/table?format=csv");
    if (!ok(t)) return report_failure(o.remote, t, std::string("table of ") + what + " " + id);
    std::ofstream out(o.csv, std::ios::binary);
    out << t->body;
    if (!out) {
      std::cerr << "moreau: cannot write '" << o.csv << "'\n";
      return 2;
    }
  }
  if (o.remote.json_output)
    std::cout << terminal_safe_json(job->dump(2)) << "\n";
  else if (o.study)
    print_study(*job);
  else
    print_job(*job);
  return done ? 0 : 1;
}

// ---- status ----

struct IdOptions {
  Remote remote;
  std::string id;
  bool wait = false;
};

int status(const IdOptions& o) {
  auto c = o.remote.client();
  std::optional<json> job;
  if (o.wait) {
    int code = 0;
    job = wait_for(o.remote, *c, "/v1/jobs/", o.id, code);
    if (!job) return code;
  } else {
    auto r = c->Get("/v1/jobs/" + o.id);
    if (!ok(r)) return report_failure(o.remote, r, "status of " + o.id);
    job = body_json(r);
  }
  if (o.remote.json_output)
    std::cout << terminal_safe_json(job->dump(2)) << "\n";
  else
    print_job(*job);
  const std::string state = job->value("state", "");
  return state == "failed" || state == "cancelled" ? 1 : 0;
}

// ---- result ----

struct ResultOptions {
  Remote remote;
  std::string id;
  std::string out;
  std::string format;
};

bool write_file(const std::string& path, const std::string& bytes) {
  std::ofstream f(path, std::ios::binary);
  f << bytes;
  f.close();
  if (!f) {
    std::cerr << "moreau: cannot write '" << path << "'\n";
    return false;
  }
  return true;
}

int result(const ResultOptions& o) {
  auto c = o.remote.client();
  if (o.out.empty()) {
    auto r = c->Get("/v1/jobs/" + o.id + "/report");
    if (!ok(r)) return report_failure(o.remote, r, "report of " + o.id);
    std::cout << terminal_safe_json(r->body);  // the stored report.json: the same JSON, unsafe characters as \uNNNN
    return 0;
  }
  std::string format = o.format;
  if (format.empty()) format = o.out.size() > 5 && o.out.substr(o.out.size() - 5) == ".json" ? "json" : "csv";
  auto r = c->Get("/v1/jobs/" + o.id + "/trajectory?format=" + format);
  if (!ok(r)) return report_failure(o.remote, r, "trajectory of " + o.id);
  if (!write_file(o.out, r->body)) return 1;
  std::cerr << "wrote " << o.out << " (" << r->body.size() << " bytes)\n";
  return 0;
}

// ---- figure ----

struct FigureOptions {
  Remote remote;
  std::string id;
  std::string kind = scene::figure_name(scene::default_figure<scene::TrajectoryFigure>());
  std::string out;
  std::string size;
};

int figure(const FigureOptions& o) {
  std::string query = "?kind=" + o.kind;
  if (!o.size.empty()) {
    const auto x = o.size.find('x');
    if (x == std::string::npos) {
      std::cerr << "moreau: --size must be WIDTHxHEIGHT, got '" << o.size << "'\n";
      return 2;
    }
    query += "&width=" + o.size.substr(0, x) + "&height=" + o.size.substr(x + 1);
  }
  // SVG when the file is named so (drawn by the server without GL), else PNG.
  const bool svg = o.out.size() >= 4 && o.out.compare(o.out.size() - 4, 4, ".svg") == 0;
  if (svg) query += std::string("&format=") + scene::figure_name(scene::FigureFormat::kSvg);
  auto c = o.remote.client();
  auto r = c->Get("/v1/jobs/" + o.id + "/figure" + query);
  if (!ok(r)) return report_failure(o.remote, r, o.kind + " figure of " + o.id);
  if (!write_file(o.out, r->body)) return 1;
  std::cerr << "wrote " << o.out << "\n";
  return 0;
}

// ---- cancel ----

int cancel(const IdOptions& o) {
  auto c = o.remote.client();
  auto r = c->Delete("/v1/jobs/" + o.id);
  if (!ok(r)) return report_failure(o.remote, r, "cancel " + o.id);
  const json job = body_json(r);
  if (o.remote.json_output)
    std::cout << terminal_safe_json(job.dump(2)) << "\n";
  else
    std::cout << terminal_safe(o.id) << " " << text(job, "state", "?") << "\n";
  return 0;
}

// ---- jobs, scenes ----

struct ListOptions {
  Remote remote;
  std::string state;
  int limit = 0;
};

int jobs(const ListOptions& o) {
  auto c = o.remote.client();
  std::string query = "?";
  if (!o.state.empty()) query += "state=" + o.state + "&";
  if (o.limit > 0) query += "limit=" + std::to_string(o.limit);
  auto r = c->Get("/v1/jobs" + query);
  if (!ok(r)) return report_failure(o.remote, r, "list jobs");
  const json list = body_json(r);
  if (o.remote.json_output) {
    std::cout << terminal_safe_json(list.dump(2)) << "\n";
    return 0;
  }
  for (const auto& job : field(list, "jobs")) {
    const json& fraction = field(field(job, "progress"), "fraction");
    const double f = fraction.is_number() ? fraction.get<double>() : 0.0;
    std::printf("%s  %-9s %5.1f%%  %s\n", text(job, "id", "?").c_str(), text(job, "state", "?").c_str(), 100.0 * f,
                text(job, "scene", "").c_str());
  }
  return 0;
}

int scenes(const ListOptions& o) {
  auto c = o.remote.client();
  auto r = c->Get("/v1/scenes");
  if (!ok(r)) return report_failure(o.remote, r, "list scenes");
  const json list = body_json(r);
  if (o.remote.json_output) {
    std::cout << terminal_safe_json(list.dump(2)) << "\n";
    return 0;
  }
  for (const auto& s : field(list, "scenes")) {
    std::string d = s.value("description", "");
    if (d.size() > 90) {
      std::size_t cut = 87;  // not inside a UTF-8 sequence
      while (cut > 0 && (static_cast<unsigned char>(d[cut]) & 0xC0) == 0x80) --cut;
      d = d.substr(0, cut) + "...";
    }
    std::printf("%-24s %s\n", text(s, "name", "?").c_str(), terminal_safe(d).c_str());
  }
  return 0;
}

}  // namespace

void register_remote_commands(CLI::App& app, Actions& actions) {
  {
    auto o = std::make_shared<SubmitOptions>();
    auto* cmd = app.add_subcommand("submit", std::string(remote_command_description("submit")));
    cmd->add_option("scene", o->scene, "Scene file, or the name of a scene the server ships (moreau scenes)")->required();
    cmd->add_option("--set", o->overrides, "Override a scene field: PATH=VALUE (applied and checked by the server)");
    cmd->add_flag("--wait", o->wait, "Wait for the job to finish and print its report");
    cmd->add_flag("--stream", o->stream, "Publish the live state over LCM (see moreau watch)");
    cmd->add_option("--period", o->period, "Streaming period in simulation seconds (default 1/64)");
    cmd->add_flag("--realtime", o->realtime, "Stream paced to wall-clock time");
    cmd->add_option("--channel", o->channel, "LCM channel prefix (default MOREAU: MOREAU_STATE_<ID>)");
    cmd->add_flag("--study", o->study, "Run a study on the server (as moreau study): step sizes and schemes below");
    cmd->add_option("--h", o->ladder, "Study: step sizes FIRST:LAST:COUNT (log-spaced) or a comma list (default 1e-1:1e-5:9)");
    cmd->add_option("--schemes", o->schemes, "Study: comma list of abl, explicit, regularized (default: all three)");
    cmd->add_option("--reference-h", o->reference_h, "Study: force an abl reference at this h");
    cmd->add_option("--epsilon", o->epsilon, "Study: width of the regularized sign");
    cmd->add_option("--regularization", o->regularization, "Study: tanh or saturation")->check(CLI::IsMember({"tanh", "saturation"}));
    cmd->add_option("--eval-points", o->eval_points, "Study: common times at which errors are measured");
    cmd->add_option("--repeats", o->repeats, "Study: timed runs per point (the minimum is kept)");
    cmd->add_option("--csv", o->csv, "Study, with --wait: write the table as CSV (needs --wait)");
    cmd->add_flag("--json", o->remote.json_output, "Print the job (or study) as JSON");
    o->remote.add_to(cmd);
    actions[cmd] = [o] { return guarded([&] { return submit(*o); }); };
  }
  {
    auto o = std::make_shared<IdOptions>();
    auto* cmd = app.add_subcommand("status", std::string(remote_command_description("status")));
    cmd->add_option("id", o->id, "Job id")->required();
    cmd->add_flag("--wait", o->wait, "Wait until the job has finished");
    cmd->add_flag("--json", o->remote.json_output, "Print the job as JSON");
    o->remote.add_to(cmd);
    actions[cmd] = [o] { return guarded([&] { return status(*o); }); };
  }
  {
    auto o = std::make_shared<ResultOptions>();
    auto* cmd = app.add_subcommand("result", std::string(remote_command_description("result")));
    cmd->add_option("id", o->id, "Job id")->required();
    cmd->add_option("--out", o->out, "Write the trajectory here (CSV; JSON if the name ends in .json)");
    cmd->add_option("--format", o->format, "Trajectory format: csv or json")->check(CLI::IsMember({"csv", "json"}));
    o->remote.add_to(cmd);
    actions[cmd] = [o] { return guarded([&] { return result(*o); }); };
  }
  {
    auto o = std::make_shared<FigureOptions>();
    auto* cmd = app.add_subcommand("figure", std::string(remote_command_description("figure")));
    cmd->add_option("id", o->id, "Job id")->required();
    cmd->add_option("--kind", o->kind, scene::figure_name_list<scene::TrajectoryFigure>())
        ->capture_default_str()
        ->check(CLI::IsMember(scene::figure_names<scene::TrajectoryFigure>()));
    cmd->add_option("-o,--out", o->out, "File to write: PNG, or SVG if its name ends in .svg")->required();
    cmd->add_option("--size", o->size, "WIDTHxHEIGHT in pixels (default 1200x800)");
    o->remote.add_to(cmd);
    actions[cmd] = [o] { return guarded([&] { return figure(*o); }); };
  }
  {
    auto o = std::make_shared<IdOptions>();
    auto* cmd = app.add_subcommand("cancel", std::string(remote_command_description("cancel")));
    cmd->add_option("id", o->id, "Job id")->required();
    cmd->add_flag("--json", o->remote.json_output, "Print the job as JSON");
    o->remote.add_to(cmd);
    actions[cmd] = [o] { return guarded([&] { return cancel(*o); }); };
  }
  {
    auto o = std::make_shared<ListOptions>();
    auto* cmd = app.add_subcommand("jobs", std::string(remote_command_description("jobs")));
    cmd->add_option("--state", o->state, "Only jobs in this state")
        ->check(CLI::IsMember({"queued", "running", "done", "failed", "cancelled"}));
    cmd->add_option("--limit", o->limit, "Only the most recent N");
    cmd->add_flag("--json", o->remote.json_output, "Print the list as JSON");
    o->remote.add_to(cmd);
    actions[cmd] = [o] { return guarded([&] { return jobs(*o); }); };
  }
  {
    auto o = std::make_shared<ListOptions>();
    auto* cmd = app.add_subcommand("scenes", std::string(remote_command_description("scenes")));
    cmd->add_flag("--json", o->remote.json_output, "Print the list as JSON");
    o->remote.add_to(cmd);
    actions[cmd] = [o] { return guarded([&] { return scenes(*o); }); };
  }
}

}  // namespace moreau::cli
