// The server's metrics: the Prometheus text exposition (format 0.0.4) parses line by line, every
// series has # HELP and # TYPE, histograms are cumulative, and counters move.
#include <gtest/gtest.h>

#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "server/metrics.hpp"

namespace grotto::server {
namespace {

struct Sample {
  std::string name;
  std::string labels;
  std::string value;
};

// Every line is a comment (# HELP name text / # TYPE name type) or `name{labels} value`;
// returns the samples and fails the test on any other line.
std::vector<Sample> parse_exposition(const std::string& text,
                                     std::map<std::string, std::string>* types,
                                     std::set<std::string>* helps) {
  static const std::regex kSample(
      R"re(^([a-zA-Z_:][a-zA-Z0-9_:]*)(\{((?:[a-zA-Z_][a-zA-Z0-9_]*="(?:[^"\\\n]|\\["\\n])*",?)*)\})? ([-+]?(?:[0-9.eE+-]+|Inf|NaN))$)re");
  static const std::regex kHelp(R"(^# HELP ([a-zA-Z_:][a-zA-Z0-9_:]*) .+$)");
  static const std::regex kType(
      R"(^# TYPE ([a-zA-Z_:][a-zA-Z0-9_:]*) (counter|gauge|histogram|summary|untyped)$)");
  std::vector<Sample> out;
  std::istringstream in(text);
  std::string line;
  std::smatch m;
  EXPECT_FALSE(text.empty());
  EXPECT_EQ(text.back(), '\n');
  while (std::getline(in, line)) {
    if (std::regex_match(line, m, kHelp)) {
      helps->insert(m[1]);
    } else if (std::regex_match(line, m, kType)) {
      EXPECT_TRUE(types->emplace(m[1], m[2]).second) << "TYPE twice: " << line;
    } else if (std::regex_match(line, m, kSample)) {
      out.push_back({m[1], m[3], m[4]});
    } else {
      ADD_FAILURE() << "not a Prometheus line: '" << line << "'";
    }
  }
  return out;
}

// The family a sample belongs to: histogram samples carry _bucket/_sum/_count suffixes.
std::string family(const std::string& name, const std::map<std::string, std::string>& types) {
  if (types.count(name)) return name;
  for (const char* suffix : {"_bucket", "_sum", "_count"}) {
    std::string s = suffix;
    if (name.size() > s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0) {
      std::string base = name.substr(0, name.size() - s.size());
      if (types.count(base) && types.at(base) == "histogram") return base;
    }
  }
  return name;
}

std::string value_of(const std::vector<Sample>& samples, const std::string& name,
                     const std::string& labels = "") {
  for (const Sample& s : samples) {
    if (s.name == name && s.labels == labels) return s.value;
  }
  return "<missing>";
}

TEST(MetricsTest, render_parses_and_every_series_has_help_and_type) {
  Metrics m;
  m.set_compute_path("opencl: pthread-cpu \"quoted\" back\\slash\nnewline");
  m.build_seconds.observe(0.003);
  std::map<std::string, std::string> types;
  std::set<std::string> helps;
  std::vector<Sample> samples = parse_exposition(m.render(), &types, &helps);
  ASSERT_FALSE(samples.empty());
  for (const Sample& s : samples) {
    std::string f = family(s.name, types);
    EXPECT_TRUE(types.count(f)) << "no # TYPE for " << s.name;
    EXPECT_TRUE(helps.count(f)) << "no # HELP for " << s.name;
  }
  for (const char* name : {"grotto_connections_total",
                           "grotto_connections_open",
                           "grotto_connections_rejected_total",
                           "grotto_http_requests_total",
                           "grotto_messages_total",
                           "grotto_rooms_requested_total",
                           "grotto_rooms_built_total",
                           "grotto_rooms_served_total",
                           "grotto_rooms_cache_hits_total",
                           "grotto_rooms_cancelled_total",
                           "grotto_rooms_deduplicated_total",
                           "grotto_rooms_failed_total",
                           "grotto_batches_total",
                           "grotto_queue_depth",
                           "grotto_rooms_in_flight",
                           "grotto_cache_bytes",
                           "grotto_cache_entries",
                           "grotto_build_seconds",
                           "grotto_encode_seconds",
                           "grotto_room_latency_seconds",
                           "grotto_bytes_sent_total",
                           "grotto_slow_clients_dropped_total",
                           "grotto_errors_total",
                           "grotto_compute_path_info"}) {
    EXPECT_TRUE(types.count(name)) << name;
  }
  EXPECT_EQ(types["grotto_rooms_built_total"], "counter");
  EXPECT_EQ(types["grotto_queue_depth"], "gauge");
  EXPECT_EQ(types["grotto_build_seconds"], "histogram");
  EXPECT_EQ(value_of(samples, "grotto_compute_path_info",
                     R"(path="opencl: pthread-cpu \"quoted\" back\\slash\nnewline")"),
            "1");
}

TEST(MetricsTest, counters_gauges_and_errors_move) {
  Metrics m;
  m.rooms_built.add(3);
  m.rooms_built.add();
  m.queue_depth.set(7);
  m.queue_depth.add(-2);
  m.count_error(ErrorCode::kNotFound);
  m.count_error(ErrorCode::kNotFound);
  m.count_error(ErrorCode::kOverloaded);
  m.count_error(ErrorCode::kUnavailable);      // sent as overloaded
  m.count_error(ErrorCode::kInvalidArgument);  // sent as bad_message
  EXPECT_EQ(m.errors(ErrorCode::kNotFound), 2u);
  std::map<std::string, std::string> types;
  std::set<std::string> helps;
  std::vector<Sample> s = parse_exposition(m.render(), &types, &helps);
  EXPECT_EQ(value_of(s, "grotto_rooms_built_total"), "4");
  EXPECT_EQ(value_of(s, "grotto_queue_depth"), "5");
  EXPECT_EQ(value_of(s, "grotto_errors_total", R"(code="not_found")"), "2");
  EXPECT_EQ(value_of(s, "grotto_errors_total", R"(code="overloaded")"), "2");
  EXPECT_EQ(value_of(s, "grotto_errors_total", R"(code="bad_message")"), "1");
  EXPECT_EQ(value_of(s, "grotto_errors_total", R"(code="timeout")"), "0");
  // Wire names only: the general codes never appear under their own names.
  EXPECT_EQ(value_of(s, "grotto_errors_total", R"(code="invalid_argument")"), "<missing>");
  EXPECT_EQ(value_of(s, "grotto_errors_total", R"(code="unavailable")"), "<missing>");
  // No path yet: the info family is declared but has no sample.
  EXPECT_EQ(value_of(s, "grotto_compute_path_info"), "<missing>");
}

TEST(MetricsTest, histogram_buckets_are_cumulative_and_sum_counts) {
  Histogram h;
  h.observe(0.0001);  // first bucket
  h.observe(0.003);   // le 0.005
  h.observe(0.003);
  h.observe(30.0);  // only +Inf
  EXPECT_EQ(h.count(), 4u);
  EXPECT_NEAR(h.sum(), 30.0061, 1e-5);
  EXPECT_EQ(h.bucket(0), 1u);   // le 0.0005
  EXPECT_EQ(h.bucket(2), 1u);   // le 0.002
  EXPECT_EQ(h.bucket(3), 3u);   // le 0.005
  EXPECT_EQ(h.bucket(13), 3u);  // le 10
  EXPECT_EQ(h.bucket(Histogram::kBounds.size()), 4u);
  for (size_t i = 1; i <= Histogram::kBounds.size(); ++i)
    EXPECT_LE(h.bucket(i - 1), h.bucket(i));

  Metrics m;
  m.encode_seconds.observe(0.003);
  m.encode_seconds.observe(30.0);
  std::map<std::string, std::string> types;
  std::set<std::string> helps;
  std::vector<Sample> s = parse_exposition(m.render(), &types, &helps);
  EXPECT_EQ(value_of(s, "grotto_encode_seconds_bucket", R"(le="0.005")"), "1");
  EXPECT_EQ(value_of(s, "grotto_encode_seconds_bucket", R"(le="+Inf")"), "2");
  EXPECT_EQ(value_of(s, "grotto_encode_seconds_count"), "2");
  EXPECT_EQ(value_of(s, "grotto_encode_seconds_sum"), "30.003");
}

}  // namespace
}  // namespace grotto::server
