// moreau study SCENE --h 1e-1:1e-5:9 --schemes abl,explicit,regularized : error against run time and the
// order of convergence, as a table (text, JSON, CSV) and the `work` and `order` figures.
// moreau study TRACKING-SCENE --periods 1e-2:1e-4:5 --laws implicit,explicit : the digital controller's
// tracking error and chattering against its sampling period (sampling_study.h), and the `order` figure
// of the error against T_s.
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

#include "commands.h"
#include "figure_output.h"
#include "moreau/render/render.h"
#include "moreau/analysis/figures.h"
#include "moreau/analysis/sampling_study.h"
#include "moreau/analysis/study.h"

namespace moreau::cli {
namespace {

struct StudyOptions {
  std::string scene_path, ladder = "1e-1:1e-5:9", schemes = "abl,explicit,regularized";
  std::vector<std::string> overrides;
  std::optional<double> reference_h;
  double epsilon = 1e-3;
  std::string regularization = "tanh";
  int eval_points = 1000, repeats = 3;
  bool json = false;
  std::string csv, work_png, order_png;
  std::string periods, laws = "implicit,explicit";  // a sampling study when periods is given
};

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("cannot write '" + path + "'");
}

int sampling_study(const StudyOptions& opt) {
  scene::SamplingStudyResult result;
  try {
    nlohmann::json doc = scene::read_scene_file(opt.scene_path);
    for (const auto& o : opt.overrides) scene::apply_override(doc, o);
    std::vector<std::string> laws;
    std::stringstream list(opt.laws);
    for (std::string law; std::getline(list, law, ',');) laws.push_back(law);
    result = scene::run_sampling_study(doc, scene::parse_ladder(opt.periods), laws);
  } catch (const scene::SceneError& e) {
    std::cerr << "moreau study: " << e.what() << "\n";
    return 2;
  }
  try {
    if (!opt.csv.empty()) write_text(opt.csv, result.to_csv());
    // The tracking error at the end against T_s (--order) and against the run's wall time (--work).
    std::vector<render::SchemeRuns> runs;
    for (const auto& r : result.rows) {
      if (runs.empty() || runs.back().scheme != r.law) runs.push_back({r.law, {}, {}, {}});
      runs.back().h.push_back(r.period);
      runs.back().error.push_back(r.error_final);
      runs.back().run_time_s.push_back(r.wall_seconds);
    }
    render::FigureOptions o;
    o.y_label = "|e| at t_end";
    if (!opt.order_png.empty()) {
      o.title = result.scene + ": the tracking error at the end against the sampling period";
      o.x_label = "sampling period T_s";
      render::render_png(render::order_figure(runs, o), opt.order_png);
    }
    if (!opt.work_png.empty()) {
      o.title = result.scene + ": the tracking error at the end against run time";
      o.x_label = "";
      render::render_png(render::work_figure(runs, o), opt.work_png);
    }
  } catch (const std::exception& e) {
    std::cerr << "moreau study: " << e.what() << "\n";
    return 1;
  }
  std::cout << (opt.json ? result.to_json().dump(2) + "\n" : result.to_text());
  return 0;
}

int study(const StudyOptions& opt) {
  if (!opt.periods.empty()) return sampling_study(opt);
  scene::StudyResult result;
  try {
    nlohmann::json doc = scene::read_scene_file(opt.scene_path);
    for (const auto& o : opt.overrides) scene::apply_override(doc, o);
    const scene::LagrangianScene sc = scene::load_scene(doc);
    warn_unread_parameters("moreau study", sc.unread_parameters);
    scene::StudySettings st;
    st.h = scene::parse_ladder(opt.ladder);
    st.schemes = scene::parse_study_schemes(opt.schemes);
    st.reference_h = opt.reference_h;
    st.epsilon = opt.epsilon;
    st.regularization = *scene::regularization_from_name(opt.regularization);  // CLI11 checked the name
    st.eval_points = opt.eval_points;
    st.repeats = opt.repeats;
    result = scene::run_study(sc, st);
  } catch (const scene::SceneError& e) {
    std::cerr << "moreau study: " << e.what() << "\n";
    return 2;
  }
  try {
    if (!opt.csv.empty()) write_text(opt.csv, result.to_csv());
    if (!opt.work_png.empty()) render::render_png(scene::study_figure(scene::StudyFigure::kWork, result), opt.work_png);
    if (!opt.order_png.empty()) render::render_png(scene::study_figure(scene::StudyFigure::kOrder, result), opt.order_png);
  } catch (const std::exception& e) {
    std::cerr << "moreau study: " << e.what() << "\n";
    return 1;
  }
  std::cout << (opt.json ? result.to_json().dump(2) + "\n" : result.to_text());
  return 0;
}

}  // namespace

void register_study_command(CLI::App& app, Actions& actions) {
  auto opt = std::make_shared<StudyOptions>();
  auto* cmd = app.add_subcommand("study", "Error against run time and order of convergence over a ladder of step sizes");
  cmd->add_option("scene", opt->scene_path, "Scene file")->required();
  cmd->add_option("--h", opt->ladder, "Step sizes: FIRST:LAST:COUNT (log-spaced) or a comma list")->capture_default_str();
  cmd->add_option("--schemes", opt->schemes, "Comma list of abl, explicit, regularized")->capture_default_str();
  cmd->add_option("--set", opt->overrides, "Override a scene field: PATH=VALUE");
  cmd->add_option("--reference-h", opt->reference_h,
                  "Use an abl run at this h as the reference (default: the exact solution if the scene has one, else min h / 10)");
  cmd->add_option("--epsilon", opt->epsilon, "Width of the regularized sign")->capture_default_str();
  cmd->add_option("--regularization", opt->regularization, "tanh or saturation")->check(CLI::IsMember({"tanh", "saturation"}));
  cmd->add_option("--eval-points", opt->eval_points, "Common times at which errors are measured")->capture_default_str();
  cmd->add_option("--repeats", opt->repeats, "Timed runs per point (the minimum is kept)")->capture_default_str();
  cmd->add_flag("--json", opt->json, "Print the table as JSON");
  cmd->add_option("--csv", opt->csv, "Write the table as CSV");
  cmd->add_option("--work", opt->work_png, "Write the work figure (error against run time) as PNG");
  cmd->add_option("--order", opt->order_png, "Write the order figure (error against h, fitted slope) as PNG");
  cmd->add_option("--periods", opt->periods,
                  "A tracking scene's digital controller over sampling periods T_s: FIRST:LAST:COUNT or a comma list");
  cmd->add_option("--laws", opt->laws, "With --periods: comma list of implicit, explicit, saturated")->capture_default_str();
  actions[cmd] = [opt] { return study(*opt); };
}

}  // namespace moreau::cli
