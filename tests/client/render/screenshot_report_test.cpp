// grotto-client --screenshot --json's report (client/app/screenshot_report): percentiles over the
// pixels that show rock only, and the JSON's fields. Pure: no GL.
#include "client/app/screenshot_report.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <nlohmann/json.hpp>
#include <vector>

namespace grotto::app {
namespace {

constexpr float kNone = std::numeric_limits<float>::infinity();

TEST(ScreenshotReport, depth_percentiles_count_only_pixels_that_show_rock) {
  // Ten rock pixels 1..10 m among ten that show nothing (far plane, fog, a cap).
  std::vector<float> depth;
  for (int i = 10; i >= 1; --i) {
    depth.push_back(static_cast<float>(i));
    depth.push_back(i % 2 ? kNone : std::numeric_limits<float>::quiet_NaN());
  }
  const DepthSummary s = summarize_depth(depth);
  EXPECT_EQ(s.pixels, 20u);
  EXPECT_EQ(s.counted, 10u);
  EXPECT_DOUBLE_EQ(s.covered, 0.5);
  EXPECT_DOUBLE_EQ(s.p10, 1.0);
  EXPECT_DOUBLE_EQ(s.median, 5.0);
  EXPECT_DOUBLE_EQ(s.p90, 9.0);
}

TEST(ScreenshotReport, a_picture_without_rock_has_no_depth_and_says_so_as_null) {
  const std::vector<float> depth(16, kNone);
  ScreenshotReport r;
  r.depth = summarize_depth(depth);
  EXPECT_EQ(r.depth.counted, 0u);
  EXPECT_EQ(r.depth.covered, 0.0);
  const nlohmann::json j = nlohmann::json::parse(screenshot_json(r));
  EXPECT_TRUE(j["depth_m"]["median"].is_null());
  EXPECT_TRUE(j["depth_m"]["p10"].is_null());
  EXPECT_TRUE(j["seed"].is_null());
}

TEST(ScreenshotReport, json_holds_the_pose_the_depth_and_every_light) {
  ScreenshotReport r;
  r.picture = "shot.png";
  r.seed = 95;
  r.width = 480;
  r.height = 270;
  r.position = {1.5, -2, 3};
  r.yaw_deg = 90;
  r.pitch_deg = -10;
  r.mode = "fly";
  r.depth = summarize_depth(std::vector<float>{2, 4, 6, kNone});
  r.lights = {{"headlamp", {1.75, -1.7, 3}}, {"flare", {5, -3, 2}}};
  const nlohmann::json j = nlohmann::json::parse(screenshot_json(r));
  EXPECT_EQ(j["seed"].get<uint64_t>(), 95u);
  EXPECT_EQ(j["width"].get<int>(), 480);
  EXPECT_EQ(j["height"].get<int>(), 270);
  EXPECT_EQ(j["pose"]["position"][1].get<double>(), -2.0);
  EXPECT_EQ(j["pose"]["yaw"].get<double>(), 90.0);
  EXPECT_EQ(j["pose"]["pitch"].get<double>(), -10.0);
  EXPECT_EQ(j["mode"].get<std::string>(), "fly");
  EXPECT_EQ(j["depth_m"]["median"].get<double>(), 4.0);
  EXPECT_EQ(j["covered"].get<double>(), 0.75);
  ASSERT_EQ(j["lights"].size(), 2u);
  EXPECT_EQ(j["light_count"].get<int>(), 2);
  EXPECT_EQ(j["lights"][1]["kind"].get<std::string>(), "flare");
  EXPECT_EQ(j["lights"][1]["position"][0].get<double>(), 5.0);
}

}  // namespace
}  // namespace grotto::app
