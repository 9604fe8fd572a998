// Included first in every translation unit of the project (see the top-level CMakeLists.txt).
//
// nlohmann::json states its preconditions with JSON_ASSERT, which is assert() by default and so vanishes
// in a release build. The one that matters most: operator[] on a const object with a key it does not
// hold dereferences end(), which is undefined behaviour, not an exception. In a release build that read
// was garbage or a crash depending on the heap, so a test that did it failed only now and then. Defined
// here, the preconditions are checked in every build type and a violation stops the process at once,
// naming the file and line, the same way each time. Parsing is not on any hot path; the cost is a
// compare per checked call.
#pragma once
#include <cstdio>
#include <cstdlib>

#define JSON_ASSERT(condition)        \
  ((condition) ? static_cast<void>(0) \
               : (std::fprintf(stderr, "%s:%d: nlohmann::json precondition failed: %s\n", __FILE__, __LINE__, #condition), std::abort()))
