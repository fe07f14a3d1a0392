// grotto-client's overlay lines and running figures (pure: no GL, no network).
#include "client/app/hud.hpp"

#include <gtest/gtest.h>

namespace grotto::app {
namespace {

bool has_line(const std::vector<render::OverlayLine>& lines, const std::string& start,
              glm::vec4 color) {
  for (const auto& line : lines)
    if (line.text.rfind(start, 0) == 0 && line.color == color) return true;
  return false;
}

TEST(Hud, a_ready_stream_shows_figures_and_toggles_without_a_connection_line) {
  HudState s;
  s.frame_ms = 16.7;
  s.latency_ms = 42;
  s.rooms_on_gpu = 12;
  s.stream.state = stream::StreamState::kReady;
  s.stream.in_flight = 3;
  s.mode = "walk";
  s.seed = "7";
  s.room = "0.0.0.r3";
  s.position = {12.25, -3.5, 40};
  const auto lines = hud_lines(s);
  ASSERT_GE(lines.size(), 2u);
  EXPECT_EQ(lines[0].text, "SEED 7  ROOM 0.0.0.r3  AT 12.2, -3.5, 40.0");
  EXPECT_EQ(lines[1].text.rfind("16.7 MS  60 FPS", 0), 0u) << lines[1].text;
  for (const auto& line : lines)
    EXPECT_EQ(line.color, render::kOverlayText) << line.text;
  bool latency = false, toggles = false;
  for (const auto& line : lines) {
    latency |= line.text.find("3 IN FLIGHT  LATENCY 42 MS") != std::string::npos;
    toggles |=
        line.text.find("TESS PN 8  RELIEF ON  BLOOM ON  BLUR ON  PORTALS ON") != std::string::npos;
    EXPECT_EQ(line.text.find("CAPS"), std::string::npos) << "no jargon: " << line.text;
  }
  EXPECT_TRUE(latency);
  EXPECT_TRUE(toggles);
}

TEST(Hud, says_plainly_when_the_server_is_gone_or_refuses) {
  HudState s;
  s.stream.state = stream::StreamState::kBackoff;
  s.stream.connects = 2;
  s.stream.last_error = "connection refused";
  auto lines = hud_lines(s);
  EXPECT_TRUE(has_line(lines, "SERVER LOST: RECONNECTING", render::kOverlayError));
  EXPECT_TRUE(has_line(lines, "connection refused", render::kOverlayError));
  s.stream.connects = 0;
  EXPECT_TRUE(has_line(hud_lines(s), "CANNOT REACH THE SERVER", render::kOverlayError));
  s.stream.state = stream::StreamState::kFailed;
  s.stream.last_error = "unauthorized: missing token";
  EXPECT_TRUE(has_line(hud_lines(s), "SERVER REFUSED US: unauthorized", render::kOverlayError));
  s.stream.state = stream::StreamState::kConnecting;
  s.stream.connects = 1;
  EXPECT_TRUE(has_line(hud_lines(s), "SERVER LOST: RECONNECTING", render::kOverlayWarning));
  // Past the server's capacity: the place in its queue instead.
  s.stream.queued = stream::StreamStats::QueuePlace{14, 19'600, 30};
  EXPECT_TRUE(has_line(hud_lines(s), "WAITING TO ENTER: 14TH IN LINE, ABOUT 20 S",
                       render::kOverlayWarning));
  EXPECT_FALSE(has_line(hud_lines(s), "SERVER LOST", render::kOverlayWarning));
}

TEST(Hud, the_key_list_appears_on_request) {
  HudState s;
  s.stream.state = stream::StreamState::kReady;
  const size_t short_list = hud_lines(s).size();
  s.help = true;
  EXPECT_GT(hud_lines(s).size(), short_list);
}

TEST(HudMeter, averages_frames_takes_the_median_latency_and_measures_bandwidth) {
  HudMeter m;
  EXPECT_LT(m.latency_ms(), 0);
  m.frame(0, 0.0, 0, {});  // the first frame's time is unknown
  EXPECT_EQ(m.frame_ms(), 0);
  std::vector<stream::RoomSample> samples(3);
  samples[0].latency_ms = 5, samples[1].latency_ms = 100, samples[2].latency_ms = 7;
  m.frame(20, 0.5, 1024, samples);
  EXPECT_EQ(m.frame_ms(), 20);
  EXPECT_EQ(m.latency_ms(), 7);
  // 201 KiB over the 2 s since the first frame (which saw none).
  m.frame(20, 2.0, 201 * 1024, {});
  EXPECT_NEAR(m.kbytes_per_s(), 100.5, 1e-9);
  m.frame(50, 2.1, 0, {});
  EXPECT_GT(m.frame_ms(), 20);
  EXPECT_LT(m.frame_ms(), 50);
}

}  // namespace
}  // namespace grotto::app
