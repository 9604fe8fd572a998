// The T_s ladder of a tracking scene (sampling_study.h) on m x'' = u + D0 with the controller's model
// m^ = m = 2, Lambda = 3, a = 4, D0 = 1, q_d = 0.5 t, against docs/tracking.md's closed forms: the
// implicit law settles at e = D0 T_s / (m Lambda) (so the final error halves with T_s), u of one sign
// after e's transient; the explicit law switches the sign of u at least 2 / (3 T_s) times a second.
#include "moreau/analysis/sampling_study.h"

#include <gtest/gtest.h>

#include <cmath>

#include "moreau/scene/scene.h"
#include "support/one_dof_tracking.h"

namespace moreau::scene {
namespace {

nlohmann::json one_dof() {
  return test_support::one_dof_tracking("-1", "0.5*t", {{"law", "implicit"}, {"period", 1e-3}}, 1e-4, 6.0, 0.2, 0.0);
}

TEST(SamplingStudy, ImplicitAndExplicitAgainstTheClosedForms) {
  const std::vector<double> periods = {2e-3, 1e-3};
  const SamplingStudyResult r = run_sampling_study(one_dof(), periods, {"implicit", "explicit"});
  ASSERT_EQ(r.rows.size(), 4u);
  for (std::size_t k = 0; k < r.rows.size(); ++k) {
    const SamplingStudyRow& row = r.rows[k];
    SCOPED_TRACE(row.law + " at T_s = " + std::to_string(row.period));
    EXPECT_EQ(row.law, k < 2 ? "implicit" : "explicit");
    EXPECT_EQ(row.period, periods[k % 2]);
    EXPECT_DOUBLE_EQ(row.h, row.period / 10.0);  // the scene's 10 plant steps per sample
    EXPECT_EQ(row.status, "completed");
    ASSERT_TRUE(row.reached);
    if (row.law == "implicit") {
      // Two sign changes after reaching (arrival, and e's transient) over about 6 s; the error at the end
      // is the fixed point's D0 T_s / (m Lambda) (e's transient, 0.2 exp(-18), is below the tolerance).
      EXPECT_LT(row.sign_changes_per_second, 0.5);
      EXPECT_NEAR(row.error_final, row.period / (2.0 * 3.0), 1e-7);
    } else {
      EXPECT_GE(row.sign_changes_per_second, 2.0 / (3.0 * row.period) * 0.99);
    }
  }
  const std::string text = r.to_text(), csv = r.to_csv();
  EXPECT_NE(text.find("implicit"), std::string::npos);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 5);
  EXPECT_EQ(r.to_json()["rows"].size(), 4u);
}

TEST(SamplingStudy, BadOptionsAreNamed) {
  auto pointer_of = [](const nlohmann::json& doc, const std::vector<double>& periods, const std::vector<std::string>& laws) {
    try {
      run_sampling_study(doc, periods, laws);
    } catch (const SceneError& e) {
      return e.pointer();
    }
    return std::string("no error");
  };
  EXPECT_EQ(pointer_of(one_dof(), {}, {"implicit"}), "--periods");
  EXPECT_EQ(pointer_of(one_dof(), {-1.0}, {"implicit"}), "--periods");
  EXPECT_EQ(pointer_of(one_dof(), {1e-3}, {"sideways"}), "--laws");
  EXPECT_EQ(pointer_of(one_dof(), {1e-3}, {"saturated"}), "/system/tracking/boundary_layer");
  nlohmann::json plain = one_dof();
  plain["system"].erase("tracking");
  EXPECT_EQ(pointer_of(plain, {1e-3}, {"implicit"}), "/system/tracking");
}

}  // namespace
}  // namespace moreau::scene
