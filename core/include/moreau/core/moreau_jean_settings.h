// The options of the Moreau-Jean scheme (eq. (8) of Brogliato 2003), shared by its dense integrator
// (moreau_jean_integrator.h) and its large-contact integrator (large_contact_integrator.h).
#pragma once

#include "moreau/core/time_grid.h"

namespace moreau {

// How Q^{k+1} follows from the step's velocities (moreau_jean_integrator.h, "Position update").
enum class PositionUpdate { kMdi, kStandard };

// The grid (a fixed step) and the scheme's own options.
struct MoreauJeanSettings : TimeGrid {
  PositionUpdate position_update = PositionUpdate::kMdi;
  bool correct_positions = false;
  int max_recorded_impacts = 10000;
};

}  // namespace moreau
