// moreau._moreau: the compiled part of the Python package `moreau` (python/moreau/, docs/python.md). It
// binds the scene library as the command line uses it: a scene read and compiled (Simulation), a run with
// its recorded states in one table (TrajectoryTable, shared with numpy without a copy), the report, the
// figures (render/, its raster module opened at the first PNG as in the CLI), studies and campaigns.
// The package's Python files build the user's API over these few calls.
//
// The GIL is released while a scene integrates, a study or a campaign runs: Python threads run scenes in
// parallel. The run's observer takes the GIL back about every 50 ms of wall time to let Python see a
// Ctrl-C (PyErr_CheckSignals, which acts in the main thread only) and to report progress; an interrupt
// cancels the run at its next control point and is raised as KeyboardInterrupt once the run has returned.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "moreau/analysis/campaign.h"
#include "moreau/analysis/campaign_figures.h"
#include "moreau/analysis/figure_kind.h"
#include "moreau/analysis/figures.h"
#include "moreau/analysis/sampling_study.h"
#include "moreau/analysis/study.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/simulation.h"
#include "trajectory_table.h"

namespace py = pybind11;

namespace moreau::python {
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kCheckInterval = std::chrono::milliseconds(50);

// Python's own exception types for the scene library's errors (python/moreau/errors.py), so that local
// and remote code catch the same classes.
void raise_scene_error(const scene::SceneError& e) {
  py::object cls = py::module_::import("moreau.errors").attr("SceneError");
  py::object exc = cls(e.what(), e.pointer(), e.reason());
  PyErr_SetObject(cls.ptr(), exc.ptr());
}

// Takes the GIL every kCheckInterval while a run goes on: Ctrl-C (in the main thread) or an exception of
// the progress callback cancels the run; the error is kept and raised by the caller once the run returned.
class PythonControl : public ForwardingObserver {
 public:
  PythonControl(RunObserver* next, std::function<void(double)> progress) : ForwardingObserver(next), progress_(std::move(progress)) {}
  bool keep_going(std::int64_t step, double t) override {
    if (!ForwardingObserver::keep_going(step, t)) return false;
    const auto now = Clock::now();
    if (now < next_check_) return true;
    next_check_ = now + kCheckInterval;
    py::gil_scoped_acquire gil;
    try {
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      if (progress_) progress_(t);
    } catch (py::error_already_set& e) {
      error_ = std::make_unique<py::error_already_set>(std::move(e));
      return false;
    }
    return true;
  }
  // With the GIL held: raises what stopped the run, if anything did.
  void raise_if_stopped() {
    if (error_) {
      std::unique_ptr<py::error_already_set> e = std::move(error_);
      throw std::move(*e);
    }
  }

 private:
  std::function<void(double)> progress_;
  Clock::time_point next_check_ = Clock::now() + kCheckInterval;
  std::unique_ptr<py::error_already_set> error_;
};

// Runs `work` on a thread of its own while this (Python's) thread waits without the GIL, waking every
// kCheckInterval to look for Ctrl-C (then `stop` is set and the work is waited for) and to call `poll`.
// For studies and campaigns, whose runs have no observer of ours; the work must end soon after `stop`.
template <typename Work>
void run_beside_python(Work work, std::atomic<bool>& stop, const std::function<void()>& poll) {
  std::mutex mu;
  std::condition_variable cv;
  bool done = false;
  std::exception_ptr failure;
  std::thread worker([&] {
    try {
      work();
    } catch (...) {
      failure = std::current_exception();
    }
    std::lock_guard<std::mutex> lock(mu);
    done = true;
    cv.notify_all();
  });
  std::unique_ptr<py::error_already_set> interrupt;
  for (;;) {
    {
      py::gil_scoped_release release;
      std::unique_lock<std::mutex> lock(mu);
      if (cv.wait_for(lock, kCheckInterval, [&] { return done; })) break;
    }
    if (interrupt) continue;
    try {
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      if (poll) poll();
    } catch (py::error_already_set& e) {
      interrupt = std::make_unique<py::error_already_set>(std::move(e));
      stop = true;
    }
  }
  worker.join();
  if (poll && !interrupt) poll();
  if (interrupt) throw std::move(*interrupt);
  if (failure) std::rethrow_exception(failure);
}

// One finished run: the table of its recorded states, its summary and diagnostics, and the Simulation it
// ran (shared), for the report and the figures.
struct RunOutput {
  scene::Simulation sim;
  // The compiled scene the run came from, for the figures' labels and units (a run bound from a scene
  // compiled with free parameters has no document of its own).
  scene::Simulation labels;
  std::shared_ptr<TrajectoryTable> table;
  RunSummary summary;
  scene::RunDiagnostics diagnostics;

