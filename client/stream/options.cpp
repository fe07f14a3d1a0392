#include "client/stream/options.hpp"

#include <cmath>
#include <string>

#include "client/stream/url.hpp"
#include "proto/token.hpp"

namespace grotto::stream {

Status validate_options(const StreamOptions& options) {
  if (auto url = parse_url(options.url); !url) return url.error();
  auto invalid = [](const std::string& why) { return Error{ErrorCode::kInvalidArgument, why}; };
  if (!(options.plan.horizon_s > 0) || !std::isfinite(options.plan.horizon_s)) {
    return invalid("horizon must be a positive number of seconds");
  }
  // A floor above the horizon means the horizon alone (a fixed one): no error, so that a caller
  // who shortens the horizon need not know the default floor.
  if (!(options.min_horizon_s >= 0) || !std::isfinite(options.min_horizon_s)) {
    return invalid("min_horizon_s must be 0 (fixed horizon) or a positive number of seconds");
  }
  if (!(options.cancel_factor >= 1) || !std::isfinite(options.cancel_factor)) {
    return invalid("cancel_factor must be at least 1");
  }
  if (options.max_in_flight < 1) return invalid("max_in_flight must be at least 1");
  if (options.backoff_initial.count() < 1 || options.backoff_max < options.backoff_initial) {
    return invalid("backoff: need 1 ms <= initial <= max");
  }
  if (options.restart_spread < options.backoff_initial)
    return invalid("restart_spread must be at least backoff_initial");
  // A zero interval would spin the tick timer; zero timeouts would drop every connection.
  if (options.connect_timeout.count() < 1) return invalid("connect_timeout must be at least 1 ms");
  if (options.request_timeout.count() < 1) return invalid("request_timeout must be at least 1 ms");
  if (options.replan_interval.count() < 1) return invalid("replan_interval must be at least 1 ms");
  if (options.max_room_failures < 1) return invalid("max_room_failures must be at least 1");
  if (options.lod > 255) return invalid("lod must be in [0, 255] (PROTOCOL.md: max_lod <= 255)");
  const NetProfile& net = options.net;
  if (net.rtt.count() < 0 || net.jitter.count() < 0 || net.stall.count() < 0 ||
      (net.stall.count() > 0 && net.stall_every <= net.stall)) {
    return invalid("net: times must be >= 0 and a stall's period longer than the stall");
  }
  if (options.protocol_version != 0 && !proto::speaks_version(options.protocol_version)) {
    return invalid("protocol_version must be 0 (all) or one of " +
                   std::to_string(proto::kMinProtocolVersion) + ".." +
                   std::to_string(proto::kProtocolVersion));
  }
  if (!options.token.empty()) {
    if (auto st = proto::check_token(options.token); !st)
      return invalid("token " + st.error().message);
  }
  return {};
}

}  // namespace grotto::stream
