// GET /v1/jobs/{id}/kinematics against an independent forward kinematics: the shipped KUKA iiwa
// (scenes/iiwa14-joint-limit.json) is run, and every link's pose the route serves at a few times is held,
// to 1e-12, to the product of the URDF's transforms written out here from its text (origin xyz, then
// roll-pitch-yaw as Rz(yaw) Ry(pitch) Rx(roll), then the joint's rotation about its axis), with the joint
// positions of the stored trajectory's row at that time. Neither urdfdom's quaternions nor the model's
// Rodrigues form (rigid_body.cc) is in that product. A pendulum drawn with a box, a cylinder and a
// sphere (tests/server/shapes-pendulum.json) is held to its closed form, with its visuals as its URDF
// writes them. Also: the sampled form, a running job (the rows written so far), a queued job (links, no
// frames yet), a scene without a robot, and bad query parameters.
#include <chrono>
#include <cmath>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "moreau/scene/scene.h"
#include "server_fixture.h"

namespace {

using moreau::server::ServerConfig;
using moreau::server::testing::manipulator;
using moreau::server::testing::submit;
using moreau::server::testing::TestServer;
using moreau::server::testing::wait_final;
using moreau::server::testing::wait_running;
using json = nlohmann::json;

// A joint of the URDF, read from its text with regular expressions.
struct TextJoint {
  std::string name, type, parent, child;
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero(), rpy = Eigen::Vector3d::Zero(), axis = Eigen::Vector3d::UnitX();
};

Eigen::Vector3d three(const std::string& s) {
  std::istringstream in(s);
  Eigen::Vector3d v;
  in >> v.x() >> v.y() >> v.z();
  return v;
}

std::vector<TextJoint> joints_of(const std::string& urdf) {
  std::vector<TextJoint> out;
  const std::regex joint(R"re(<joint name="([^"]+)" type="([^"]+)">([\s\S]*?)</joint>)re");
  const std::regex parent(R"re(<parent link="([^"]+)")re"), child(R"re(<child link="([^"]+)")re");
  const std::regex origin(R"re(<origin xyz="([^"]+)" rpy="([^"]+)")re"), axis(R"re(<axis xyz="([^"]+)")re");
  for (auto it = std::sregex_iterator(urdf.begin(), urdf.end(), joint); it != std::sregex_iterator(); ++it) {
    TextJoint j;
    j.name = (*it)[1];
    j.type = (*it)[2];
    const std::string body = (*it)[3];
    std::smatch m;
    if (std::regex_search(body, m, parent)) j.parent = m[1];
    if (std::regex_search(body, m, child)) j.child = m[1];
    if (std::regex_search(body, m, origin)) {
      j.xyz = three(m[1]);
      j.rpy = three(m[2]);
    }
    if (std::regex_search(body, m, axis)) j.axis = three(m[1]);
    out.push_back(j);
  }
  return out;
}

// Every link's world pose at joint positions `q` (by joint name), the root's frame the world's.
std::map<std::string, Eigen::Isometry3d> forward_kinematics(const std::vector<TextJoint>& joints, const std::map<std::string, double>& q,
                                                            const std::string& root) {
  std::map<std::string, Eigen::Isometry3d> pose{{root, Eigen::Isometry3d::Identity()}};
  for (const TextJoint& j : joints) {  // the file lists parents before children
    Eigen::Isometry3d t = pose.at(j.parent);
    t.translate(j.xyz);
    t.rotate(Eigen::AngleAxisd(j.rpy.z(), Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(j.rpy.y(), Eigen::Vector3d::UnitY()) *
             Eigen::AngleAxisd(j.rpy.x(), Eigen::Vector3d::UnitX()));
    if (j.type == "revolute" || j.type == "continuous") t.rotate(Eigen::AngleAxisd(q.at(j.name), j.axis.normalized()));
    pose[j.child] = t;
  }
  return pose;
}

json get_json(httplib::Client& c, const std::string& path, int status = 200) {
  auto r = c.Get(path);
  EXPECT_TRUE(r) << path;
  if (!r) return json();
  EXPECT_EQ(r->status, status) << path << ": " << r->body;
  return json::parse(r->body);
}

TEST(ServerKinematics, LinkPosesEqualAnIndependentForwardKinematicsOfTheUrdf) {
  TestServer server;
  auto c = server.client();
  json scene = moreau::scene::read_scene_file("scenes/iiwa14-joint-limit.json");  // the URDF inline
  const std::string urdf = scene["system"]["urdf"]["text"];
  const std::vector<TextJoint> joints = joints_of(urdf);
  ASSERT_EQ(joints.size(), 9u);  // base joint, seven revolute, end effector
  auto r = submit(*c, {{"scene", scene}, {"overrides", {"integrator.t_end=0.4"}}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_final(*c, id)["state"], "done");
  const json trajectory = get_json(*c, "/v1/jobs/" + id + "/trajectory");

  // The sampled form: max_samples rows from the first to the last.
  const json sampled = get_json(*c, "/v1/jobs/" + id + "/kinematics?max_samples=5");
  EXPECT_EQ(sampled["robot"], "iiwa14");
  EXPECT_EQ(sampled["final"], true);
  EXPECT_EQ(sampled["rows"], trajectory["rows"]);
  ASSERT_EQ(sampled["frames"].size(), 5u);
  EXPECT_EQ(sampled["frames"][0]["row"], 0);
  EXPECT_EQ(sampled["frames"][4]["row"], trajectory["rows"].get<int>() - 1);
  EXPECT_EQ(sampled["frames"][4]["t"], 0.4);
  // Every link, the merged ones included (iiwa_link_0 on the base, iiwa_link_ee on link 7).
  std::vector<std::string> names;
  for (const json& link : sampled["links"]) names.push_back(link["name"]);
  EXPECT_THAT(names, ::testing::ElementsAre("base", "iiwa_link_0", "iiwa_link_1", "iiwa_link_2", "iiwa_link_3", "iiwa_link_4",
                                            "iiwa_link_5", "iiwa_link_6", "iiwa_link_7", "iiwa_link_ee"));
  EXPECT_EQ(sampled["links"][9]["parent"], "iiwa_link_7");
  EXPECT_EQ(sampled["links"][9]["joint_origin"], json({0.0, 0.0, 0.045}));

  int compared = 0;
  for (const double t : {0.0, 0.1, 0.2137, 0.4}) {
    std::ostringstream path;
    path.precision(17);
    path << "/v1/jobs/" << id << "/kinematics?t=" << t;
    const json k = get_json(*c, path.str());
    ASSERT_EQ(k["frames"].size(), 1u) << t;
    const json& frame = k["frames"][0];
    // The row that holds the state at t: the last at or before it.
    const int row = frame["row"];
    const json& times = trajectory["data"]["t"];
    EXPECT_LE(times[row].get<double>(), t);
    if (row + 1 < static_cast<int>(times.size())) {
      EXPECT_GT(times[row + 1].get<double>(), t);
    }
    EXPECT_EQ(frame["t"], times[row]);
    // Its joint positions, from the trajectory itself.
    std::map<std::string, double> q;
    for (std::size_t i = 0; i < k["joints"].size(); ++i) {
      const std::string name = k["joints"][i];
      q[name] = trajectory["data"][name][row];
      EXPECT_EQ(frame["q"][i], trajectory["data"][name][row]);
    }
    const auto want = forward_kinematics(joints, q, "base");
    ASSERT_EQ(frame["poses"].size(), k["links"].size());
    for (std::size_t l = 0; l < k["links"].size(); ++l) {
      const std::string name = k["links"][l]["name"];
      const Eigen::Isometry3d& w = want.at(name);
      const json& p = frame["poses"][l];
      ASSERT_EQ(p.size(), 12u);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) EXPECT_NEAR(p[4 * i + j].get<double>(), w.linear()(i, j), 1e-12) << name << " at t = " << t;
        EXPECT_NEAR(p[4 * i + 3].get<double>(), w.translation()(i), 1e-12) << name << " at t = " << t;
      }
      ++compared;
    }
  }
  EXPECT_EQ(compared, 40);
  // The end effector moves: the check is not of a robot at rest.
  EXPECT_GT(std::abs(sampled["frames"][0]["poses"][9][3].get<double>() - sampled["frames"][4]["poses"][9][3].get<double>()), 1e-3);
}

TEST(ServerKinematics, PendulumDrawnWithPrimitivesMatchesItsClosedForm) {
  TestServer server;
  auto c = server.client();
  auto r = submit(*c, {{"scene", moreau::server::testing::read_json_file("tests/server/shapes-pendulum.json")}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_final(*c, id)["state"], "done");
  const json k = get_json(*c, "/v1/jobs/" + id + "/kinematics?max_samples=7");
  ASSERT_EQ(k["links"].size(), 3u);
  // The visuals as the URDF writes them; the tip's mesh counted, not described.
  EXPECT_EQ(k["links"][0]["visuals"], json::parse(R"([{"shape": "box", "size": [0.2, 0.2, 0.5],
      "origin": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0.25]}])"));
  EXPECT_EQ(k["links"][1]["visuals"], json::parse(R"([{"shape": "cylinder", "radius": 0.03, "length": 0.5,
      "origin": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, -0.25]}])"));
  EXPECT_EQ(k["links"][2]["visuals"],
            json::parse(R"([{"shape": "sphere", "radius": 0.06, "origin": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0]}])"));
  EXPECT_EQ(k["links"][2]["meshes"], 1);
  EXPECT_EQ(k["links"][2]["parent"], "arm");
  ASSERT_EQ(k["frames"].size(), 7u);
  for (const json& frame : k["frames"]) {
    // The arm turns by q about y at (0, 0, 0.5): R = Ry(q); the tip hangs 0.5 below the pivot.
    const double q = frame["q"][0], cq = std::cos(q), sq = std::sin(q);
    const json want_arm = {cq, 0, sq, 0, 0, 1, 0, 0, -sq, 0, cq, 0.5};
    const json want_tip = {cq, 0, sq, -0.5 * sq, 0, 1, 0, 0, -sq, 0, cq, 0.5 - 0.5 * cq};
    for (int i = 0; i < 12; ++i) {
      EXPECT_NEAR(frame["poses"][1][i].get<double>(), want_arm[i].get<double>(), 1e-12) << "arm, entry " << i << ", t = " << frame["t"];
      EXPECT_NEAR(frame["poses"][2][i].get<double>(), want_tip[i].get<double>(), 1e-12) << "tip, entry " << i << ", t = " << frame["t"];
    }
  }
  EXPECT_GT(std::abs(k["frames"][0]["q"][0].get<double>() - k["frames"][3]["q"][0].get<double>()), 0.1);  // it swings
}