  std::string report_json() const { return sim.report_json(summary, diagnostics).dump(); }
  std::string report_text() const { return sim.report_text(summary, diagnostics); }

  py::bytes figure(const std::string& kind_name, const std::string& format_name, std::optional<int> width, std::optional<int> height,
                   const std::string& title, bool robust_y) const {
    const auto kind = scene::figure_from_name<scene::TrajectoryFigure>(kind_name);
    if (!kind)
      throw std::invalid_argument("figure kind '" + kind_name + "': expected " + scene::figure_name_list<scene::TrajectoryFigure>());
    const auto format = scene::figure_from_name<scene::FigureFormat>(format_name);
    if (!format) throw std::invalid_argument("figure format '" + format_name + "': expected png or svg");
    render::FigureOptions options;
    if (width) options.width_px = *width;
    if (height) options.height_px = *height;
    options.title = title;
    options.robust_y = robust_y;
    std::string bytes;
    {
      py::gil_scoped_release release;
      render::TimeSeriesData data = table->time_series(sim.position_names(), sim.velocity_names(), sim.signal_names());
      if (summary.converged_time) data.converged_time = *summary.converged_time;
      scene::label_for_system(data, labels);
      if (const ContactDiagnostics* contacts = diagnostics.contacts())
        for (const auto& impact : contacts->impacts) data.impact_times.push_back(impact.t);
      bytes = scene::encode_figure(scene::trajectory_figure(*kind, data, options), *format);
    }
    return py::bytes(bytes);
  }
};

// A compiled scene and its document (every file it names read in: read_scene_file), for runs as it is
// and for runs with other values. Runs that change only parameters bind a ParametricLagrangianScene
// compiled once for those names, as a campaign's samples do, instead of compiling the scene again.
class CompiledScene {
 public:
  CompiledScene(nlohmann::json doc, scene::Simulation sim)
      : doc_(std::make_shared<const nlohmann::json>(std::move(doc))), sim_(std::move(sim)) {}

  static std::shared_ptr<CompiledScene> from_file(const std::string& path, const std::vector<std::string>& sets) {
    nlohmann::json doc = scene::read_scene_file(path);
    return compile(std::move(doc), sets, "null");
  }
  static std::shared_ptr<CompiledScene> from_text(const std::string& text, const std::vector<std::string>& sets) {
    return compile(scene::parse_json_text(text, "scene"), sets, "null");
  }
  // This scene's document with the `--set` assignments applied in order, then the JSON merge patch (RFC
  // 7386: objects merge, a null removes the member), compiled.
  std::shared_ptr<CompiledScene> with(const std::vector<std::string>& sets, const std::string& patch) const {
    return compile(*doc_, sets, patch);
  }

  const scene::Simulation& simulation() const { return sim_; }
  std::string document() const { return doc_->dump(); }

  std::shared_ptr<RunOutput> run(const std::function<void(double)>& progress) const { return run_simulation(sim_, progress); }

