// GET /v1/jobs/{id}/kinematics: where every link of a URDF job's robot is at the times of its trajectory,
// for a viewer that draws the robot (the web page's 3D view, server/web/robot3d.js) and does no
// kinematics of its own. The robot is read from the job's stored scene (scene.json, the URDF inline), its
// links placed by the model's forward kinematics (scene::link_poses); the joint positions are the stored
// trajectory's rows, those written so far while the job runs.
#pragma once

#include <cstddef>

#include "api_context.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

// Frames one answer carries at most (max_samples' upper bound), and link poses at most: a robot of many
// links gets fewer frames (kMaxKinematicsPoses / links), so that an answer stays within a few MB.
inline constexpr int kMaxKinematicsFrames = 1000;
inline constexpr int kDefaultKinematicsFrames = 200;
inline constexpr std::size_t kMaxKinematicsPoses = 100'000;

void job_kinematics(ApiContext& api, const httplib::Request& req, httplib::Response& res);

}  // namespace moreau::server
