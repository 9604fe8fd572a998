#include "figure_output.h"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "moreau/render/render.h"
#include "moreau/analysis/figures.h"

namespace moreau::cli {

TimeSeriesRecorder::TimeSeriesRecorder(std::vector<std::string> q_names, std::vector<std::string> v_names,
                                       std::vector<std::string> signal_names) {
  data_.q_names = std::move(q_names);
  data_.v_names = std::move(v_names);
  data_.q.resize(data_.q_names.size());
  data_.v.resize(data_.v_names.size());
  data_.energy_label = "E = 1/2 <M v, v>";
  data_.signal_names = std::move(signal_names);
  data_.signals.resize(data_.signal_names.size());
}

void TimeSeriesRecorder::on_sample(const Sample& s) {
  data_.t.push_back(s.t);
  data_.h.push_back(s.h);
  for (int i = 0; i < s.n && i < static_cast<int>(data_.q.size()); ++i) {
    data_.q[i].push_back(s.q[i]);
    data_.v[i].push_back(s.v[i]);
  }
  data_.energy.push_back(s.kinetic_energy);
  for (int i = 0; i < s.m && i < static_cast<int>(data_.signals.size()); ++i) data_.signals[i].push_back(s.signals[i]);
}

void FigureFlags::add_to(CLI::App* cmd) {
  cmd->add_option("--size", size, "Figure size in pixels, WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--title", title, "Figure title");
  cmd->add_option("--coords", coordinates, "Coordinates to draw (0-based indices; default all)")->delimiter(',');
  cmd->add_option("--t0", t0, "Start of the time window");
  cmd->add_option("--t1", t1, "End of the time window");
  cmd->add_option("--y-scale", y_scale, "linear or log (default: the figure kind's)")->check(CLI::IsMember({"linear", "log"}));
  cmd->add_flag("--robust-y", robust_y,
                "State figure: each y axis over the 1st to 99th percentile of its values, a spike clipped and counted in the legend");
  cmd->add_option("--format", format, "png or svg (default: from the file name)")
      ->check(CLI::IsMember(scene::figure_names<scene::FigureFormat>()));
}

std::optional<double> exact_rest_time(const render::TimeSeriesData& data) {
  if (data.t.empty() || data.v.empty()) return std::nullopt;
  std::size_t first = data.t.size();
  for (std::size_t k = data.t.size(); k-- > 0;) {
    bool zero = true;
    for (const auto& v : data.v) zero = zero && v[k] == 0.0;
    if (!zero) break;
    first = k;
  }
  if (first == data.t.size()) return std::nullopt;
  return data.t[first];
}

std::pair<std::string, std::string> parse_figure_spec(const std::string& spec) {
  const std::size_t eq = spec.find('=');
  if (eq == std::string::npos) return {scene::figure_name(scene::default_figure<scene::TrajectoryFigure>()), spec};
  return {spec.substr(0, eq), spec.substr(eq + 1)};
}

namespace {

// The options the flags give a figure of n coordinates (--coords checked against n).
render::FigureOptions figure_options(const FigureFlags& flags, std::size_t n) {
  render::FigureOptions opt;
  int w = 0, h = 0;
  char x = 0;
  std::istringstream size(flags.size);
  if (!(size >> w >> x >> h) || x != 'x') throw std::runtime_error("--size must be WIDTHxHEIGHT, got '" + flags.size + "'");
  opt.width_px = w;
  opt.height_px = h;
  opt.title = flags.title;
  opt.coordinates = flags.coordinates;
  for (std::size_t c : opt.coordinates)
    if (c >= n)
      throw std::runtime_error("--coords: coordinate " + std::to_string(c) + " does not exist (there are " + std::to_string(n) + ")");
  opt.t0 = flags.t0;
  opt.t1 = flags.t1;
  if (flags.y_scale == "log") opt.y_scale = render::Scale::log;
  if (flags.y_scale == "linear") opt.y_scale = render::Scale::linear;
  opt.robust_y = flags.robust_y;
  return opt;
}

// Writes `fig` as --format says, else as the file name's extension says (.svg), else PNG.
void write_figure_file(const render::Figure& fig, const FigureFlags& flags, const std::string& path) {
  std::optional<scene::FigureFormat> format = scene::figure_from_name<scene::FigureFormat>(flags.format);  // "" when not given
  if (!format) format = path.size() > 4 && path.substr(path.size() - 4) == ".svg" ? scene::FigureFormat::kSvg : scene::FigureFormat::kPng;
  if (*format == scene::FigureFormat::kSvg) {
    std::ofstream out(path, std::ios::binary);
    out << render::render_svg(fig);
    if (!out) throw std::runtime_error("cannot write '" + path + "'");
  } else {
    render::render_png(fig, path);
  }
}

}  // namespace

void write_figure(scene::TrajectoryFigure kind, const render::TimeSeriesData& input, const FigureFlags& flags, const std::string& path) {
  render::TimeSeriesData data = input;
  if (!data.converged_time) data.converged_time = exact_rest_time(data);
  write_figure_file(scene::trajectory_figure(kind, data, figure_options(flags, data.q.size())), flags, path);
}

void write_tracking_comparison(const std::vector<std::pair<std::string, render::TimeSeriesData>>& runs, const FigureFlags& flags,
                               const std::string& path) {
  write_figure_file(render::tracking_comparison_figure(runs, figure_options(flags, runs.empty() ? 0 : runs.front().second.q.size())), flags,
                    path);
}

render::TimeSeriesData read_trajectory_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open '" + path + "'");
  render::TimeSeriesData data = scene::time_series(scene::read_trajectory_csv(in, "'" + path + "'"));
  // What the columns are (a Lur'e state, units, impacts), when `moreau run --out` wrote it beside them.
  const std::string meta_path = scene::trajectory_metadata_path(path);
  std::ifstream meta(meta_path, std::ios::binary);
  if (meta) {
    constexpr std::size_t kMaxMetadataBytes = std::size_t{16} << 20;
    std::string text(kMaxMetadataBytes + 1, '\0');
    meta.read(text.data(), static_cast<std::streamsize>(text.size()));
    text.resize(static_cast<std::size_t>(meta.gcount()));
    if (text.size() > kMaxMetadataBytes) throw std::runtime_error("'" + meta_path + "' is larger than 16 MiB");
    scene::label_from_metadata(data, text, "'" + meta_path + "'");
  }
  return data;
}

}  // namespace moreau::cli
