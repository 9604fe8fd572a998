// A double as text: the one formatter of the project, in three forms.
//
//   shortest(v)              machine output (CSV cells, labels such as "restitution=0.8", expression text,
//                            numbers quoted in a message that someone may read back): the shortest decimal
//                            text that std::strtod, std::from_chars and Python's float() read back as the
//                            same double, bit for bit (std::to_chars without a format; -0.0 is "-0").
//                            0.1 is "0.1", never the 17 digits "0.10000000000000001" of %.17g.
//   significant(v, digits)   text for people (reports, messages): v rounded to `digits` significant digits,
//                            as printf's %.<digits>g writes it in the C locale ("0.333", "1e-05",
//                            "1.5e+10"), trailing zeros dropped. It does not read back exactly.
//   fixed(v, decimals)       `decimals` digits after the point, as printf's %.<decimals>f ("2.00").
//
// One spelling, in all three, of the doubles that are not finite numbers: "nan" (whatever its sign bit and
// payload: printf writes "-nan" for some), "inf" and "-inf", the words strtod, from_chars and float() read
// back. JSON has neither; a JSON writer turns them into null (scene/include/moreau/scene/json_number.h).
//
// Locale-independent (std::to_chars, never printf), allocation-free in write_shortest, and pure: no I/O,
// so core/ may use it.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace moreau::platform {

// The most characters shortest() writes: a sign, 17 significant digits, the point and "e-308".
inline constexpr std::size_t kShortestMaxChars = 24;

// "nan", "inf" or "-inf" for a value that is not finite; empty for a finite one.
std::string_view non_finite_text(double v);

// Writes shortest(v) into [first, last) and returns one past its last character. A range of at least
// kShortestMaxChars characters always suffices; a shorter one that cannot hold the text throws
// std::length_error. For writers that fill a buffer (the trajectory CSV) and must not allocate.
char* write_shortest(char* first, char* last, double v);

// The shortest text that reads back as v, bit for bit (see above).
std::string shortest(double v);

// v rounded to `digits` significant digits (%.<digits>g), `digits` taken within [1, 17]: more than 17 never
// changes a double's value, and printf reads 0 as 1.
std::string significant(double v, int digits);

// v with `decimals` digits after the point (%.<decimals>f), `decimals` taken within [0, 17].
std::string fixed(double v, int decimals);

}  // namespace moreau::platform