TEST(ServerKinematics, RunningJobServesTheRowsWrittenSoFar) {
  TestServer server;
  auto c = server.client();
  // The iiwa for long enough to be seen running (about 15 s; cancelled below), a row every 2000 steps:
  // about 70 rows, 10 kB, a second, which without the writer's periodic flush would stay in its 1 MiB
  // buffer until the run ends.
  auto r = submit(*c, {{"scene", moreau::scene::read_scene_file("scenes/iiwa14-joint-limit.json")},
                       {"overrides", {"integrator.t_end=2000", "output.every=2000"}}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_running(*c, id), "running");
  // The writer puts its rows on disk at least every 0.5 s: within a second or so some are there.
  json k;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(8);
  do {
    k = get_json(*c, "/v1/jobs/" + id + "/kinematics?max_samples=3");
    if (k["rows"].get<int>() > 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  } while (std::chrono::steady_clock::now() < deadline);
  ASSERT_GT(k["rows"].get<int>(), 0) << k.dump().substr(0, 300);
  EXPECT_EQ(k["state"], "running");
  EXPECT_EQ(k["final"], false);
  EXPECT_LT(k["t_last"].get<double>(), 2000.0);
  ASSERT_FALSE(k["frames"].empty());
  EXPECT_EQ(k["frames"].back()["t"], k["t_last"]);  // the newest row written, whole
  EXPECT_EQ(k["frames"].back()["poses"].size(), 10u);
  // Later, more rows.
  const int rows = k["rows"];
  json later;
  do {
    later = get_json(*c, "/v1/jobs/" + id + "/kinematics?max_samples=1");
    if (later["rows"].get<int>() > rows) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  } while (std::chrono::steady_clock::now() < deadline);
  EXPECT_GT(later["rows"].get<int>(), rows);
  c->Delete("/v1/jobs/" + id);
}

TEST(ServerKinematics, QueuedJobHasLinksAndNoFramesYetAndOtherScenesAreRefused) {
  ServerConfig cfg;
  cfg.workers = 1;
  TestServer server(cfg);
  auto c = server.client();
  // A long run holds the one worker; the robot waits in the queue.
  json busy = manipulator();
  auto r = submit(*c, {{"scene", busy}, {"overrides", {"integrator.t_end=1000", "output.every=1000"}}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string busy_id = json::parse(r->body)["id"];
  ASSERT_NE(wait_running(*c, busy_id), "queued");
  r = submit(*c, {{"scene", moreau::scene::read_scene_file("scenes/iiwa14-joint-limit.json")}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string robot_id = json::parse(r->body)["id"];
  // The job says where its link poses are; a job without a robot does not.
  EXPECT_EQ(get_json(*c, "/v1/jobs/" + robot_id)["links"]["kinematics"], "/v1/jobs/" + robot_id + "/kinematics");
  EXPECT_FALSE(get_json(*c, "/v1/jobs/" + busy_id)["links"].contains("kinematics"));
  const json queued = get_json(*c, "/v1/jobs/" + robot_id + "/kinematics");
  EXPECT_EQ(queued["state"], "queued");
  EXPECT_EQ(queued["final"], false);
  EXPECT_EQ(queued["links"].size(), 10u);
  EXPECT_EQ(queued["rows"], 0);
  EXPECT_TRUE(queued["frames"].empty());

  // A scene without a robot: 404 that says so.
  const json not_robot = get_json(*c, "/v1/jobs/" + busy_id + "/kinematics", 404);
  EXPECT_EQ(not_robot["error"], "not a robot");
  // Bad parameters: 400 naming the parameter.
  for (const std::string query : {"max_samples=0", "max_samples=1001", "max_samples=2.5", "t=abc", "from=nan", "from=2&to=1"}) {
    const json bad = get_json(*c, "/v1/jobs/" + robot_id + "/kinematics?" + query, 400);
    EXPECT_EQ(bad["error"], "bad query") << query;
    EXPECT_THAT(bad["reason"].get<std::string>(), ::testing::HasSubstr(query.substr(0, query.find('=')))) << query;
  }
  c->Delete("/v1/jobs/" + robot_id);
  c->Delete("/v1/jobs/" + busy_id);
}

}  // namespace
