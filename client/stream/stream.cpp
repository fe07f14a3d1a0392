// client/stream's connection: the one Boost.Beast translation unit of the client library.
//
// A Stream is an Impl shared by its handlers (enable_shared_from_this, as in Beast's examples) and
// serialized on a strand of the Runtime's io_context. Each WebSocket connection is a Conn of its
// own; a dropped Conn is forgotten at once and its pending handlers, which hold it alive, find
// that it is no longer current and return. State that other threads read (pose, store, stats,
// graph) sits behind one mutex, which strand handlers take for their whole run: they are short
// (decoding runs on the Runtime's workers), so a renderer calling room() waits microseconds.
#include "client/stream/stream.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/bind_executor.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <cmath>
#include <deque>
#include <future>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include "codec/room_codec.hpp"
#include "proto/lod.hpp"
#include "proto/room_frame.hpp"
#include "proto/token.hpp"

namespace grotto::client {

namespace beast = boost::beast;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

// ---- Runtime ----

struct Runtime::Impl {
  net::io_context ioc;
  net::executor_work_guard<net::io_context::executor_type> work{ioc.get_executor()};
  std::vector<std::thread> io;
  net::thread_pool workers;

  Impl(int io_threads, int worker_threads)
      : workers(static_cast<size_t>(worker_threads > 0
                                        ? worker_threads
                                        : std::max(1u, std::thread::hardware_concurrency()))) {
    for (int i = 0; i < std::max(1, io_threads); ++i)
      io.emplace_back([this] { ioc.run(); });
  }
  ~Impl() {
    workers.join();
    work.reset();
    ioc.stop();
    for (auto& t : io)
      t.join();
  }
};

Runtime::Runtime(int io_threads, int workers)
    : impl_(std::make_unique<Impl>(io_threads, workers)) {}
Runtime::~Runtime() = default;

const char* state_name(StreamState state) {
  switch (state) {
    case StreamState::kConnecting:
      return "connecting";
    case StreamState::kReady:
      return "ready";
    case StreamState::kBackoff:
      return "backoff";
    case StreamState::kFailed:
      return "failed";
    case StreamState::kStopped:
      return "stopped";
  }
  return "unknown";
}

// ---- Stream ----

namespace {

// One WebSocket connection: its stream, read buffer and write queue.
struct Conn {
  explicit Conn(net::strand<net::io_context::executor_type> strand) : ws(strand) {}
  websocket::stream<beast::tcp_stream> ws;
  beast::flat_buffer buffer;
  std::deque<std::string> queue;  // text messages waiting for the one async_write in flight
  bool writing = false;
  bool welcomed = false;
  std::string fatal;  // the fatal error the server sent before closing ("overloaded: ..."), if any
};

struct InFlight {
  Clock::time_point sent;
  uint32_t priority = 0;
};

// Errors that no reconnect can cure: the server refuses this client as it is.
bool is_final(ErrorCode code) {
  return code == ErrorCode::kUnsupportedVersion || code == ErrorCode::kWorldMismatch ||
         code == ErrorCode::kUnauthorized;
}

// Samples and evicted ids kept for a caller that does not drain them.
constexpr size_t kMaxUndrained = size_t{1} << 16;

double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

}  // namespace

struct Stream::Impl : std::enable_shared_from_this<Stream::Impl> {
  Impl(const StreamOptions& o, Url u, Runtime& runtime)
      : options(o),
        url(std::move(u)),
        rt(runtime.impl()),
        strand(net::make_strand(rt.ioc)),
        resolver(strand),
        timer(strand),
        tick(strand),
        store(o.store_bytes),
        rng(std::random_device{}()) {}

  const StreamOptions options;
  const Url url;
  Runtime::Impl& rt;
  net::strand<net::io_context::executor_type> strand;
  tcp::resolver resolver;
  net::steady_timer timer;  // reconnect backoff, or the welcome deadline
  net::steady_timer tick;   // replan, ping, request timeouts