  // The run with /parameters/<names[i]> = values[i]: the values bound into the scene compiled once with
  // those parameters free, or, where that cannot be (a parameter the compiler needs as a number, a value
  // of 0, a Lur'e scene), the document with the values written in, compiled.
  std::shared_ptr<RunOutput> run_with_parameters(const std::vector<std::string>& names, const std::vector<double>& values,
                                                 const std::function<void(double)>& progress) {
    if (names.size() != values.size()) throw std::invalid_argument("as many parameter values as names");
    std::optional<scene::Simulation> bound;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(parametric_mu_);
      if (sim_.lagrangian() && parametric_names_ != names) {
        parametric_.reset();
        parametric_names_ = names;
        try {
          parametric_ = std::make_unique<scene::ParametricLagrangianScene>(*doc_, names);
        } catch (const std::exception&) {
          // Not compilable with these parameters free: every such run compiles its document (and reports
          // what is wrong with it, if anything is).
        }
      }
      if (parametric_) {
        try {
          const scene::LagrangianScene& nominal = parametric_->nominal();
          bound = scene::Simulation::from_scene(parametric_->bind(values, nominal.q0, nominal.v0), {}, *doc_);
        } catch (const std::invalid_argument&) {
          // A value (or a quantity of values alone) of 0: compiled from the document below.
        }
      }
    }
    if (bound) return run_simulation(*bound, progress);
    nlohmann::json doc = *doc_;
    for (std::size_t i = 0; i < names.size(); ++i) doc["parameters"][names[i]] = values[i];
    return run_simulation(scene::Simulation::from_json(doc), progress);
  }

 private:
  static std::shared_ptr<CompiledScene> compile(nlohmann::json doc, const std::vector<std::string>& sets, const std::string& patch) {
    for (const std::string& s : sets) scene::apply_override(doc, s);
    if (patch != "null") doc.merge_patch(scene::parse_json_text(patch, "overrides"));
    std::optional<scene::Simulation> sim;
    {
      py::gil_scoped_release release;
      sim = scene::Simulation::from_json(doc);
    }
    return std::make_shared<CompiledScene>(std::move(doc), std::move(*sim));
  }

  std::shared_ptr<RunOutput> run_simulation(const scene::Simulation& sim, const std::function<void(double)>& progress) const {
    auto out = std::make_shared<RunOutput>(RunOutput{sim, sim_, nullptr, {}, {}});
    const std::int64_t every = std::max<std::int64_t>(1, sim.output_every());
    out->table = std::make_shared<TrajectoryTable>(sim.dof(), static_cast<int>(sim.signal_names().size()), sim.planned_steps() / every + 2);
    PythonControl control(out->table.get(), progress);
    {
      py::gil_scoped_release release;
      out->summary = sim.run(&control, &out->diagnostics);
    }
    control.raise_if_stopped();
    return out;
  }

  std::shared_ptr<const nlohmann::json> doc_;
  scene::Simulation sim_;
  std::mutex parametric_mu_;
  std::vector<std::string> parametric_names_;
  std::unique_ptr<scene::ParametricLagrangianScene> parametric_;
};

