// client/stream's options: what Stream::start refuses, each by the option's name, before any
// network (validate_options).
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>

#include "client/stream/options.hpp"

namespace grotto::stream {
namespace {

using std::chrono::milliseconds;

StreamOptions good() {
  StreamOptions o;
  o.url = "ws://127.0.0.1:1/ws";
  return o;
}

TEST(StreamOptions, defaults_with_a_url_are_valid) {
  EXPECT_TRUE(validate_options(good()).ok());
  StreamOptions o = good();
  o.token = "s3cret token";
  o.lod = 255;
  EXPECT_TRUE(validate_options(o).ok());
}

TEST(StreamOptions, the_default_horizon_is_adaptive_and_a_floor_above_it_is_no_error) {
  StreamOptions o = good();
  EXPECT_EQ(o.min_horizon_s, kDefaultMinHorizonS);
  EXPECT_GT(o.min_horizon_s, 0) << "adaptive by default";
  EXPECT_LT(o.min_horizon_s, o.plan.horizon_s);
  o.plan.horizon_s = 1.0;  // shorter than the default floor: a fixed 1 s horizon, no error
  EXPECT_TRUE(validate_options(o).ok());
  o.min_horizon_s = 0;  // the fixed horizon stays available
  EXPECT_TRUE(validate_options(o).ok());
}

TEST(StreamOptions, each_bad_option_is_refused_by_name) {
  struct Row {
    const char* mention;
    std::function<void(StreamOptions&)> spoil;
  };
  const Row rows[] = {
      {"url", [](StreamOptions& o) { o.url = "http://x/ws"; }},
      {"horizon", [](StreamOptions& o) { o.plan.horizon_s = 0; }},
      {"horizon", [](StreamOptions& o) { o.plan.horizon_s = std::nan(""); }},
      {"horizon", [](StreamOptions& o) { o.plan.horizon_s = INFINITY; }},
      {"min_horizon_s", [](StreamOptions& o) { o.min_horizon_s = -1; }},
      {"min_horizon_s", [](StreamOptions& o) { o.min_horizon_s = INFINITY; }},
      {"min_horizon_s", [](StreamOptions& o) { o.min_horizon_s = std::nan(""); }},
      {"cancel_factor", [](StreamOptions& o) { o.cancel_factor = 0.5; }},
      {"max_in_flight", [](StreamOptions& o) { o.max_in_flight = 0; }},
      {"backoff", [](StreamOptions& o) { o.backoff_initial = milliseconds(0); }},
      {"backoff", [](StreamOptions& o) { o.backoff_max = o.backoff_initial - milliseconds(1); }},
      {"connect_timeout", [](StreamOptions& o) { o.connect_timeout = milliseconds(0); }},
      {"request_timeout", [](StreamOptions& o) { o.request_timeout = milliseconds(0); }},
      {"replan_interval", [](StreamOptions& o) { o.replan_interval = milliseconds(0); }},
      {"max_room_failures", [](StreamOptions& o) { o.max_room_failures = 0; }},
      {"lod", [](StreamOptions& o) { o.lod = 256; }},
      {"token", [](StreamOptions& o) { o.token = "tab\there"; }},
      {"token", [](StreamOptions& o) { o.token = std::string(257, 'x'); }},
  };
  for (const Row& row : rows) {
    StreamOptions o = good();
    row.spoil(o);
    Status s = validate_options(o);
    ASSERT_FALSE(s.ok()) << row.mention;
    EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument) << row.mention;
    EXPECT_NE(s.error().message.find(row.mention), std::string::npos) << s.error().message;
  }
}

}  // namespace
}  // namespace grotto::stream