  // Guarded by mu (strand handlers hold it for their whole run).
  mutable std::mutex mu;
  Pose pose;
  bool pose_set = false;
  bool pose_from_spawn = false;  // the pose is the server's spawn point, not the caller's
  bool pose_dirty = false;
  std::optional<proto::SpawnPoint> spawn;
  PortalGraph graph;
  RoomStore store;
  std::vector<std::shared_ptr<const ReadyRoom>> fresh;
  std::vector<RoomSample> samples;
  std::vector<cave::RoomId> evicted;
  StreamStats stats;
  bool stopping = false;
  std::atomic<bool> stop_called{false};

  // Strand only.
  std::shared_ptr<Conn> conn;
  proto::Limits limits;                                // the welcome's, or defaults before one
  std::optional<std::pair<uint64_t, uint64_t>> world;  // (seed, params) of the last welcome
  std::map<cave::RoomId, InFlight> in_flight;
  std::set<cave::RoomId> decoding;
  std::map<cave::RoomId, int> failures;
  std::set<cave::RoomId> given_up;
  std::map<uint64_t, std::vector<cave::RoomId>> pending;  // request ref -> its rooms
  std::set<cave::RoomId> wanted;                          // the last plan
  std::optional<cave::RoomId> current;
  uint64_t next_ref = 1;
  int attempts = 0;  // reconnects since the last welcome
  Clock::time_point last_send;
  Clock::time_point last_plan;
  Clock::time_point hold_until;  // after `overloaded`: no requests before this
  Clock::time_point last_locate;
  std::mt19937_64 rng;
  std::promise<void> stopped;

  // ---- connecting ----

  void connect() {
    std::lock_guard lock(mu);
    if (stopping) return;
    stats.state = StreamState::kConnecting;
    auto self = shared_from_this();
    resolver.async_resolve(url.host, std::to_string(url.port),
                           [self](beast::error_code ec, tcp::resolver::results_type results) {
                             self->on_resolve(ec, std::move(results));
                           });
  }

  void on_resolve(beast::error_code ec, tcp::resolver::results_type results) {
    std::lock_guard lock(mu);
    if (stopping) return;
    if (ec) return fail_connect("resolving " + url.host + ": " + ec.message());
    conn = std::make_shared<Conn>(strand);
    auto c = conn;
    beast::get_lowest_layer(c->ws).expires_after(options.connect_timeout);
    beast::get_lowest_layer(c->ws).async_connect(
        results, [self = shared_from_this(), c](beast::error_code e, const tcp::endpoint&) {
          self->on_connect(c, e);
        });
  }

  void on_connect(const std::shared_ptr<Conn>& c, beast::error_code ec) {
    std::lock_guard lock(mu);
    if (c != conn || stopping) return;
    if (ec)
      return fail_connect("connecting to " + url.host + ":" + std::to_string(url.port) + ": " +
                          ec.message());
    beast::get_lowest_layer(c->ws).socket().set_option(tcp::no_delay(true));
    c->ws.read_message_max(std::max(limits.max_frame_bytes, limits.max_message_bytes));
    std::string host = url.host + ":" + std::to_string(url.port);
    // The seed as a query routing hint (PROTOCOL.md, Transport): a load balancer hashing on it
    // sends every player of one world to the same replica.
    std::string target = url.path;
    if (options.seed) {
      target += (target.find('?') == std::string::npos ? "?seed=" : "&seed=") +
                std::to_string(*options.seed);
    }
    c->ws.async_handshake(host, target, [self = shared_from_this(), c](beast::error_code e) {
      self->on_handshake(c, e);
    });
  }