// A study of the scene document `doc_text`: over step sizes and schemes (study.h; `settings_text` as a
// server's study object: {"h": [...], "schemes": [...], ...}), or, with {"periods": [...], "laws": [...]},
// a tracking scene's digital controller over sampling periods (sampling_study.h). The result as JSON text.
std::string run_study_json(const std::string& doc_text, const std::string& settings_text) {
  const nlohmann::json doc = scene::parse_json_text(doc_text, "scene");
  const nlohmann::json settings = scene::parse_json_text(settings_text, "study");
  std::atomic<bool> stop{false};
  std::string out;
  if (settings.is_object() && settings.contains("periods")) {
    if (!settings["periods"].is_array() || settings["periods"].empty())
      throw scene::SceneError("/periods", "expected a non-empty list of sampling periods");
    std::vector<double> periods;
    for (std::size_t i = 0; i < settings["periods"].size(); ++i) {
      const auto& p = settings["periods"][i];
      if (!p.is_number()) throw scene::SceneError("/periods/" + std::to_string(i), "expected a number");
      periods.push_back(p.get<double>());
    }
    std::vector<std::string> laws = {"implicit", "explicit"};
    if (settings.contains("laws")) {
      if (!settings["laws"].is_array()) throw scene::SceneError("/laws", "expected a list of law names");
      laws.clear();
      for (std::size_t i = 0; i < settings["laws"].size(); ++i) {
        if (!settings["laws"][i].is_string()) throw scene::SceneError("/laws/" + std::to_string(i), "expected a law name");
        laws.push_back(settings["laws"][i].get<std::string>());
      }
    }
    for (const auto& [key, value] : settings.items())
      if (key != "periods" && key != "laws") throw scene::SceneError("/" + scene::json_pointer_token(key), "unknown study option");
    run_beside_python([&] { out = scene::run_sampling_study(doc, periods, laws).to_json().dump(); }, stop, {});
    return out;
  }
  const scene::LagrangianScene sc = scene::load_scene(doc);
  scene::StudySettings st = scene::study_settings_from_json(settings, "");
  scene::check_study_settings(sc, st);
  st.cancel = &stop;
  run_beside_python([&] { out = scene::run_study(sc, st).to_json().dump(); }, stop, {});
  return out;
}

// A campaign (campaign.h) from its spec's JSON text, paths in it relative to `base_dir`, into `out_dir`,
// as `moreau campaign SPEC --out DIR -j JOBS` runs it: resumable, the same files, and the figures once
// every sample is present. `progress(done, total)` is called from Python's thread. Returns
// {"ran", "skipped", "steps", "stopped", "summarized", "figures": [paths]}.
py::dict run_campaign_dir(const std::string& spec_text, const std::string& base_dir, const std::string& out_dir, int jobs,
                          const std::function<void(std::int64_t, std::int64_t)>& progress) {
  const scene::CampaignSpec spec = scene::CampaignSpec::from_json(scene::parse_json_text(spec_text, "campaign"), base_dir);
  std::atomic<bool> stop{false};
  std::atomic<std::int64_t> done{-1}, total{0};
  std::int64_t reported = -1;
  scene::CampaignRunOptions options;
  options.workers = std::max(1, jobs);
  options.stop = &stop;
  options.progress = [&](std::int64_t d, std::int64_t t) {
    total = t;
    done = d;
  };
  scene::CampaignRunResult r;
  std::vector<std::string> figures;
  run_beside_python(
      [&] {
        r = scene::run_campaign(spec, out_dir, options);
        if (r.summarized && !r.stopped) figures = scene::write_campaign_figures(out_dir);
      },
      stop,
      [&] {
        const std::int64_t d = done;
        if (progress && d >= 0 && d != reported) {
          reported = d;
          progress(d, total);
        }
      });
  py::dict result;
  result["ran"] = r.ran;
  result["skipped"] = r.skipped;
  result["steps"] = r.steps;
  result["stopped"] = r.stopped;
  result["summarized"] = r.summarized;
  result["figures"] = figures;
  return result;
}

}  // namespace
}  // namespace moreau::python

