// SVG backend: the same scene as the PNG backend, written as SVG 1.1 text. Series are <polyline>s
// (decimated like the raster output, so dense series stay small), clipped to their plot area.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>
#include <type_traits>

#include "backends.h"

namespace moreau::render::detail {
namespace {

std::string escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string num(double v) {
  // Pixel coordinates: two decimals are far below what any viewer resolves.
  v = std::clamp(v, -1e6, 1e6);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v);
  std::string s = buf;
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  if (s == "-0") s = "0";
  return s;
}

std::string color(Rgba c) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", c.r, c.g, c.b);
  return buf;
}

std::string opacity(Rgba c, const char* attr) {
  if (c.a == 255) return {};
  char buf[48];
  std::snprintf(buf, sizeof buf, " %s=\"%.3f\"", attr, c.a / 255.0);
  return buf;
}

class Writer {
 public:
  explicit Writer(const Scene& scene) : scene_(scene) {}

  std::string write() {
    os_ << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
        << "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"" << scene_.width << "\" height=\"" << scene_.height
        << "\" viewBox=\"0 0 " << scene_.width << " " << scene_.height << "\">\n";
    // Clip paths, one per distinct clip rectangle (the plot areas).
    os_ << "<defs>\n";
    for (const Item& item : scene_.items) declare_clip(clip_of(item));
    os_ << "</defs>\n";
    os_ << "<rect width=\"100%\" height=\"100%\" fill=\"#ffffff\"/>\n";
    os_ << "<g font-family=\"DejaVu Sans, Verdana, Arial, sans-serif\">\n";
    for (const Item& item : scene_.items) std::visit([this](const auto& it) { this->add(it); }, item);
    os_ << "</g>\n</svg>\n";
    return os_.str();
  }

 private:
  static std::optional<Rect> clip_of(const Item& item) {
    return std::visit(
        [](const auto& it) -> std::optional<Rect> {
          if constexpr (std::is_same_v<std::decay_t<decltype(it)>, Text>)
            return std::nullopt;
          else
            return it.clip;
        },
        item);
  }

  static std::string key(const Rect& r) { return num(r.x) + "," + num(r.y) + "," + num(r.w) + "," + num(r.h); }

  void declare_clip(const std::optional<Rect>& r) {
    if (!r || clips_.count(key(*r))) return;
    const std::string id = "plot" + std::to_string(clips_.size());
    clips_[key(*r)] = id;
    os_ << "<clipPath id=\"" << id << "\"><rect x=\"" << num(r->x) << "\" y=\"" << num(r->y) << "\" width=\"" << num(r->w) << "\" height=\""
        << num(r->h) << "\"/></clipPath>\n";
  }

  std::string clip_attr(const std::optional<Rect>& r) {
    if (!r) return {};
    return " clip-path=\"url(#" + clips_.at(key(*r)) + ")\"";
  }

  void add(const FillRect& f) {
    os_ << "<rect x=\"" << num(f.rect.x) << "\" y=\"" << num(f.rect.y) << "\" width=\"" << num(f.rect.w) << "\" height=\"" << num(f.rect.h)
        << "\" fill=\"" << color(f.color) << "\"" << opacity(f.color, "fill-opacity") << clip_attr(f.clip) << "/>\n";
  }

  void add(const Stroke& s) {
    const std::string style =
        " fill=\"none\" stroke=\"" + color(s.color) + "\" stroke-width=\"" + num(s.width) + "\"" + opacity(s.color, "stroke-opacity") +
        (s.dashed ? " stroke-dasharray=\"" + num(std::max(4.0, 4 * s.width)) + " " + num(std::max(3.0, 3 * s.width)) + "\""
                  : std::string()) +
        clip_attr(s.clip);
    if (s.series) {
      os_ << "<polyline stroke-linejoin=\"round\" stroke-linecap=\"round\"" << style << " points=\"";
      for (std::size_t i = 0; i < s.points.size(); ++i) os_ << (i ? " " : "") << num(s.points[i].x) << "," << num(s.points[i].y);
      os_ << "\"/>\n";
      return;
    }
    os_ << "<path" << style << " d=\"";
    for (std::size_t i = 0; i < s.points.size(); ++i) os_ << (i ? " L" : "M") << num(s.points[i].x) << " " << num(s.points[i].y);
    os_ << "\"/>\n";
  }

  void add(const Dots& d) {
    os_ << "<g fill=\"" << color(d.color) << "\"" << opacity(d.color, "fill-opacity") << clip_attr(d.clip) << ">";
    for (const Point& c : d.centers) os_ << "<circle cx=\"" << num(c.x) << "\" cy=\"" << num(c.y) << "\" r=\"" << num(d.radius) << "\"/>";
    os_ << "</g>\n";
  }

  void add(const Text& t) {
    const char* anchor = t.align == Text::Align::left ? "start" : t.align == Text::Align::center ? "middle" : "end";
    os_ << "<text x=\"" << num(t.x) << "\" y=\"" << num(t.y) << "\" font-size=\"" << t.size_px << "\" text-anchor=\"" << anchor
        << "\" fill=\"" << color(t.color) << "\"";
    if (t.bold) os_ << " font-weight=\"bold\"";
    if (t.vertical) os_ << " transform=\"rotate(-90 " << num(t.x) << " " << num(t.y) << ")\"";
    os_ << ">" << escape(t.text);
    if (!t.superscript.empty())
      os_ << "<tspan dy=\"" << -superscript_rise(t.size_px) << "\" font-size=\"" << superscript_px(t.size_px) << "\">"
          << escape(t.superscript) << "</tspan>";
    os_ << "</text>\n";
  }

  const Scene& scene_;
  std::ostringstream os_;
  std::map<std::string, std::string> clips_;
};

}  // namespace

std::string write_svg(const Scene& scene) { return Writer(scene).write(); }

}  // namespace moreau::render::detail
