// The server's metrics: the Prometheus text exposition (format 0.0.4) parses line by line, every
// series has # HELP and # TYPE, histograms are cumulative, and counters move.
#include <gtest/gtest.h>

#include <cctype>
#include <cstdlib>
#include <map>
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

bool is_name_char(char c, bool first) {
  return std::isalpha(static_cast<unsigned char>(c)) || c == '_' || c == ':' ||
         (!first && std::isdigit(static_cast<unsigned char>(c)));
}

// A metric name at text[pos]; advances pos. Empty when there is none.
std::string read_name(const std::string& text, size_t& pos) {
  size_t start = pos;
  while (pos < text.size() && is_name_char(text[pos], pos == start))
    ++pos;
  return text.substr(start, pos - start);
}

// `{name="value",...}` with escapes \\, \" and \n only; returns false on anything else. (A hand
// parser: std::regex trips GCC 12's -Wmaybe-uninitialized under the sanitizer build.)
bool read_labels(const std::string& text, size_t& pos, std::string* labels) {
  size_t start = pos;
  if (text[pos++] != '{') return false;
  while (pos < text.size() && text[pos] != '}') {
    size_t name_start = pos;
    while (pos < text.size() &&
           (std::isalnum(static_cast<unsigned char>(text[pos])) || text[pos] == '_'))
      ++pos;
    if (pos == name_start || text.compare(pos, 2, "=\"") != 0) return false;
    pos += 2;
    while (pos < text.size() && text[pos] != '"') {
      if (text[pos] == '\\') {
        if (pos + 1 >= text.size() || std::string("\\\"n").find(text[pos + 1]) == std::string::npos)
          return false;
        ++pos;
      }
      ++pos;
    }
    if (pos >= text.size()) return false;
    ++pos;  // closing quote
    if (pos < text.size() && text[pos] == ',') ++pos;
  }
  if (pos >= text.size()) return false;
  ++pos;  // '}'
  *labels = text.substr(start + 1, pos - start - 2);
  return true;
}

bool is_number(const std::string& v) {
  if (v == "+Inf" || v == "-Inf" || v == "NaN") return true;
  if (v.empty()) return false;
  char* end = nullptr;
  std::strtod(v.c_str(), &end);
  return end == v.c_str() + v.size();
}

// Every line is a comment (# HELP name text / # TYPE name type) or `name{labels} value`;
// returns the samples and fails the test on any other line.
std::vector<Sample> parse_exposition(const std::string& text,
                                     std::map<std::string, std::string>* types,
                                     std::set<std::string>* helps) {
  static const std::set<std::string> kTypes = {"counter", "gauge", "histogram", "summary",
                                               "untyped"};
  std::vector<Sample> out;
  std::istringstream in(text);
  std::string line;
  EXPECT_FALSE(text.empty());
  EXPECT_EQ(text.back(), '\n');
  while (std::getline(in, line)) {
    size_t pos = 0;
    if (line.rfind("# HELP ", 0) == 0) {
      pos = 7;
      std::string name = read_name(line, pos);
      bool ok = !name.empty() && pos + 1 < line.size() && line[pos] == ' ';
      EXPECT_TRUE(ok) << "bad HELP: '" << line << "'";
      if (ok) helps->insert(name);
    } else if (line.rfind("# TYPE ", 0) == 0) {
      pos = 7;
      std::string name = read_name(line, pos);
      bool ok = !name.empty() && pos < line.size() && line[pos] == ' ' &&
                kTypes.count(line.substr(pos + 1));
      EXPECT_TRUE(ok) << "bad TYPE: '" << line << "'";
      if (ok) {
        EXPECT_TRUE(types->emplace(name, line.substr(pos + 1)).second) << "TYPE twice: " << line;
      }
    } else {
      Sample s;
      s.name = read_name(line, pos);
      bool ok = !s.name.empty() && pos < line.size();
      if (ok && line[pos] == '{') ok = read_labels(line, pos, &s.labels);
      ok = ok && pos < line.size() && line[pos] == ' ';
      if (ok) {
        s.value = line.substr(pos + 1);
        ok = is_number(s.value);
      }
      EXPECT_TRUE(ok) << "not a Prometheus line: '" << line << "'";
      if (ok) out.push_back(s);
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
                           "grotto_device_launches_total",
                           "grotto_device_launch_seconds",
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
