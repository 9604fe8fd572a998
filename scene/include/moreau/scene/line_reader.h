// Reading text input line by line with a bound on each line: input that never ends a line (/dev/zero, a
// binary file, an endless FIFO) is refused at the bound instead of being read until memory runs out.
#pragma once

#include <cstddef>
#include <istream>
#include <stdexcept>
#include <string>

namespace moreau::scene {

// Reads the next line of `in` into `line`, without its '\n'. Returns false at the end of the input.
// Throws std::runtime_error ("<where> is longer than <limit>") once the line exceeds `max_bytes`;
// `where` names the line in that message (e.g. "'traj.csv' line 3").
inline bool read_line(std::istream& in, std::string& line, std::size_t max_bytes, const std::string& where, const std::string& limit) {
  line.clear();
  std::streambuf* buf = in.rdbuf();
  if (!buf) return false;
  for (;;) {
    const auto c = buf->sbumpc();
    if (c == std::char_traits<char>::eof()) {
      in.setstate(std::ios::eofbit);
      return !line.empty();
    }
    if (c == '\n') return true;
    if (line.size() >= max_bytes) throw std::runtime_error(where + " is longer than " + limit);
    line.push_back(static_cast<char>(c));
  }
}

}  // namespace moreau::scene
