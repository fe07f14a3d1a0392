// client/stream's connection: the one Boost.Beast translation unit of the client library. It
// moves bytes and timers only; the protocol (handshake, rooms in flight, plan, failures,
// reconnect policy) is the Conversation's (conversation.hpp), whose actions it carries out.
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
#include <condition_variable>
#include <deque>
#include <future>
#include <mutex>
#include <optional>
#include <random>
#include <span>
#include <thread>

#include "client/stream/conversation.hpp"
#include "client/stream/decode_queue.hpp"
#include "client/stream/net_sim.hpp"
#include "common/codec/room_codec.hpp"
#include "common/core/thread_name.hpp"

namespace grotto::stream {

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
  DecodeQueue decodes;  // what the workers decode next: the most urgent first

  Impl(int io_threads, int worker_threads)
      : workers(static_cast<size_t>(worker_threads > 0
                                        ? worker_threads
                                        : std::max(1u, std::thread::hardware_concurrency()))) {
    for (int i = 0; i < std::max(1, io_threads); ++i)
      io.emplace_back([this] {
        name_this_thread("stream-io");
        ioc.run();
      });
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

// ---- Stream ----

namespace {

// A message the simulated network (StreamOptions::net) holds until its link delivers it: a
// frame, or the end of the connection (a close or an error), which waits behind the frames.
struct Held {
  Clock::time_point due;
  std::string bytes;
  bool text = false;
  bool end = false;
  beast::error_code ec;  // with `end`: websocket::error::closed for a close, else the error
  uint16_t close_code = 0;
  std::string close_reason;
};

// One WebSocket connection: its stream, read buffer and write queue.
struct Conn {
  explicit Conn(net::strand<net::io_context::executor_type> strand)
      : ws(strand), inbox_timer(strand), outbox_timer(strand) {}
  websocket::stream<beast::tcp_stream> ws;
  beast::flat_buffer buffer;
  std::deque<std::string> queue;  // text messages waiting for the one async_write in flight
  bool writing = false;
  // The simulated network, when there is one: each direction's link, and what it holds.
  std::optional<NetLink> down, up;
  std::deque<Held> inbox;  // received, not yet delivered to the conversation
  size_t inbox_bytes = 0;
  bool read_paused = false;  // the inbox is full: the socket is not read until it drains
  std::deque<std::pair<Clock::time_point, std::string>> outbox;  // sent, not yet on the wire
  net::steady_timer inbox_timer, outbox_timer;
};

// What the simulated link's buffers hold before the player stops reading its socket: past it,
// the server's socket backs up as over a real slow link (and its send queue keeps the urgent rooms
// first), instead of the whole stream piling up here.
constexpr size_t kSimulatedBufferBytes = size_t{64} << 10;

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
        conversation(o, std::random_device{}()) {}

  const StreamOptions options;
  const Url url;
  Runtime::Impl& rt;
  net::strand<net::io_context::executor_type> strand;
  tcp::resolver resolver;
  net::steady_timer timer;  // reconnect backoff
  net::steady_timer tick;   // the conversation's periodic work while a connection is open

  // Guarded by mu (strand handlers hold it for their whole run; they are short, decoding runs on
  // the Runtime's workers, so a renderer calling room() waits microseconds).
  mutable std::mutex mu;
  Conversation conversation;  // the protocol: everything but bytes and timers
  bool stopping = false;
  // Notified when a room is stored and when the Stream fails or stops (wait_area_ready).
  mutable std::condition_variable changed;
  std::atomic<bool> stop_called{false};

  // Strand only.
  std::shared_ptr<Conn> conn;
  std::promise<void> stopped;

  // ---- carrying out the conversation's actions ----

  void run(Actions actions) {
    for (auto& action : actions) {
      std::visit([this](auto& a) { act(a); }, action);
    }
  }

  void act(SendMessage& m) { send(proto::serialize(m.message)); }

  // Every Stream of the Runtime queues its decodes in one DecodeQueue; each post lets a worker
  // take the most urgent job there, which need not be this one.
  void act(DecodeRoom& job) {
    const SteadyTime due = job.due;
    rt.decodes.push(due, [self = shared_from_this(), job = std::move(job)]() mutable {
      auto start = Clock::now();
      auto mesh = decode_payload(job);
      job.sample.decode_ms =
          std::chrono::duration<double, std::milli>(Clock::now() - start).count();
      net::post(self->strand, [self, job = std::move(job), mesh = std::move(mesh)]() mutable {
        std::lock_guard lock(self->mu);
        if (self->stopping) return;
        self->run(self->conversation.decoded(std::move(job), std::move(mesh), Clock::now()));
        self->changed.notify_all();
      });
    });
    net::post(rt.workers, [&decodes = rt.decodes] {
      thread_local bool named = false;  // the pool's threads are Asio's: named at their first job
      if (!named) name_this_thread("stream-decode");
      named = true;
      if (auto next = decodes.pop()) next();
    });
  }

  void act(SetReadLimit& r) {
    if (conn) conn->ws.read_message_max(r.bytes);
  }

  void act(Reconnect& r) {
    close_socket();
    spdlog::info("event=stream_dropped url={}:{} reason=\"{}\" retry_ms={}", url.host, url.port,
                 r.why, r.delay.count());
    tick.cancel();
    timer.expires_after(r.delay);
    timer.async_wait([self = shared_from_this()](beast::error_code ec) {
      if (!ec) self->connect();
    });
  }

  void act(Fail& f) {
    spdlog::error("event=stream_failed url={}:{} reason=\"{}\"", url.host, url.port, f.why);
    changed.notify_all();
    timer.cancel();
    tick.cancel();
    close_socket();
  }

  void close_socket() {
    if (!conn) return;
    beast::error_code ignored;
    beast::get_lowest_layer(conn->ws).socket().close(ignored);
    conn.reset();
  }

  // ---- connecting ----

  void connect() {
    std::lock_guard lock(mu);
    if (stopping) return;
    conversation.connecting();
    auto self = shared_from_this();
    resolver.async_resolve(url.host, std::to_string(url.port),
                           [self](beast::error_code ec, tcp::resolver::results_type results) {
                             self->on_resolve(ec, std::move(results));
                           });
  }

  void on_resolve(beast::error_code ec, tcp::resolver::results_type results) {
    std::lock_guard lock(mu);
    if (stopping) return;
    if (ec) return lost("resolving " + url.host + ": " + ec.message());
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
      return lost("connecting to " + url.host + ":" + std::to_string(url.port) + ": " +
                  ec.message());
    beast::get_lowest_layer(c->ws).socket().set_option(tcp::no_delay(true));
    const auto& limits = conversation.limits();
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
    if (ec) return lost("WebSocket upgrade at " + url.path + ": " + ec.message());
    beast::get_lowest_layer(c->ws).expires_never();
    // Beast's pings find a server that vanished without closing (a cable pulled, a VM paused).
    websocket::stream_base::timeout t{};
    t.handshake_timeout = options.connect_timeout;
    t.idle_timeout = std::chrono::seconds(15);
    t.keep_alive_pings = true;
    c->ws.set_option(t);
    if (options.net.active()) {
      // The simulated network: the TCP connect and the upgrade took a round trip each.
      const auto now = Clock::now();
      const uint64_t seed = std::random_device{}();
      c->down.emplace(options.net, true, now, seed);
      c->up.emplace(options.net, false, now, seed ^ 0x9e3779b97f4a7c15ull);
      c->inbox_timer.expires_after(2 * options.net.rtt);
      c->inbox_timer.async_wait([self = shared_from_this(), c](beast::error_code e) {
        std::lock_guard guard(self->mu);
        if (e || c != self->conn || self->stopping) return;
        self->open(c);
      });
      return;
    }
    open(c);
  }

  void open(const std::shared_ptr<Conn>& c) {
    run(conversation.opened(Clock::now()));
    if (c != conn) return;
    read(c);
    start_tick();
  }

  void lost(const std::string& why) { run(conversation.lost(why, Clock::now())); }

  // ---- reading ----

  void read(const std::shared_ptr<Conn>& c) {
    c->ws.async_read(c->buffer, [self = shared_from_this(), c](beast::error_code ec, size_t) {
      self->on_read(c, ec);
    });
  }

  void on_read(const std::shared_ptr<Conn>& c, beast::error_code ec) {
    std::lock_guard lock(mu);
    if (c != conn || stopping) return;
    if (c->down) return hold(c, ec);
    if (ec) {
      if (ec != websocket::error::closed) return lost("reading: " + ec.message());
      const auto& reason = c->ws.reason();
      return run(conversation.closed(static_cast<uint16_t>(reason.code),
                                     std::string_view(reason.reason.c_str()), Clock::now()));
    }
    auto data = c->buffer.cdata();
    std::span<const uint8_t> bytes(static_cast<const uint8_t*>(data.data()), data.size());
    if (c->ws.got_text()) {
      run(conversation.text(
          std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
          Clock::now()));
    } else {
      run(conversation.binary(bytes, Clock::now()));
    }
    c->buffer.consume(c->buffer.size());
    if (c == conn) read(c);
  }

  // ---- the simulated network: what was read waits for its link to deliver it ----

  void hold(const std::shared_ptr<Conn>& c, beast::error_code ec) {
    Held h;
    if (ec) {
      h.end = true;
      h.ec = ec;
      if (ec == websocket::error::closed) {
        h.close_code = static_cast<uint16_t>(c->ws.reason().code);
        h.close_reason = std::string(c->ws.reason().reason.c_str());
      }
    } else {
      auto data = c->buffer.cdata();
      h.bytes.assign(static_cast<const char*>(data.data()), data.size());
      h.text = c->ws.got_text();
      c->buffer.consume(c->buffer.size());
    }
    h.due = c->down->arrival(Clock::now(), h.bytes.size());
    c->inbox_bytes += h.bytes.size();
    c->inbox.push_back(std::move(h));
    if (c->inbox.size() == 1) arm_inbox(c);
    if (ec) return;
    if (c->inbox_bytes < kSimulatedBufferBytes) {
      read(c);
    } else {
      c->read_paused = true;
    }
  }

  void arm_inbox(const std::shared_ptr<Conn>& c) {
    if (c->inbox.empty()) return;
    c->inbox_timer.expires_at(c->inbox.front().due);
    c->inbox_timer.async_wait([self = shared_from_this(), c](beast::error_code ec) {
      std::lock_guard lock(self->mu);
      if (ec || c != self->conn || self->stopping) return;
      self->deliver(c);
    });
  }

  void deliver(const std::shared_ptr<Conn>& c) {
    while (c == conn && !c->inbox.empty() && c->inbox.front().due <= Clock::now()) {
      Held h = std::move(c->inbox.front());
      c->inbox.pop_front();
      c->inbox_bytes -= h.bytes.size();
      if (h.end) {
        if (h.ec != websocket::error::closed) return lost("reading: " + h.ec.message());
        return run(conversation.closed(h.close_code, h.close_reason, Clock::now()));
      }
      if (h.text) {
        run(conversation.text(h.bytes, Clock::now()));
      } else {
        run(conversation.binary(
            std::span(reinterpret_cast<const uint8_t*>(h.bytes.data()), h.bytes.size()),
            Clock::now()));
      }
    }
    if (c != conn) return;
    if (c->read_paused && c->inbox_bytes < kSimulatedBufferBytes) {
      c->read_paused = false;
      read(c);
    }
    arm_inbox(c);
  }

  void arm_outbox(const std::shared_ptr<Conn>& c) {
    if (c->outbox.empty()) return;
    c->outbox_timer.expires_at(c->outbox.front().first);
    c->outbox_timer.async_wait([self = shared_from_this(), c](beast::error_code ec) {
      std::lock_guard lock(self->mu);
      if (ec || c != self->conn || self->stopping) return;
      while (!c->outbox.empty() && c->outbox.front().first <= Clock::now()) {
        c->queue.push_back(std::move(c->outbox.front().second));
        c->outbox.pop_front();
      }
      if (!c->writing && !c->queue.empty()) self->write(c);
      self->arm_outbox(c);
    });
  }

  // ---- periodic work ----

  void start_tick() {
    tick.expires_after(options.replan_interval);
    tick.async_wait([self = shared_from_this(), c = conn](beast::error_code ec) {
      if (!ec) self->on_tick(c);
    });
  }

  void on_tick(const std::shared_ptr<Conn>& c) {
    std::lock_guard lock(mu);
    if (stopping || c != conn || !conn) return;
    run(conversation.tick(Clock::now()));
    if (c == conn) start_tick();
  }

  // ---- writing ----

  void send(std::string text) {
    if (!conn) return;
    if (conn->up) {  // the simulated network: on the wire once its link carries it there
      const auto due = conn->up->arrival(Clock::now(), text.size());
      conn->outbox.emplace_back(due, std::move(text));
      if (conn->outbox.size() == 1) arm_outbox(conn);
      return;
    }
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
                        if (c != self->conn || self->stopping) return;
                        if (ec) return self->lost("writing: " + ec.message());
                        c->queue.pop_front();
                        if (!c->queue.empty()) self->write(c);
                      });
  }