  void on_handshake(const std::shared_ptr<Conn>& c, beast::error_code ec) {
    std::lock_guard lock(mu);
    if (c != conn || stopping) return;
    if (ec) return fail_connect("WebSocket upgrade at " + url.path + ": " + ec.message());
    beast::get_lowest_layer(c->ws).expires_never();
    // Beast's pings find a server that vanished without closing (a cable pulled, a VM paused).
    websocket::stream_base::timeout t{};
    t.handshake_timeout = options.connect_timeout;
    t.idle_timeout = std::chrono::seconds(15);
    t.keep_alive_pings = true;
    c->ws.set_option(t);
    proto::Hello hello;
    hello.ref = next_ref++;
    hello.versions = {proto::kProtocolVersion};
    hello.seed = options.seed;
    hello.params = options.params;
    hello.name = options.name;
    if (!options.token.empty()) hello.token = options.token;
    send(proto::serialize(proto::ClientMessage{hello}));
    read(c);
    // The welcome must come within connect_timeout of the upgrade.
    timer.expires_after(options.connect_timeout);
    timer.async_wait([self = shared_from_this(), c](beast::error_code e) {
      std::lock_guard guard(self->mu);
      if (e || c != self->conn || c->welcomed) return;
      self->drop("no welcome within " + std::to_string(self->options.connect_timeout.count()) +
                 " ms");
    });
  }

  void fail_connect(const std::string& why) { drop(why); }

  // ---- reading ----

  void read(const std::shared_ptr<Conn>& c) {
    c->ws.async_read(c->buffer, [self = shared_from_this(), c](beast::error_code ec, size_t) {
      self->on_read(c, ec);
    });
  }

