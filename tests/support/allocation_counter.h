// Counts heap allocations made through the global operator new, which allocation_counter.cc replaces.
// Link that file only into test binaries that measure allocations.
#pragma once

namespace moreau::testing {
long allocations();
}
