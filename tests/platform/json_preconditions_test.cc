// nlohmann::json's preconditions are checked in every build type (cmake/json_preconditions.h, forced
// into every translation unit by the top-level CMakeLists.txt). Reference: the library's documented
// contract for operator[] on a const object, "the behavior is undefined if the key is not found"; with
// the check on, that call must stop the process with a message naming the failed precondition, in a
// release build too, instead of reading whatever follows the object's end().
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace {

TEST(JsonPreconditions, ConstLookupOfAMissingKeyStopsWithAMessage) {
  const nlohmann::json scene = nlohmann::json::parse(R"({"system": {"urdf": {"file": "arm.urdf"}}})");
  EXPECT_DEATH(static_cast<void>(scene["system"]["coordinates"].size()), "nlohmann::json precondition failed");
}

TEST(JsonPreconditions, PresentKeysAndCheckedAccessorsAreUnaffected) {
  const nlohmann::json scene = nlohmann::json::parse(R"({"system": {"coordinates": ["x"]}})");
  EXPECT_EQ(scene["system"]["coordinates"].size(), 1u);
  EXPECT_FALSE(scene.at("system").contains("urdf"));
  EXPECT_THROW(static_cast<void>(scene.at("system").at("urdf")), nlohmann::json::out_of_range);
}

}  // namespace