  void on_read(const std::shared_ptr<Conn>& c, beast::error_code ec) {
    std::lock_guard lock(mu);
    if (c != conn || stopping) return;
    if (ec) {
      if (ec != websocket::error::closed) return drop("reading: " + ec.message());
      const std::string reason(c->ws.reason().reason.c_str());
      // The fatal error that came before the close says why better than its reason.
      return drop("server closed the connection (" + std::to_string(c->ws.reason().code) +
                      (reason.empty() ? "" : " " + proto::echo(reason)) + ")" +
                      (c->fatal.empty() ? "" : ": " + c->fatal),
                  reason == "service_restart");
    }
    stats.bytes_received += c->buffer.size();
    auto data = c->buffer.cdata();
    std::span<const uint8_t> bytes(static_cast<const uint8_t*>(data.data()), data.size());
    if (c->ws.got_text()) {
      on_text(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
    } else {
      on_frame(bytes);
    }
    c->buffer.consume(c->buffer.size());
    if (c == conn) read(c);
  }

  void on_text(std::string_view text) {
    auto parsed = proto::parse_server_message(text, limits);
    if (!parsed) {
      ++stats.errors["bad_message"];
      note_error("server sent an invalid message: " + parsed.error().message);
      if (!conn->welcomed) drop("before welcome: " + parsed.error().message);
      return;
    }
    std::visit([this](auto& m) { on_message(m); }, parsed.value());
  }

  void on_message(const proto::Welcome& w) {
    if (conn->welcomed) return note_error("server sent a second welcome");
    if (w.version != proto::kProtocolVersion) {
      return fail("server chose protocol version " + std::to_string(w.version) +
                  "; this client speaks only version " + std::to_string(proto::kProtocolVersion));
    }
    if (options.seed && w.seed != *options.seed) {
      return fail("server serves seed " + std::to_string(w.seed) + ", not the requested " +
                  std::to_string(*options.seed));
    }
    if (world && *world != std::pair{w.seed, w.params}) {
      // Another world behind the same address (a redeploy with another seed or parameters): what
      // we hold belongs to the old one. Renderers learn of it through take_evicted().
      spdlog::warn("event=world_changed server={} seed={} action=clear_rooms", w.server, w.seed);
      for (auto id : store.ids())
        evicted.push_back(id);
      stats.rooms_evicted += store.size();
      graph.clear();
      store.clear();
      fresh.clear();
      failures.clear();
      given_up.clear();
      current.reset();
      wanted.clear();
      if (pose_from_spawn) {  // the old world's spawn point means nothing here
        pose_set = false;
        pose_from_spawn = false;
        pose = {};
      }
      spawn.reset();
    }
    world = std::pair{w.seed, w.params};
    conn->welcomed = true;
    timer.cancel();
    limits = w.limits;
    conn->ws.read_message_max(std::max(limits.max_frame_bytes, limits.max_message_bytes));
    stats.limits = limits;
    stats.server = w.server;
    stats.seed = w.seed;
    stats.state = StreamState::kReady;
    if (stats.connects++ > 0) ++stats.reconnects;
    attempts = 0;
    if (options.lod > limits.max_lod) {
      note_error("server serves lod up to " + std::to_string(limits.max_lod) + "; asked for " +
                 std::to_string(options.lod) + ", using " + std::to_string(limits.max_lod));
    }
    if (!pose_set && options.spawn && !spawn) {
      proto::Spawn s;
      s.ref = next_ref++;
      send(proto::serialize(proto::ClientMessage{s}));
    }
    plan();
    start_tick();
  }

  void on_message(const proto::SpawnPoint& s) {
    spawn = s;
    if (!pose_set) {
      pose.position = s.position;
      pose.room = s.room;
      pose_set = true;
      pose_from_spawn = true;
    }
    plan();
  }

  void on_message(const proto::Located& l) {
    if (l.room) current = l.room;
    plan();
  }

  void on_message(const proto::ErrorMessage& e) {
    const char* code = proto::wire_code_name(e.code);
    // service_restart is a graceful drain (PROTOCOL.md), a notice rather than an error: the close
    // follows and drop() reconnects at once. What it names is asked for again on the next
    // connection, so it is no failure of a room.
    const bool restart = e.code == ErrorCode::kServiceRestart;
    if (restart) {
      ++stats.restart_notices;
      spdlog::debug("event=stream_restart_notice url={}:{} detail=\"{}\"", url.host, url.port,
                    e.message);
    } else {
      ++stats.errors[code];
      note_error(std::string("server error ") + code + ": " + e.message);
    }
    if (e.room) {
      in_flight.erase(*e.room);
      if (e.code == ErrorCode::kNotFound) {
        give_up(*e.room);
      } else if (!restart) {
        count_failure(*e.room);
      }
    } else if (e.ref) {
      // A request refused whole put nothing in flight (PROTOCOL.md "Rooms in flight").
      if (auto it = pending.find(*e.ref); it != pending.end()) {
        for (auto id : it->second)
          in_flight.erase(id);
        pending.erase(it);
      }
    }
    if (e.code == ErrorCode::kOverloaded || e.code == ErrorCode::kLimitExceeded) {
      hold_until = Clock::now() + backoff_delay(1);
    }
    if (e.fatal) conn->fatal = std::string(code) + ": " + e.message;  // checked by the parser
    if (e.fatal && is_final(e.code)) fail(std::string(code) + ": " + e.message);
    // Other fatal errors: the server closes next, and on_read reconnects.
  }

  void on_message(const proto::Pong&) {}
  void on_message(const proto::Stats&) {}

  void on_frame(std::span<const uint8_t> bytes) {
    if (!conn->welcomed) return drop("a room frame before welcome");
    auto decoded = proto::decode_room_frame(bytes, limits);
    if (!decoded) {
      ++stats.rooms_rejected;
      note_error("refused a room frame: " + decoded.error().message);
      // The id field, when it is there and names a room we asked for: ask again.
      if (bytes.size() >= 16) {
        uint64_t packed = 0;
        for (int i = 0; i < 8; ++i)
          packed |= uint64_t{bytes[8 + i]} << (8 * i);
        if (auto id = cave::RoomId::unpack(packed); id && in_flight.erase(id.value())) {
          count_failure(id.value());
        }
      }
      return plan();
    }
    proto::RoomFrame frame = std::move(decoded).value();
    const cave::RoomId id = frame.room.id;
    auto it = in_flight.find(id);
    if (it == in_flight.end() && !wanted.count(id)) {
      // Cancelled while on the wire, or never asked for.
      return;
    }
    if (frame.lod != std::min(options.lod, limits.max_lod)) {
      ++stats.rooms_rejected;
      note_error("room " + id.to_string() + " came at lod " + std::to_string(frame.lod));
      if (it != in_flight.end()) in_flight.erase(it);
      count_failure(id);
      return plan();
    }
    RoomSample sample;
    sample.id = id;
    sample.frame_bytes = bytes.size();
    if (it != in_flight.end()) {
      sample.latency_ms = ms_since(it->second.sent);
      in_flight.erase(it);
    }
    if (auto added = graph.add(frame.room); !added) {
      ++stats.rooms_rejected;
      note_error("room " + id.to_string() +
                 " disagrees with a neighbour: " + added.error().message);
      count_failure(id);
      return plan();
    }
    ++stats.rooms_received;
    decoding.insert(id);
    auto limits_for_lod = frame.lod == 0 ? codec::DecodeLimits{} : codec::kDetailLimits;
    limits_for_lod.portal_count = static_cast<int>(frame.room.portals.size());
    net::post(rt.workers, [self = shared_from_this(), frame = std::move(frame), limits_for_lod,
                           sample]() mutable {
      auto start = Clock::now();
      auto mesh = codec::decode_room(frame.payload, limits_for_lod);
      sample.decode_ms = ms_since(start);
      net::post(self->strand,
                [self, frame = std::move(frame), mesh = std::move(mesh), sample]() mutable {
                  self->on_decoded(std::move(frame), std::move(mesh), sample);
                });
    });
    plan();  // the new descriptor's portals extend the graph
  }

  void on_decoded(proto::RoomFrame frame, Result<codec::DecodedRoom> mesh, RoomSample sample) {
    std::lock_guard lock(mu);
    const cave::RoomId id = frame.room.id;
    decoding.erase(id);
    if (stopping) return;
    if (!mesh) {
      ++stats.rooms_rejected;
      note_error("room " + id.to_string() + ": " + mesh.error().message);
      count_failure(id);
      return plan();
    }
    auto ready = std::make_shared<ReadyRoom>();
    ready->room = std::move(frame.room);
    ready->lod = frame.lod;
    ready->origin = frame.origin;
    ready->mesh = std::move(mesh).value();
    ready->payload_bytes = frame.payload.size();
    ready->decode_ms = sample.decode_ms;
    store.insert(ready);
    fresh.push_back(ready);
    samples.push_back(sample);
    failures.erase(id);
    ++stats.rooms_ready;
    auto gone = store.evict(pose.position, wanted);
    stats.rooms_evicted += gone.size();
    // Their descriptors go too, so a long walk keeps the graph as bounded as the store; coming
    // back asks for the rooms again, descriptors included.
    for (auto g : gone)
      graph.remove(g);
    evicted.insert(evicted.end(), gone.begin(), gone.end());
    // A caller that never drains must not make memory grow without bound: rooms it never took
    // and that are gone now are dropped from `fresh` (it holds them alive), and the oldest
    // samples and evicted ids go past kMaxUndrained.
    if (!gone.empty() && !fresh.empty()) {
      std::set<cave::RoomId> dead(gone.begin(), gone.end());
      std::erase_if(fresh, [&](const auto& r) { return dead.count(r->room.id) != 0; });
    }
    trim(samples);
    trim(evicted);
  }

  template <class T>
  static void trim(std::vector<T>& v) {
    if (v.size() > kMaxUndrained) v.erase(v.begin(), v.begin() + (v.size() - kMaxUndrained));
  }

  // ---- planning ----

  void plan() {
    if (!conn || !conn->welcomed || stopping) return;
    last_plan = Clock::now();
    pose_dirty = false;
    std::optional<cave::RoomId> start = pose.room;
    if (!start) start = graph.room_at(pose.position);
    if (!start) start = current;
    if (!start && spawn) start = spawn->room;
    if (!start) {
      if (pose_set && Clock::now() - last_locate > std::chrono::seconds(1)) {
        last_locate = Clock::now();
        proto::Locate l;
        l.ref = next_ref++;
        l.point = pose.position;
        send(proto::serialize(proto::ClientMessage{l}));
      }
      return;
    }
    current = start;
    PlanOptions wide = options.plan;
    wide.horizon_s *= options.cancel_factor;
    auto keep = graph.plan(*start, pose, wide);
    std::set<cave::RoomId> keep_ids;
    wanted.clear();
    for (const auto& p : keep) {
      keep_ids.insert(p.id);
      if (p.seconds <= options.plan.horizon_s) wanted.insert(p.id);
    }
    const uint32_t batch = batch_size();
    std::vector<cave::RoomId> cancels;
    for (auto it = in_flight.begin(); it != in_flight.end();) {
      if (keep_ids.count(it->first)) {
        ++it;
        continue;
      }
      cancels.push_back(it->first);
      it = in_flight.erase(it);
    }
    for (size_t i = 0; i < cancels.size(); i += batch) {
      proto::Cancel c;
      c.ref = next_ref++;
      c.rooms.assign(cancels.begin() + i,
                     cancels.begin() + std::min(cancels.size(), size_t{i + batch}));
      stats.cancels_sent += c.rooms.size();
      send(proto::serialize(proto::ClientMessage{c}));
    }
    if (Clock::now() < hold_until) return;
    const size_t cap = std::min(options.max_in_flight, limits.max_rooms_in_flight);
    std::vector<proto::RoomWant> wants;
    const uint32_t lod = std::min(options.lod, limits.max_lod);
    for (const auto& p : keep) {
      if (in_flight.size() + wants.size() >= cap) break;
      if (p.seconds > options.plan.horizon_s) break;
      if (store.contains(p.id) || in_flight.count(p.id) || decoding.count(p.id) ||
          given_up.count(p.id)) {
        continue;
      }
      double ms = std::min(p.seconds * 1000.0, 4294967295.0);
      wants.push_back({p.id, lod, static_cast<uint32_t>(ms)});
    }
    auto now = Clock::now();
    for (size_t i = 0; i < wants.size(); i += batch) {
      proto::Request r;
      r.ref = next_ref++;
      r.rooms.assign(wants.begin() + i, wants.begin() + std::min(wants.size(), size_t{i + batch}));
      auto& ids = pending[*r.ref];
      for (const auto& w : r.rooms) {
        in_flight[w.id] = {now, w.priority};
        ids.push_back(w.id);
      }
      stats.requests_sent += r.rooms.size();
      send(proto::serialize(proto::ClientMessage{r}));
    }
    // Refs are answered only by a refusal, which comes before later replies: keep a bounded tail.
    while (pending.size() > 256)
      pending.erase(pending.begin());
  }

  // Rooms per request or cancel: the server's limit, and what fits in max_message_bytes (an entry
  // is at most ~72 bytes of JSON: a 30-character id, lod, a 10-digit priority).
  uint32_t batch_size() const {
    uint32_t by_bytes = limits.max_message_bytes > 256 ? (limits.max_message_bytes - 128) / 80 : 1;
    return std::max(1u, std::min(limits.max_rooms_per_request, by_bytes));
  }

  void count_failure(cave::RoomId id) {
    if (++failures[id] >= options.max_room_failures) give_up(id);
  }

  void give_up(cave::RoomId id) {
    if (given_up.insert(id).second) ++stats.rooms_given_up;
  }

  void note_error(const std::string& message) {
    stats.last_error = message;
    spdlog::debug("event=stream_error url={}:{} detail=\"{}\"", url.host, url.port, message);
  }

  // ---- periodic work ----

  void start_tick() {
    tick.expires_after(options.replan_interval);
    tick.async_wait([self = shared_from_this()](beast::error_code ec) {
      if (!ec) self->on_tick();
    });
  }

  void on_tick() {
    std::lock_guard lock(mu);
    if (stopping || !conn || !conn->welcomed) return;
    auto now = Clock::now();
    bool replan = pose_dirty;
    // Rooms in flight too long: the server lost them, or a frame was refused without an id.
    for (auto it = in_flight.begin(); it != in_flight.end();) {
      if (now - it->second.sent > options.request_timeout) {
        it = in_flight.erase(it);
        replan = true;
      } else {
        ++it;
      }
    }
    if (now >= hold_until && hold_until != Clock::time_point{}) {
      hold_until = {};
      replan = true;
    }
    if (replan) plan();
    auto ping_every = milliseconds(std::clamp<int64_t>(limits.idle_timeout_ms / 3, 1, 10'000));
    if (now - last_send > ping_every) {
      proto::Ping p;
      p.t = std::chrono::duration<double, std::milli>(now.time_since_epoch()).count();
      send(proto::serialize(proto::ClientMessage{p}));
    }
    start_tick();
  }

  // ---- writing ----

  void send(std::string text) {
    if (!conn) return;
    last_send = Clock::now();
    conn->queue.push_back(std::move(text));
    if (!conn->writing) write(conn);
  }

  void write(const std::shared_ptr<Conn>& c) {
    c->writing = true;
    c->ws.text(true);
    c->ws.async_write(net::buffer(c->queue.front()),
                      [self = shared_from_this(), c](beast::error_code ec, size_t) {
                        std::lock_guard lock(self->mu);
                        c->writing = false;
                        if (c != self->conn) return;
                        if (ec) return self->drop("writing: " + ec.message());
                        c->queue.pop_front();
                        if (!c->queue.empty()) self->write(c);
                      });
  }

  // ---- losing the connection ----

  milliseconds backoff_delay(int attempt) {
    double base =
        static_cast<double>(options.backoff_initial.count()) * std::pow(2.0, std::min(attempt, 30));
    base = std::min(base, static_cast<double>(options.backoff_max.count()));
    std::uniform_real_distribution<double> jitter(0.5, 1.0);  // "equal jitter"
    return milliseconds(static_cast<int64_t>(base * jitter(rng)));
  }

  // Forgets the connection and everything in flight on it, then reconnects after a backoff. A
  // service_restart reconnects after the shortest delay (another replica is likely up).
  void drop(const std::string& why, bool restart = false) {
    if (conn) {
      beast::error_code ignored;
      beast::get_lowest_layer(conn->ws).socket().close(ignored);
      conn.reset();
      ++stats.drops;
    }
    in_flight.clear();
    pending.clear();
    hold_until = {};
    note_error(why);
    if (stats.state == StreamState::kFailed) return;
    stats.state = StreamState::kBackoff;
    auto delay = backoff_delay(restart ? 0 : attempts++);
    spdlog::info("event=stream_dropped url={}:{} reason=\"{}\" retry_ms={}", url.host, url.port,
                 why, delay.count());
    timer.expires_after(delay);
    timer.async_wait([self = shared_from_this()](beast::error_code ec) {
      if (!ec) self->connect();
    });
  }

  // Stops for good: the server refuses this client as configured.
  void fail(const std::string& why) {
    spdlog::error("event=stream_failed url={}:{} reason=\"{}\"", url.host, url.port, why);
    stats.state = StreamState::kFailed;
    stats.last_error = why;
    timer.cancel();
    tick.cancel();
    if (conn) {
      beast::error_code ignored;
      beast::get_lowest_layer(conn->ws).socket().close(ignored);
      conn.reset();
    }
    in_flight.clear();
  }

  void shut_down() {
    std::unique_lock lock(mu);
    stopping = true;
    if (stats.state != StreamState::kFailed) stats.state = StreamState::kStopped;
    timer.cancel();
    tick.cancel();
    resolver.cancel();
    auto c = std::move(conn);
    if (!c || !c->welcomed) {
      if (c) {
        beast::error_code ignored;
        beast::get_lowest_layer(c->ws).socket().close(ignored);
      }
      stopped.set_value();
      return;
    }
    // A normal close, bounded: the server answers at once unless it is gone.
    beast::get_lowest_layer(c->ws).expires_after(std::chrono::seconds(1));
    c->ws.async_close(websocket::close_code::normal, [self = shared_from_this(), c](auto) {
      beast::error_code ignored;
      beast::get_lowest_layer(c->ws).socket().close(ignored);
      self->stopped.set_value();
    });
  }
};

Result<std::unique_ptr<Stream>> Stream::start(const StreamOptions& options, Runtime& runtime) {
  auto url = parse_url(options.url);
  if (!url) return url.error();
  auto invalid = [](const std::string& why) { return Error{ErrorCode::kInvalidArgument, why}; };
  if (!(options.plan.horizon_s > 0) || !std::isfinite(options.plan.horizon_s)) {
    return invalid("horizon must be a positive number of seconds");
  }
  if (!(options.cancel_factor >= 1) || !std::isfinite(options.cancel_factor)) {
    return invalid("cancel_factor must be at least 1");
  }
  if (options.max_in_flight < 1) return invalid("max_in_flight must be at least 1");
  if (options.backoff_initial.count() < 1 || options.backoff_max < options.backoff_initial) {
    return invalid("backoff: need 1 ms <= initial <= max");
  }
  if (options.max_room_failures < 1) return invalid("max_room_failures must be at least 1");
  if (!options.token.empty()) {
    if (auto st = proto::check_token(options.token); !st)
      return invalid("token " + st.error().message);
  }
  auto impl = std::make_shared<Impl>(options, std::move(url).value(), runtime);
  net::post(impl->strand, [impl] { impl->connect(); });
  return std::unique_ptr<Stream>(new Stream(std::move(impl)));
}

Stream::Stream(std::shared_ptr<Impl> impl) : impl_(std::move(impl)) {}
Stream::~Stream() {
  stop();
}

void Stream::stop() {
  if (impl_->stop_called.exchange(true)) return;
  auto done = impl_->stopped.get_future();
  net::post(impl_->strand, [impl = impl_] { impl->shut_down(); });
  done.wait_for(std::chrono::seconds(3));
}

void Stream::set_pose(const Pose& pose) {
  std::lock_guard lock(impl_->mu);
  impl_->pose = pose;
  impl_->pose_set = true;
  impl_->pose_from_spawn = false;
  impl_->pose_dirty = true;
}

std::optional<proto::SpawnPoint> Stream::spawn_point() const {
  std::lock_guard lock(impl_->mu);
  return impl_->spawn;
}

std::shared_ptr<const ReadyRoom> Stream::room(cave::RoomId id) const {
  std::lock_guard lock(impl_->mu);
  return impl_->store.find(id);
}

std::optional<cave::Room> Stream::descriptor(cave::RoomId id) const {
  std::lock_guard lock(impl_->mu);
  if (const auto* r = impl_->graph.find(id)) return *r;
  return std::nullopt;
}

std::vector<std::shared_ptr<const ReadyRoom>> Stream::take_new_rooms() {
  std::lock_guard lock(impl_->mu);
  return std::exchange(impl_->fresh, {});
}

std::vector<cave::RoomId> Stream::take_evicted() {
  std::lock_guard lock(impl_->mu);
  return std::exchange(impl_->evicted, {});
}

std::vector<RoomSample> Stream::take_samples() {
  std::lock_guard lock(impl_->mu);
  return std::exchange(impl_->samples, {});
}

StreamStats Stream::stats() const {
  std::lock_guard lock(impl_->mu);
  StreamStats s = impl_->stats;
  s.in_flight = impl_->in_flight.size();
  s.store_bytes = impl_->store.bytes();
  s.store_rooms = impl_->store.size();
  return s;
}

StreamState Stream::state() const {
  std::lock_guard lock(impl_->mu);
  return impl_->stats.state;
}

}  // namespace grotto::client