  // ---- stopping ----

  void shut_down() {
    std::unique_lock lock(mu);
    stopping = true;
    changed.notify_all();
    const bool welcomed = conversation.welcomed();
    conversation.stop();
    timer.cancel();
    tick.cancel();
    resolver.cancel();
    auto c = std::move(conn);
    if (!c || !welcomed) {
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
  if (Status valid = validate_options(options); !valid) return valid.error();
  auto url = parse_url(options.url);
  if (!url) return url.error();
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
  impl_->conversation.set_pose(pose);
}

std::optional<proto::SpawnPoint> Stream::spawn_point() const {
  std::lock_guard lock(impl_->mu);
  return impl_->conversation.spawn_point();
}

std::shared_ptr<const ReadyRoom> Stream::room(cave::RoomId id) const {
  std::lock_guard lock(impl_->mu);
  return impl_->conversation.room(id);
}

std::optional<cave::Room> Stream::descriptor(cave::RoomId id) const {
  std::lock_guard lock(impl_->mu);
  if (const auto* r = impl_->conversation.graph().find(id)) return *r;
  return std::nullopt;
}

std::vector<std::shared_ptr<const ReadyRoom>> Stream::take_new_rooms() {
  std::lock_guard lock(impl_->mu);
  return impl_->conversation.take_new_rooms();
}

std::vector<cave::RoomId> Stream::take_evicted() {
  std::lock_guard lock(impl_->mu);
  return impl_->conversation.take_evicted();
}

std::vector<RoomSample> Stream::take_samples() {
  std::lock_guard lock(impl_->mu);
  return impl_->conversation.take_samples();
}

StreamStats Stream::stats() const {
  std::lock_guard lock(impl_->mu);
  return impl_->conversation.stats();
}

StreamState Stream::state() const {
  std::lock_guard lock(impl_->mu);
  return impl_->conversation.state();
}

AreaStatus Stream::area_status(Vec3 point, double radius_m, uint32_t max_lod) const {
  std::lock_guard lock(impl_->mu);
  return stream::area_status(impl_->conversation.graph(), impl_->conversation.store(), point,
                             radius_m, max_lod);
}

bool Stream::wait_area_ready(Vec3 point, double radius_m, uint32_t max_lod,
                             std::chrono::milliseconds timeout) const {
  // A year is forever here, and milliseconds::max() would overflow the deadline.
  const auto deadline =
      Clock::now() + std::min(timeout, milliseconds(std::chrono::hours(24 * 365)));
  std::unique_lock lock(impl_->mu);
  Conversation& c = impl_->conversation;
  auto ready = [&] {
    return stream::area_status(c.graph(), c.store(), point, radius_m, max_lod).ready;
  };
  if (ready()) return true;
  if (timeout <= milliseconds(0)) return false;
  // While this call waits, the plan requests the area's rooms and the store keeps them
  // (Conversation::pin_area); the pin goes when the call returns, whichever way (the guard is
  // destroyed while `lock` still holds the mutex).
  struct Unpin {
    Conversation& c;
    uint64_t handle;
    ~Unpin() { c.unpin_area(handle); }
  } pin{c, c.pin_area({point, radius_m, max_lod, deadline})};
  while (true) {
    if (impl_->stopping || c.state() == StreamState::kFailed) return false;
    // One lod a session: rooms come at lod(), so an area asked for below it never completes.
    if (c.welcomed() && c.lod() > max_lod) return false;
    if (impl_->changed.wait_until(lock, deadline) == std::cv_status::timeout) return ready();
    if (ready()) return true;
  }
}

}  // namespace grotto::stream
