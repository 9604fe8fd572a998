// Shared by impact_test.cc and impact_unconstrained_test.cc: a shipped scene read from scenes/, an
// observer that records every sample, and a run of a scene with its contact diagnostics.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "moreau/scene/scene.h"
#include "support/scene_run.h"

namespace moreau::scene {
namespace {

using nlohmann::json;

inline json Scene(const std::string& name) { return test_support::shipped_scene(name); }
using Recorder = test_support::SampleRecorder;

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
