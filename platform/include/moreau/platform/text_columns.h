// Columns of a table for people: a cell padded to a width, on the left or on the right.
#pragma once

#include <cstddef>
#include <string>

namespace moreau::platform {

// `text` followed by spaces up to `width` characters (unchanged when it is as long already).
inline std::string pad_right(std::string text, std::size_t width) {
  if (text.size() < width) text.append(width - text.size(), ' ');
  return text;
}

// Spaces up to `width` characters, then `text` (numbers, aligned on their last digit).
inline std::string pad_left(std::string text, std::size_t width) {
  if (text.size() < width) text.insert(0, width - text.size(), ' ');
  return text;
}

}  // namespace moreau::platform
