// What many scene tests start from: a shipped scene read from scenes/, and an observer that records every
// sample's t, q and v (q and v flat, n values a sample).
#pragma once

#include <string>
#include <vector>

#include "moreau/core/observer.h"
#include "moreau/scene/scene.h"

namespace moreau::test_support {

inline nlohmann::json shipped_scene(const std::string& name) {
  return scene::read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/" + name);
}

struct SampleRecorder : RunObserver {
  std::vector<double> t, q, v;
  int n = 0;
  void on_sample(const Sample& s) override {
    n = s.n;
    t.push_back(s.t);
    q.insert(q.end(), s.q, s.q + s.n);
    v.insert(v.end(), s.v, s.v + s.n);
  }
};

}  // namespace moreau::test_support
