// Counts heap allocations: the global operator new and the C allocator (malloc, calloc, realloc and the
// aligned ones), which allocation_counter.cc replaces.
// Link that file only into test binaries that measure allocations.
#pragma once

namespace moreau::testing {
long allocations();
}
