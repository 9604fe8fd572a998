// SVG backend: the same scene as the PNG backend, written as SVG 1.1 text. Series are <polyline>s
// (decimated like the raster output, so dense series stay small), clipped to their plot area.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <sstream>
#include <type_traits>

#include "backends.h"
#include "moreau/platform/number_text.h"

namespace moreau::render::detail {

std::string xml_text(std::string_view s) {
  static const char kReplacement[] = "\xEF\xBF\xBD";  // U+FFFD
  std::string out;
  out.reserve(s.size());
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  for (std::size_t i = 0; i < s.size();) {
    const unsigned char c = byte(i);
    if (c < 0x80) {
      switch (c) {
        case '&': out += "&amp;"; break;
        case '<': out += "&lt;"; break;
        case '>': out += "&gt;"; break;
        case '"': out += "&quot;"; break;
        case '\t':
        case '\n':
        case '\r': out += static_cast<char>(c); break;
        default:
          if (c < 0x20 || c == 0x7F)
            out += kReplacement;
          else
            out += static_cast<char>(c);
      }
      ++i;
      continue;
    }
    // A UTF-8 sequence: its length, and its code point if it is valid (shortest form, no surrogate).
    std::size_t len = 0;
    std::uint32_t cp = 0, min = 0;
    if ((c & 0xE0) == 0xC0) {
      len = 2, cp = c & 0x1Fu, min = 0x80;
    } else if ((c & 0xF0) == 0xE0) {
      len = 3, cp = c & 0x0Fu, min = 0x800;
    } else if ((c & 0xF8) == 0xF0) {
      len = 4, cp = c & 0x07u, min = 0x10000;
    }
    bool valid = len > 0 && i + len <= s.size();
    for (std::size_t k = 1; valid && k < len; ++k) {
      valid = (byte(i + k) & 0xC0) == 0x80;
      cp = (cp << 6) | (byte(i + k) & 0x3Fu);
    }
    valid = valid && cp >= min && cp <= 0x10FFFF && !(cp >= 0xD800 && cp <= 0xDFFF);
    if (!valid) {
      out += kReplacement;  // this byte; the next one starts afresh
      ++i;
      continue;
    }
    if ((cp >= 0x80 && cp <= 0x9F) || cp == 0xFFFE || cp == 0xFFFF)
      out += kReplacement;
    else
      out.append(s.substr(i, len));
    i += len;
  }
  return out;
}

namespace {

std::string num(double v) {
  // Pixel coordinates: two decimals are far below what any viewer resolves.
  v = std::clamp(v, -1e6, 1e6);
  std::string s = platform::fixed(v, 2);
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
  return std::string(" ") + attr + "=\"" + platform::fixed(c.a / 255.0, 3) + "\"";
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
    os_ << ">" << xml_text(t.text);
    if (!t.superscript.empty())
      os_ << "<tspan dy=\"" << -superscript_rise(t.size_px) << "\" font-size=\"" << superscript_px(t.size_px) << "\">"
          << xml_text(t.superscript) << "</tspan>";
    os_ << "</text>\n";
  }

  const Scene& scene_;
  std::ostringstream os_;
  std::map<std::string, std::string> clips_;
};

}  // namespace

std::string write_svg(const Scene& scene) { return Writer(scene).write(); }

}  // namespace moreau::render::detail
