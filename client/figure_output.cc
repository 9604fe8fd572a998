#include "figure_output.h"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "line_reader.h"
#include "moreau/render/render.h"

namespace moreau::cli {

TimeSeriesRecorder::TimeSeriesRecorder(std::vector<std::string> q_names, std::vector<std::string> v_names) {
  data_.q_names = std::move(q_names);
  data_.v_names = std::move(v_names);
  data_.q.resize(data_.q_names.size());
  data_.v.resize(data_.v_names.size());
  data_.energy_label = "E = 1/2 <M v, v>";
}

void TimeSeriesRecorder::on_sample(const Sample& s) {
  data_.t.push_back(s.t);
  data_.h.push_back(s.h);
  for (int i = 0; i < s.n && i < static_cast<int>(data_.q.size()); ++i) {
    data_.q[i].push_back(s.q[i]);
    data_.v[i].push_back(s.v[i]);
  }
  data_.energy.push_back(s.kinetic_energy);
}

void FigureFlags::add_to(CLI::App* cmd) {
  cmd->add_option("--size", size, "Figure size in pixels, WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--title", title, "Figure title");
  cmd->add_option("--coords", coordinates, "Coordinates to draw (0-based indices; default all)")->delimiter(',');
  cmd->add_option("--t0", t0, "Start of the time window");
  cmd->add_option("--t1", t1, "End of the time window");
  cmd->add_option("--y-scale", y_scale, "linear or log (default: the figure kind's)")
      ->check(CLI::IsMember({"linear", "log"}));
  cmd->add_option("--format", format, "png or svg (default: from the file name)")->check(CLI::IsMember({"png", "svg"}));
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
  if (eq == std::string::npos) return {"state", spec};
  return {spec.substr(0, eq), spec.substr(eq + 1)};
}

void write_figure(const std::string& kind, const render::TimeSeriesData& input, const FigureFlags& flags,
                  const std::string& path) {
  render::TimeSeriesData data = input;
  if (!data.converged_time) data.converged_time = exact_rest_time(data);
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
    if (c >= data.q.size())
      throw std::runtime_error("--coords: coordinate " + std::to_string(c) + " does not exist (there are " +
                               std::to_string(data.q.size()) + ")");
  opt.t0 = flags.t0;
  opt.t1 = flags.t1;
  if (flags.y_scale == "log") opt.y_scale = render::Scale::log;
  if (flags.y_scale == "linear") opt.y_scale = render::Scale::linear;

  render::Figure fig;
  if (kind == "state") fig = render::state_figure(data, opt);
  else if (kind == "energy") fig = render::energy_figure(data, opt);
  else if (kind == "step") fig = render::step_figure(data, opt);
  else if (kind == "phase") fig = render::phase_figure(data, opt);
  else throw std::runtime_error("unknown figure kind '" + kind + "' (expected state, energy, step or phase)");

  std::string format = flags.format;
  if (format.empty()) format = path.size() > 4 && path.substr(path.size() - 4) == ".svg" ? "svg" : "png";
  if (format == "svg") {
    std::ofstream out(path, std::ios::binary);
    out << render::render_svg(fig);
    if (!out) throw std::runtime_error("cannot write '" + path + "'");
  } else {
    render::render_png(fig, path);
  }
}

render::TimeSeriesData read_trajectory_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open '" + path + "'");
  // A row holds at most 2 kMaxDof + 3 numbers (about 3 KB): a longer line is not a trajectory, and a
  // file without line ends (/dev/zero) must not be read whole.
  constexpr std::size_t kMaxLine = std::size_t{1} << 20;
  auto next_line = [&](std::string& line, std::size_t row) {
    return read_line(in, line, kMaxLine, "'" + path + "' line " + std::to_string(row), "1 MiB");
  };
  std::string line;
  if (!next_line(line, 1)) throw std::runtime_error("'" + path + "' is empty");
  std::vector<std::string> cols;
  {
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cols.push_back(c);
  }
  // t, h, q_1..q_n, v_1..v_n, energy (and possibly more columns after energy).
  std::size_t energy_col = 0;
  for (std::size_t i = 0; i < cols.size(); ++i)
    if (cols[i] == "energy") energy_col = i;
  if (cols.size() < 5 || cols[0] != "t" || cols[1] != "h" || energy_col < 4 || (energy_col - 2) % 2 != 0)
    throw std::runtime_error("'" + path + "' is not a Moreau trajectory (header must be t,h,q...,v...,energy)");
  const std::size_t n = (energy_col - 2) / 2;
  render::TimeSeriesData data;
  for (std::size_t i = 0; i < n; ++i) {
    data.q_names.push_back(cols[2 + i]);
    data.v_names.push_back(cols[2 + n + i]);
  }
  data.q.resize(n);
  data.v.resize(n);
  data.energy_label = "E = 1/2 <M v, v>";
  std::size_t row = 1;
  while (next_line(line, row + 1)) {
    ++row;
    if (line.empty()) continue;
    std::vector<double> values;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) {
      char* end = nullptr;
      const double v = std::strtod(cell.c_str(), &end);
      if (end == cell.c_str() || *end != '\0' || !std::isfinite(v))
        throw std::runtime_error("'" + path + "' line " + std::to_string(row) + ": '" + cell + "' is not a finite number");
      values.push_back(v);
    }
    if (values.size() != cols.size())
      throw std::runtime_error("'" + path + "' line " + std::to_string(row) + ": expected " + std::to_string(cols.size()) +
                               " values, got " + std::to_string(values.size()));
    data.t.push_back(values[0]);
    data.h.push_back(values[1]);
    for (std::size_t i = 0; i < n; ++i) {
      data.q[i].push_back(values[2 + i]);
      data.v[i].push_back(values[2 + n + i]);
    }
    data.energy.push_back(values[energy_col]);
  }
  if (data.t.empty()) throw std::runtime_error("'" + path + "' has no rows");
  return data;
}

}  // namespace moreau::cli