PYBIND11_MODULE(_moreau, m) {
  using namespace moreau;
  using namespace moreau::python;
  m.doc() = "The compiled part of the package moreau: use the package (import moreau), not this module.";

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const scene::SceneError& e) {
      raise_scene_error(e);
    }
  });

  py::class_<TrajectoryTable, std::shared_ptr<TrajectoryTable>>(m, "TrajectoryTable", py::buffer_protocol())
      .def_buffer([](TrajectoryTable& t) {
        return py::buffer_info(t.data(), sizeof(double), py::format_descriptor<double>::format(), 2, {t.rows(), t.columns()},
                               {static_cast<py::ssize_t>(sizeof(double) * t.columns()), static_cast<py::ssize_t>(sizeof(double))},
                               /*readonly=*/true);
      })
      .def_property_readonly("rows", &TrajectoryTable::rows)
      .def_property_readonly("columns", &TrajectoryTable::columns);

  py::class_<RunOutput, std::shared_ptr<RunOutput>>(m, "RunOutput")
      // The table as a numpy array whose base is the TrajectoryTable: no copy, and the memory lives as long
      // as any view of it (the package marks it read-only).
      .def_property_readonly("array",
                             [](const RunOutput& r) {
                               const TrajectoryTable& t = *r.table;
                               py::array_t<double> a(
                                   {t.rows(), t.columns()},
                                   {static_cast<py::ssize_t>(sizeof(double) * t.columns()), static_cast<py::ssize_t>(sizeof(double))},
                                   t.data(), py::cast(r.table));
                               return a;
                             })
      .def_property_readonly("status", [](const RunOutput& r) { return std::string(to_string(r.summary.status)); })
      .def("report_json", &RunOutput::report_json)
      .def("report_text", &RunOutput::report_text)
      .def("hypothesis_failure", [](const RunOutput& r) { return r.sim.hypothesis_failure(r.summary); })
      .def("figure", &RunOutput::figure, py::arg("kind"), py::arg("format"), py::arg("width"), py::arg("height"), py::arg("title"),
           py::arg("robust_y") = false);

  py::class_<CompiledScene, std::shared_ptr<CompiledScene>>(m, "CompiledScene")
      .def_static("from_file", &CompiledScene::from_file, py::arg("path"), py::arg("sets"))
      .def_static("from_text", &CompiledScene::from_text, py::arg("text"), py::arg("sets"))
      .def("with_overrides", &CompiledScene::with, py::arg("sets"), py::arg("patch"))
      .def("document", &CompiledScene::document)
      .def("run", &CompiledScene::run, py::arg("progress"))
      .def("run_with_parameters", &CompiledScene::run_with_parameters, py::arg("names"), py::arg("values"), py::arg("progress"))
      .def_property_readonly("name", [](const CompiledScene& s) { return s.simulation().name(); })
      .def_property_readonly("system_type", [](const CompiledScene& s) { return s.simulation().system_type(); })
      .def_property_readonly("scheme", [](const CompiledScene& s) { return std::string(scene::scheme_name(s.simulation().scheme())); })
      .def_property_readonly("dof", [](const CompiledScene& s) { return s.simulation().dof(); })
      .def_property_readonly("position_names", [](const CompiledScene& s) { return s.simulation().position_names(); })
      .def_property_readonly("velocity_names", [](const CompiledScene& s) { return s.simulation().velocity_names(); })
      .def_property_readonly("signal_names", [](const CompiledScene& s) { return s.simulation().signal_names(); })
      .def_property_readonly("t0", [](const CompiledScene& s) { return s.simulation().t0(); })
      .def_property_readonly("t_end", [](const CompiledScene& s) { return s.simulation().t_end(); })
      .def_property_readonly("h", [](const CompiledScene& s) { return s.simulation().h(); })
      .def_property_readonly("planned_steps", [](const CompiledScene& s) { return s.simulation().planned_steps(); })
      .def_property_readonly("unread_parameters", [](const CompiledScene& s) {
        const scene::Simulation& sim = s.simulation();
        return sim.lagrangian() ? sim.lagrangian()->unread_parameters : sim.lure()->unread_parameters;
      });

  m.def("study", &run_study_json, py::arg("doc"), py::arg("settings"));
  m.def("campaign", &run_campaign_dir, py::arg("spec"), py::arg("base_dir"), py::arg("out_dir"), py::arg("jobs"), py::arg("progress"));
  m.def(
      "read_scene_file", [](const std::string& path) { return scene::read_scene_file(path).dump(); }, py::arg("path"));
}
