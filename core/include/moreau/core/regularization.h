// The smooth or saturated sign of the regularized peer (regularized_integrator.h), apart from the
// integrator: that header brings Boost's uBLAS, which compiles only as C++17, and scene settings name
// the kind without integrating.
#pragma once

namespace moreau {

// sgn_eps(v) = tanh(v / eps) (kTanh) or clamp(v / eps, -1, 1) (kSaturation).
enum class Regularization { kTanh, kSaturation };

}  // namespace moreau
