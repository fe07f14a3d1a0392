#include "client/stream/net_sim.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <optional>
#include <vector>

namespace grotto::stream {
namespace {

using std::chrono::microseconds;

Error invalid(const std::string& why) {
  return Error{ErrorCode::kInvalidArgument, "--net: " + why};
}

// "150ms", "0.5s", "800us" -> microseconds; nullopt when it is not a non-negative time.
std::optional<microseconds> parse_time(std::string_view text) {
  double scale = 0;
  if (text.ends_with("us")) {
    scale = 1;
    text.remove_suffix(2);
  } else if (text.ends_with("ms")) {
    scale = 1e3;
    text.remove_suffix(2);
  } else if (text.ends_with("s")) {
    scale = 1e6;
    text.remove_suffix(1);
  } else {
    return std::nullopt;
  }
  double v = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty() || !std::isfinite(v) ||
      v < 0 || v * scale > 3.6e9) {
    return std::nullopt;
  }
  return microseconds(static_cast<int64_t>(std::llround(v * scale)));
}

// 'text', quoted (built by appending: GCC 12 warns, wrongly, of an overlapping copy in
// "'" + std::string(...) at -O2 and above).
std::string quoted(std::string_view text) {
  std::string q;
  q.reserve(text.size() + 2);
  q += '\'';
  q.append(text);
  q += '\'';
  return q;
}

std::string time_text(microseconds t) {
  if (t.count() % 1000 != 0) return std::to_string(t.count()) + "us";
  if (t.count() % 1'000'000 == 0) return std::to_string(t.count() / 1'000'000) + "s";
  return std::to_string(t.count() / 1000) + "ms";
}

}  // namespace

Result<NetProfile> parse_net_profile(std::string_view text) {
  NetProfile p;
  if (text.empty() || text == "off") return p;
  std::vector<std::string_view> seen;
  while (!text.empty()) {
    const size_t comma = text.find(',');
    std::string_view part = text.substr(0, comma);
    text = comma == std::string_view::npos ? std::string_view{} : text.substr(comma + 1);
    const size_t eq = part.find('=');
    if (eq == std::string_view::npos) {
      return invalid(quoted(part) + " is not name=value (rtt, jitter, kbps, stall)");
    }
    const std::string_view name = part.substr(0, eq), value = part.substr(eq + 1);
    if (std::find(seen.begin(), seen.end(), name) != seen.end()) {
      return invalid(quoted(name) + " given twice");
    }
    seen.push_back(name);
    const std::string given = "(got " + quoted(value) + ")";
    if (name == "rtt" || name == "jitter") {
      auto t = parse_time(value);
      if (!t) return invalid(std::string(name) + " must be a time such as 150ms " + given);
      (name == "rtt" ? p.rtt : p.jitter) = *t;
    } else if (name == "kbps") {
      uint32_t v = 0;
      auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), v);
      if (ec != std::errc() || end != value.data() + value.size() || v < 1 || v > 100'000'000) {
        return invalid("kbps must be a whole number of kilobits a second, at least 1 " + given);
      }
      p.kbps = v;
    } else if (name == "stall") {
      const size_t slash = value.find('/');
      auto stall = parse_time(value.substr(0, slash));
      auto every =
          slash == std::string_view::npos ? std::nullopt : parse_time(value.substr(slash + 1));
      if (!stall || !every || *every <= *stall || stall->count() == 0) {
        return invalid("stall must be a duration and a longer period such as 0.5s/30s " + given);
      }
      p.stall = *stall;
      p.stall_every = *every;
    } else {
      return invalid("unknown part " + quoted(name) + " (rtt, jitter, kbps, stall)");
    }
  }
  return p;
}

std::string net_profile_text(const NetProfile& p) {
  if (!p.active()) return "off";
  std::string out;
  auto add = [&](const std::string& part) { out += (out.empty() ? "" : ",") + part; };
  if (p.rtt.count() > 0) add("rtt=" + time_text(p.rtt));
  if (p.jitter.count() > 0) add("jitter=" + time_text(p.jitter));
  if (p.kbps > 0) add("kbps=" + std::to_string(p.kbps));
  if (p.stall.count() > 0) add("stall=" + time_text(p.stall) + "/" + time_text(p.stall_every));
  return out;
}

NetLink::NetLink(const NetProfile& profile, bool capped, Time start, uint64_t seed)
    : profile_(profile),
      capped_(capped),
      start_(start),
      wire_free_(start),
      last_(start),
      rng_(seed) {}

NetLink::Time NetLink::after_stall(Time t) const {
  if (profile_.stall.count() <= 0 || t < start_) return t;
  const auto since = std::chrono::duration_cast<microseconds>(t - start_);
  const int64_t k = since.count() / profile_.stall_every.count();
  if (k < 1) return t;  // the first stall comes one period after the link opened
  const Time begins = start_ + profile_.stall_every * k;
  return t < begins + profile_.stall ? begins + profile_.stall : t;
}

NetLink::Time NetLink::arrival(Time now, size_t bytes) {
  // On the wire once what came before has gone (and not while the link stalls).
  Time leaves = after_stall(std::max(now, wire_free_));
  if (capped_ && profile_.kbps > 0) {
    const double seconds = static_cast<double>(bytes) * 8.0 / (1000.0 * profile_.kbps);
    leaves += std::chrono::duration_cast<Time::duration>(std::chrono::duration<double>(seconds));
  }
  wire_free_ = leaves;
  Time arrives = leaves + profile_.rtt / 2;
  if (profile_.jitter.count() > 0) {
    arrives += microseconds(
        static_cast<int64_t>(rng_.uniform() * static_cast<double>(profile_.jitter.count())));
  }
  // In order, as TCP delivers; held while the link stalls.
  last_ = after_stall(std::max(arrives, last_));
  return last_;
}

}  // namespace grotto::stream
