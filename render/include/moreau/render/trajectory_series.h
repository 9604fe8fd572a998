// A trajectory read back from its CSV (scene/trajectory_csv.h) as the series the figures draw: the one
// bridge between the two, used by `moreau plot` and the server's figures alike.
#pragma once

#include <utility>

#include "moreau/render/figures.h"
#include "moreau/scene/trajectory_csv.h"

namespace moreau::render {

inline TimeSeriesData time_series(scene::TrajectoryColumns columns) {
  TimeSeriesData data;
  data.t = std::move(columns.t);
  data.h = std::move(columns.h);
  data.q_names = std::move(columns.q_names);
  data.v_names = std::move(columns.v_names);
  data.q = std::move(columns.q);
  data.v = std::move(columns.v);
  data.energy = std::move(columns.energy);
  data.energy_label = "E = 1/2 <M v, v>";
  return data;
}

}  // namespace moreau::render
