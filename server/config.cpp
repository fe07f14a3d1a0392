#include "server/config.hpp"

#include <CLI/CLI.hpp>
#include <charconv>
#include <cstdlib>
#include <functional>
#include <limits>
#include <map>
#include <sstream>
#include <variant>
#include <vector>

#include "common/cave/layout.hpp"
#include "proto/config_json.hpp"
#include "proto/token.hpp"
#include "server/room_tier.hpp"

#ifndef GROTTO_VERSION
#define GROTTO_VERSION "0.0.0"
#endif

namespace grotto::server {
namespace {

using Value = std::variant<int64_t, uint64_t, double, std::string, bool>;

// One setting: its name (the long flag without "--", and the config file's key), its type and
// range, and how it reads and writes the config. Flags and file keys go through the same parser,
// so both give the same messages.
struct Setting {
  enum class Type { kInt, kUint64, kDouble, kString, kBool };
  std::string name;
  std::string help;
  Type type = Type::kInt;
  int64_t min = 0;
  int64_t max = 0;
  std::vector<std::string> choices;  // kString: allowed values (empty: any)
  std::function<Value(const ServerConfig&)> get;
  std::function<void(ServerConfig&, const Value&)> set;
};

std::string show(const Value& v) {
  struct {
    std::string operator()(int64_t x) { return std::to_string(x); }
    std::string operator()(uint64_t x) { return std::to_string(x); }
    std::string operator()(double x) {
      std::ostringstream s;
      s << x;
      return s.str();
    }
    std::string operator()(const std::string& x) { return x; }
    std::string operator()(bool x) { return x ? "true" : "false"; }
  } visitor;
  return std::visit(visitor, v);
}

template <typename Get>
Setting int_setting(std::string name, std::string help, int64_t min, int64_t max, Get field) {
  Setting s{std::move(name), std::move(help), Setting::Type::kInt, min, max, {}, {}, {}};
  s.get = [field](const ServerConfig& c) {
    return Value{static_cast<int64_t>(field(const_cast<ServerConfig&>(c)))};
  };
  s.set = [field](ServerConfig& c, const Value& v) {
    using T = std::remove_reference_t<decltype(field(c))>;
    field(c) = static_cast<T>(std::get<int64_t>(v));
  };
  return s;
}

template <typename Get>
Setting ms_setting(std::string name, std::string help, int64_t min, int64_t max, Get field) {
  Setting s{std::move(name), std::move(help), Setting::Type::kInt, min, max, {}, {}, {}};
  s.get = [field](const ServerConfig& c) {
    return Value{static_cast<int64_t>(field(const_cast<ServerConfig&>(c)).count())};
  };
  s.set = [field](ServerConfig& c, const Value& v) {
    field(c) = std::chrono::milliseconds{std::get<int64_t>(v)};
  };
  return s;
}

template <typename Get>
Setting double_setting(std::string name, std::string help, Get field) {
  Setting s{std::move(name), std::move(help), Setting::Type::kDouble, 0, 0, {}, {}, {}};
  s.get = [field](const ServerConfig& c) { return Value{field(const_cast<ServerConfig&>(c))}; };
  s.set = [field](ServerConfig& c, const Value& v) { field(c) = std::get<double>(v); };
  return s;
}

template <typename Get>
Setting string_setting(std::string name, std::string help, std::vector<std::string> choices,
                       Get field) {
  Setting s{
      std::move(name), std::move(help), Setting::Type::kString, 0, 0, std::move(choices), {}, {}};
  s.get = [field](const ServerConfig& c) { return Value{field(const_cast<ServerConfig&>(c))}; };
  s.set = [field](ServerConfig& c, const Value& v) { field(c) = std::get<std::string>(v); };
  return s;
}

constexpr int64_t kMaxInt = std::numeric_limits<int32_t>::max();
constexpr int64_t kMaxBytes = int64_t{1} << 40;

const std::vector<Setting>& settings() {
  static const std::vector<Setting> table = [] {
    std::vector<Setting> t;
    t.push_back(string_setting(
        "bind", "Address to listen on (0.0.0.0 or :: for every interface)", {},
        [](ServerConfig & c) -> auto& { return c.bind; }));
    t.push_back(int_setting(
        "port", "TCP port for HTTP and WebSocket (0: an ephemeral port)", 0, 65535,
        [](ServerConfig & c) -> auto& { return c.port; }));
    t.push_back(int_setting(
        "io-threads", "Asio I/O threads (0: one per hardware thread)", 0, 1024,
        [](ServerConfig & c) -> auto& { return c.io_threads; }));
    Setting seed{"seed", "", Setting::Type::kUint64, 0, 0, {}, {}, {}};
    seed.help = "World seed (unsigned 64-bit): the world of clients that name none";
    seed.get = [](const ServerConfig& c) { return Value{c.seed}; };
    seed.set = [](ServerConfig& c, const Value& v) { c.seed = std::get<uint64_t>(v); };
    t.push_back(seed);
    t.push_back(int_setting(
        "max-worlds",
        "Worlds served at once: --seed plus up to N-1 others that hellos name, opened on demand "
        "(an idle one is closed for a new one; with all in use a hello gets 'overloaded'). "
        "1: --seed only",
        1, 4096, [](ServerConfig & c) -> auto& { return c.generator.max_worlds; }));
    t.push_back(double_setting(
        "sector-size", "Layout: sector edge in metres",
        [](ServerConfig & c) -> auto& { return c.layout.sector_size; }));
    t.push_back(double_setting(
        "region-scale", "Layout: sectors over which region characters change",
        [](ServerConfig & c) -> auto& { return c.layout.region_scale; }));
    t.push_back(int_setting(
        "region-sharpness", "Layout: how crisply one character dominates", 0, 64,
        [](ServerConfig & c) -> auto& { return c.layout.region_sharpness; }));
    t.push_back(double_setting(
        "min-portal-radius", "Layout: smallest portal radius in metres",
        [](ServerConfig & c) -> auto& { return c.layout.min_portal_radius; }));
    t.push_back(int_setting(
        "max-message-bytes", "Limit: largest text frame (>= 1024)", 1024, kMaxInt,
        [](ServerConfig & c) -> auto& { return c.limits.max_message_bytes; }));
    t.push_back(int_setting(
        "max-frame-bytes", "Limit: largest binary room frame (>= 1024)", 1024, kMaxInt,
        [](ServerConfig & c) -> auto& { return c.limits.max_frame_bytes; }));
    t.push_back(int_setting(
        "max-rooms-per-request", "Limit: rooms in one request or cancel", 1, 65536,
        [](ServerConfig & c) -> auto& { return c.limits.max_rooms_per_request; }));
    t.push_back(int_setting(
        "max-rooms-in-flight", "Limit: rooms in flight per client", 1, 1 << 20,
        [](ServerConfig & c) -> auto& { return c.limits.max_rooms_in_flight; }));
    t.push_back(int_setting(
        "max-lod", "Limit: highest level of detail served", 0, kMaxServedLod,
        [](ServerConfig & c) -> auto& { return c.limits.max_lod; }));
    t.push_back(int_setting(
        "idle-timeout-ms", "Limit: client silence before the server closes", 1, kMaxInt,
        [](ServerConfig & c) -> auto& { return c.limits.idle_timeout_ms; }));
    t.push_back(int_setting(
        "handshake-timeout-ms", "Limit: from the upgrade to hello", 1, kMaxInt,
        [](ServerConfig & c) -> auto& { return c.limits.handshake_timeout_ms; }));
    t.push_back(int_setting(
        "request-rate",
        "Limit: rooms per second a client may name in requests and cancels (a token bucket; "
        "0: no limit)",
        0, kMaxInt, [](ServerConfig & c) -> auto& { return c.limits.request_rate; }));
    t.push_back(int_setting(
        "request-burst", "Limit: rooms a client may name at once above the rate", 1, kMaxInt,
        [](ServerConfig & c) -> auto& { return c.limits.request_burst; }));
    t.push_back(int_setting(
        "max-kbps",
        "Limit: room frames' bandwidth per player in kbit/s, averaged over a second; rooms ready "
        "beyond it wait, most urgent first (0: no cap)",
        0, kMaxInt, [](ServerConfig & c) -> auto& { return c.limits.max_kbps; }));
    t.push_back(int_setting(
        "max-connections", "Players (WebSocket sessions past hello) at once; more are refused", 1,
        1 << 20, [](ServerConfig & c) -> auto& { return c.max_connections; }));
    t.push_back(int_setting(
        "max-handshakes",
        "WebSocket sessions waiting for their hello at once (each for handshake-timeout-ms), "
        "counted apart from players; more are refused",
        1, 1 << 20, [](ServerConfig & c) -> auto& { return c.max_handshakes; }));
    t.push_back(int_setting(
        "max-queue",
        "Sessions past hello waiting to enter while the players are not served in time; more "
        "are refused (overloaded, retry_after_ms)",
        0, 1 << 20, [](ServerConfig & c) -> auto& { return c.admission.max_queue; }));
    t.push_back(int_setting(
        "max-players",
        "Players admitted at most however well they are served; past it newcomers queue "
        "(0: the measurements alone decide)",
        0, 1 << 20, [](ServerConfig & c) -> auto& { return c.admission.max_players; }));
    t.push_back(ms_setting(
        "admission-late-ms",
        "Newcomers wait (or are refused) while players' oldest urgent room wants (90th percentile) "
        "are older than this; "
        "0: every hello is admitted at once",
        0, kMaxInt, [](ServerConfig & c) -> auto& { return c.admission.late_after; }));
    t.push_back(int_setting(
        "send-queue-bytes", "Unsent bytes per client before it is dropped as a slow reader", 1024,
        kMaxBytes, [](ServerConfig & c) -> auto& { return c.send_queue_bytes; }));
    t.push_back(ms_setting(
        "http-timeout-ms", "Plain HTTP request or WebSocket upgrade timeout", 1, kMaxInt,
        [](ServerConfig & c) -> auto& { return c.http_timeout; }));
    t.push_back(ms_setting(
        "drain-timeout-ms", "Graceful shutdown bound", 0, kMaxInt,
        [](ServerConfig & c) -> auto& { return c.drain_timeout; }));
    t.push_back(int_setting(
        "workers", "Generation threads (0: one per hardware thread)", 0, 1024,
        [](ServerConfig & c) -> auto& { return c.generator.workers; }));
    t.push_back(int_setting(
        "cache-bytes", "Encoded-room LRU cache size in bytes (0: off)", 0, kMaxBytes,
        [](ServerConfig & c) -> auto& { return c.generator.cache_bytes; }));
    t.push_back(int_setting(
        "sector-cache-entries", "Sector layouts kept (LRU), all worlds together", 1, 1 << 24,
        [](ServerConfig & c) -> auto& { return c.generator.sector_cache_entries; }));
    t.push_back(int_setting(
        "batch-rooms", "Rooms per build call (one kernel launch)", 1, 4096,
        [](ServerConfig & c) -> auto& { return c.generator.max_batch_rooms; }));
    t.push_back(ms_setting(
        "batch-wait-ms", "Longest wait for a fuller batch", 0, 10'000,
        [](ServerConfig & c) -> auto& { return c.generator.max_batch_wait; }));
    t.push_back(ms_setting(
        "job-deadline-ms", "Queued longer than this: overloaded error", 1, kMaxInt,
        [](ServerConfig & c) -> auto& { return c.generator.job_deadline; }));
    t.push_back(ms_setting(
        "urgent-ms",
        "Rooms a player can reach within this many ms are built before others' far prefetch "
        "(round-robin within each class); 0: one class",
        0, 600'000, [](ServerConfig & c) -> auto& { return c.generator.urgent_within; }));
    t.push_back(string_setting(
        "room-tier",
        "Cluster: the room tier, http://HOST:PORT (nginx in front of the replicas, "
        "deploy/nginx): rooms this replica's players want are asked of their owner replica there "
        "first, and built here when it fails or is late; empty: every room is built here",
        {}, [](ServerConfig & c) -> auto& { return c.room_tier; }));
    t.push_back(ms_setting(
        "owner-timeout-ms",
        "Cluster: the longest a room asked of the room tier may take before it is built here "
        "(a room due sooner waits its slack less 500 ms, at least 150 ms)",
        1, 60'000, [](ServerConfig & c) -> auto& { return c.generator.owner_timeout; }));
    t.push_back(string_setting(
        "opencl-device",
        "OpenCL device: auto, gpu, accelerator, cpu, none (CPU reference) or a name substring; "
        "empty: $GROTTO_OPENCL_DEVICE, else auto",
        {}, [](ServerConfig & c) -> auto& { return c.generator.builder.device.device; }));
    {
      Setting queue{"opencl-queue",
                    "How the workers use the OpenCL device: shared (one context and queue; "
                    "batches that wait for the device go up together in one launch) or "
                    "per-worker (a context and queue each)",
                    Setting::Type::kString,
                    0,
                    0,
                    {"shared", "per-worker"},
                    {},
                    {}};
      queue.get = [](const ServerConfig& c) {
        return Value{std::string(c.generator.share_device ? "shared" : "per-worker")};
      };
      queue.set = [](ServerConfig& c, const Value& v) {
        c.generator.share_device = std::get<std::string>(v) == "shared";
      };
      t.push_back(std::move(queue));
    }
    {
      Setting viewer{"viewer",
                     "Serve the browser viewer at / and the room extras it reads at /extras/ "
                     "(true or false; --no-viewer is false)",
                     Setting::Type::kBool,
                     0,
                     0,
                     {},
                     {},
                     {}};
      viewer.get = [](const ServerConfig& c) { return Value{c.viewer}; };
      viewer.set = [](ServerConfig& c, const Value& v) { c.viewer = std::get<bool>(v); };
      t.push_back(std::move(viewer));
    }
    t.push_back(string_setting(
        "log-level", "trace, debug, info, warn, error or off",
        {"trace", "debug", "info", "warn", "error", "off"},
        [](ServerConfig & c) -> auto& { return c.log_level; }));
    t.push_back(string_setting(
        "token-file",
        "File whose first line (trimmed) is the shared-secret token every hello must carry "
        "(1-256 bytes of printable ASCII). Without this setting $GROTTO_TOKEN is used; with "
        "neither (or GROTTO_TOKEN empty) no token is required",
        {}, [](ServerConfig & c) -> auto& { return c.token_file; }));
    return t;
  }();
  return table;
}

Result<Value> check_range(const Setting& s, int64_t v) {
  if (v < s.min || v > s.max) {
    return invalid_argument("must be in [" + std::to_string(s.min) + ", " + std::to_string(s.max) +
                            "] (got " + std::to_string(v) + ")");
  }
  return Value{v};
}

Result<Value> check_choice(const Setting& s, std::string v) {
  if (!s.choices.empty() && std::find(s.choices.begin(), s.choices.end(), v) == s.choices.end()) {
    std::string list;
    for (const auto& c : s.choices)
      list += (list.empty() ? "" : ", ") + c;
    return invalid_argument("must be one of " + list + " (got '" + proto::echo(v) + "')");
  }
  return Value{std::move(v)};
}

// A flag's text.
Result<Value> from_text(const Setting& s, const std::string& text) {
  auto bad = [&](const char* what) {
    return invalid_argument(std::string("must be ") + what + " (got '" + proto::echo(text) + "')");
  };
  const char* b = text.data();
  const char* e = b + text.size();
  switch (s.type) {
    case Setting::Type::kInt: {
      int64_t v = 0;
      auto [p, ec] = std::from_chars(b, e, v);
      if (ec != std::errc() || p != e || text.empty()) return bad("an integer");
      return check_range(s, v);
    }
    case Setting::Type::kUint64: {
      uint64_t v = 0;
      auto [p, ec] = std::from_chars(b, e, v);
      if (ec != std::errc() || p != e || text.empty()) return bad("an unsigned 64-bit integer");
      return Value{v};
    }
    case Setting::Type::kDouble: {
      double v = 0;
      auto [p, ec] = std::from_chars(b, e, v);
      if (ec != std::errc() || p != e || text.empty() || !std::isfinite(v)) return bad("a number");
      return Value{v};
    }
    case Setting::Type::kString:
      return check_choice(s, text);
    case Setting::Type::kBool:
      if (text == "true") return Value{true};
      if (text == "false") return Value{false};
      return bad("true or false");
  }
  return bad("valid");
}

// A config file's value.
Result<Value> from_json(const Setting& s, const proto::ConfigValue& v) {
  using K = proto::ConfigValue::Kind;
  auto wrong = [&](const char* want) {
    return invalid_argument(std::string("must be ") + want + " (got " + proto::describe(v.kind) +
                            ")");
  };
  switch (s.type) {
    case Setting::Type::kInt:
      if (v.kind != K::kInteger) return wrong("an integer");
      return check_range(s, v.integer);
    case Setting::Type::kUint64:
      // Seeds over 2^53 do not survive a JSON number in every reader: a string is accepted too.
      if (v.kind == K::kString) return from_text(s, v.string);
      if (v.kind == K::kInteger && v.integer >= 0) return Value{static_cast<uint64_t>(v.integer)};
      return wrong("an unsigned 64-bit integer or a decimal string");
    case Setting::Type::kDouble:
      if (v.kind != K::kInteger && v.kind != K::kNumber) return wrong("a number");
      return Value{v.number};
    case Setting::Type::kString:
      if (v.kind != K::kString) return wrong("a string");
      return check_choice(s, v.string);
    case Setting::Type::kBool:
      if (v.kind != K::kBool) return wrong("a boolean");
      return Value{v.boolean};
  }
  return wrong("valid");
}

const Setting* find_setting(const std::string& name) {
  for (const auto& s : settings()) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

}  // namespace

std::string product_version() {
  return std::string("grotto-server ") + GROTTO_VERSION;
}

Status validate(const ServerConfig& config) {
  if (auto st = cave::validate(config.layout); !st) {
    return invalid_argument("layout: " + st.error().message);
  }
  if (auto st = mesh::validate(config.mesh); !st) {
    return invalid_argument("mesh: " + st.error().message);
  }
  if (config.limits.max_message_bytes < 1024) {
    return invalid_argument("max-message-bytes must be >= 1024");
  }
  if (config.limits.max_frame_bytes < 1024) {
    return invalid_argument("max-frame-bytes must be >= 1024");
  }
  if (config.limits.max_rooms_per_request < 1 || config.limits.max_rooms_in_flight < 1 ||
      config.limits.max_lod > 255 || config.limits.idle_timeout_ms < 1 ||
      config.limits.handshake_timeout_ms < 1) {
    return invalid_argument("limits out of range (see --help)");
  }
  if (config.max_connections < 1) return invalid_argument("max-connections must be >= 1");
  if (!config.room_tier.empty()) {
    if (auto url = parse_tier_url(config.room_tier); !url) {
      return invalid_argument("room-tier: " + url.error().message);
    }
  }
  if (config.max_handshakes < 1) return invalid_argument("max-handshakes must be >= 1");
  if (config.send_queue_bytes < 1024) return invalid_argument("send-queue-bytes must be >= 1024");
  if (config.bind.empty()) return invalid_argument("bind must not be empty");
  if (!config.token.empty()) {
    if (auto st = proto::check_token(config.token); !st) {
      return invalid_argument("token: " + st.error().message);
    }
  }
  return {};
}

Status apply_config_file(const std::string& path, ServerConfig& config) {
  auto values = proto::read_config_file(path);
  if (!values) return values.error();
  for (const auto& [key, value] : *values) {
    const Setting* s = find_setting(key);
    if (s == nullptr) {
      return invalid_argument("config file " + path + ": unknown setting '" + proto::echo(key) +
                              "'");
    }
    auto v = from_json(*s, value);
    if (!v) {
      return invalid_argument("config file " + path + ": setting '" + key + "' " +
                              v.error().message);
    }
    s->set(config, *v);
  }
  return {};
}

CommandLine parse_command_line(int argc, const char* const* argv) {
  CommandLine out;
  // GCC 12 at -O3 (the README's Release build) warns that the destructor of this value's
  // strings may read them uninitialized, a false positive of its -Wmaybe-uninitialized, silenced
  // here only.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
  const ServerConfig defaults{};
#pragma GCC diagnostic pop
  CLI::App app{
      product_version() +
          ": streams procedurally generated cave rooms to game clients over WebSocket "
          "(ws://HOST:PORT/ws) and serves /healthz, /readyz, /metrics and /version on the "
          "same port.\nSettings: flags over a JSON config file (--config; keys are the long "
          "flag names without --) over the defaults shown.",
      "grotto-server"};
  std::string config_path;
  app.add_option("--config", config_path,
                 "JSON config file: {\"port\": 7878, \"workers\": 4, ...}");
  bool version = false;
  app.add_flag("--version", version, "Print the product and protocol version and exit");
  bool no_viewer = false;
  app.add_flag("--no-viewer", no_viewer, "Do not serve the browser viewer (as --viewer false)");
  std::map<std::string, std::string> given;
  for (const auto& s : settings()) {
    std::string help = s.help + " [default: " + show(s.get(defaults)) + "]";
    app.add_option("--" + s.name, given[s.name], help)
        ->type_name(s.type == Setting::Type::kString   ? "TEXT"
                    : s.type == Setting::Type::kDouble ? "NUMBER"
                    : s.type == Setting::Type::kBool   ? "BOOL"
                                                       : "INT");
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    out.text = app.help();
    return out;
  } catch (const CLI::ParseError& e) {
    out.exit_code = 2;
    out.text = std::string("grotto-server: ") + e.what() + " (see --help)";
    return out;
  }
  if (version) {
    out.text = product_version() + " (protocol " + std::to_string(proto::kMinProtocolVersion) +
               " to " + std::to_string(proto::kProtocolVersion) + ")";
    return out;
  }
  ServerConfig config;
  if (!config_path.empty()) {
    if (auto st = apply_config_file(config_path, config); !st) {
      out.exit_code = 2;
      out.text = "grotto-server: " + st.error().message;
      return out;
    }
  }
  for (const auto& s : settings()) {
    if (app.get_option("--" + s.name)->count() == 0) continue;
    auto v = from_text(s, given[s.name]);
    if (!v) {
      out.exit_code = 2;
      out.text = "grotto-server: --" + s.name + " " + v.error().message;
      return out;
    }
    s.set(config, *v);
  }
  if (no_viewer) config.viewer = false;
  auto token = proto::resolve_token(config.token_file, std::getenv(proto::kTokenEnvVariable));
  if (!token) {
    out.exit_code = 2;
    out.text = "grotto-server: " + token.error().message;
    return out;
  }
  config.token = std::move(token).value();
  if (auto st = validate(config); !st) {
    out.exit_code = 2;
    out.text = "grotto-server: invalid configuration: " + st.error().message;
    return out;
  }
  out.config = std::move(config);
  out.run = true;
  return out;
}

}  // namespace grotto::server
