// Shared by impact_test.cc and impact_unconstrained_test.cc: a shipped scene read from scenes/, an
// observer that records every sample, and a run of a scene with its contact diagnostics.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "moreau/scene/scene.h"

namespace moreau::scene {
namespace {

using nlohmann::json;

inline json Scene(const std::string& name) { return read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/" + name); }

struct Recorder : RunObserver {
  std::vector<double> t, q, v;
  int n = 0;
  void on_sample(const Sample& s) override {
    n = s.n;
    t.push_back(s.t);
    q.insert(q.end(), s.q, s.q + s.n);
    v.insert(v.end(), s.v, s.v + s.n);
  }
};

struct ContactRun {
  LagrangianScene scene;
  RunSummary summary;
  ContactDiagnostics diag;
  Recorder rec;
};

inline ContactRun RunContacts(const json& doc) {
  ContactRun r{load_scene(doc), {}, {}, {}};
  r.summary = run_scene(r.scene, &r.rec, &r.diag);
  EXPECT_EQ(r.summary.status, RunStatus::kCompleted) << r.summary.message;
  return r;
}

}  // namespace
}  // namespace moreau::scene
