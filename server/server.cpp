// The listener: accepting on the server's one port (with the socket limit, the pause after a
// failed accept and the fd reserve that keeps health checks answering with no descriptors left),
// the session registry, and the server's start and stop. The sessions are http_session.cpp and
// ws_session.cpp.
#include "server/server.hpp"

#include <poll.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <boost/asio/dispatch.hpp>
#include <boost/asio/post.hpp>
#include <cstring>
#include <future>

#include "common/cave/layout.hpp"
#include "common/core/random.hpp"
#include "common/core/thread_name.hpp"
#include "proto/world_digest.hpp"
#include "server/server_impl.hpp"

namespace grotto::server {
namespace {

// While the reserve holds descriptors, a paused acceptor looks again at least this often, so a
// probe waits at most this long in the backlog (with none held, the pause doubles up to 1 s).
constexpr auto kReservePause = std::chrono::milliseconds{100};
// Silent connections closed in one turn of the accept strand (the rest wait for the next turn).
constexpr int kReserveDrainPerTurn = 256;

}  // namespace

void Server::Impl::do_accept() {
  acceptor->async_accept(net::make_strand(ioc), [this](beast::error_code ec, tcp::socket s) {
    on_accept(ec, std::move(s));
  });
}

void Server::Impl::on_accept(beast::error_code ec, tcp::socket socket) {
  // While stopping, the acceptor stays open until the drain ends: a connection arriving then is
  // answered (an upgrade gets service_restart and close 1001, /readyz 503), not refused at TCP.
  if (!acceptor->is_open()) return;
  if (!ec) {
    accept_backoff = std::chrono::milliseconds{0};
    beast::error_code ignored;
    // Messages go out as soon as they are written (no Nagle wait behind a delayed ACK).
    socket.set_option(tcp::no_delay(true), ignored);
    if (int open = sockets.fetch_add(1) + 1; open > max_sockets()) {
      sockets.fetch_sub(1);
      metrics.sockets_shed.add();
      if (auto now = Clock::now(); now - shed_logged >= std::chrono::seconds{1}) {
        spdlog::warn("event=socket_shed open={} max={} (max_connections + max_handshakes + {})",
                     open - 1, max_sockets(), kSpareSocketCount);
        shed_logged = now;
      }
      socket.close(ignored);
      return do_accept();
    } else {
      metrics.sockets_open.set(open);
    }
    start_http_session(*this, std::move(socket), SocketSlot(sockets, metrics));
    if (reserve.held() + reserve_loans < kReserveCount) refill_reserve();
    return do_accept();
  }
  // Out of file descriptors (or another failure): the pending connection stays in the backlog,
  // so accepting again at once would spin. Pause, then try again; log once a second at most.
  // Out of descriptors, the reserve answers health checks meanwhile.
  metrics.accept_failures.add();
  ++accept_failures_unlogged;
  if (ec == net::error::no_descriptors || ec == beast::errc::too_many_files_open_in_system) {
    serve_from_reserve();
  }
  auto longest = reserve.held() > 0 ? kReservePause : std::chrono::milliseconds{1000};
  accept_backoff = std::clamp(accept_backoff * 2, std::chrono::milliseconds{10}, longest);
  if (auto now = Clock::now(); now - accept_logged >= std::chrono::seconds{1}) {
    spdlog::warn(
        "event=accept_failed error=\"{}\" failures={} pause_ms={} reserve_held={} "
        "reserve_connections={}",
        ec.message(), accept_failures_unlogged, accept_backoff.count(), reserve.held(),
        metrics.fd_reserve_connections.value());
    accept_failures_unlogged = 0;
    accept_logged = now;
  }
  accept_pause->expires_after(accept_backoff);
  // Cancelled by stop(), or early by a reserve coming back (reserve_returned).
  accept_pause->async_wait([this](beast::error_code) {
    if (acceptor->is_open()) do_accept();
  });
}

// Trades a reserve descriptor for the connection that has waited longest. A silent one with
// others behind it is closed at once (counted as shed), so a backlog of squatters cannot keep a
// probe from its turn; one with a request to read, or the last in line, is answered health-only.
void Server::Impl::serve_from_reserve() {
  if (!reserve.release()) return refill_reserve();  // none held: try to open them again
  metrics.fd_reserve_held.set(reserve.held());
  beast::error_code ignored;
  for (int drained = 0; drained <= kReserveDrainPerTurn; ++drained) {
    tcp::socket socket(net::make_strand(ioc));
    beast::error_code ec;
    acceptor->accept(socket, ec);  // the acceptor is non-blocking: would_block when none waits
    if (ec) break;
    if (socket.available(ignored) == 0 && connection_waiting()) {
      metrics.sockets_shed.add();
      socket.close(ignored);  // its number goes to the next in line
      continue;
    }
    socket.set_option(tcp::no_delay(true), ignored);
    metrics.sockets_open.set(sockets.fetch_add(1) + 1);
    metrics.fd_reserve_connections.add();
    ++reserve_loans;
    start_http_session(*this, std::move(socket), SocketSlot(sockets, metrics), ReserveLoan(*this));
    return;
  }
  refill_reserve();  // the number went unused: nobody waiting, or another thread took it
}

bool Server::Impl::connection_waiting() {
  pollfd p{acceptor->native_handle(), POLLIN, 0};
  return ::poll(&p, 1, 0) == 1 && (p.revents & POLLIN) != 0;
}

// Opens the reserve up to kReserveCount, less the descriptors out with connections; a failure is
// counted, logged once a second at most, and retried on the next accept, pause or returned
// reserve connection.
void Server::Impl::refill_reserve() {
  int err = reserve.refill(kReserveCount - reserve_loans);
  metrics.fd_reserve_held.set(reserve.held());
  if (err == 0) return;
  metrics.fd_reserve_refill_failures.add();
  if (auto now = Clock::now(); now - refill_logged >= std::chrono::seconds{1}) {
    spdlog::warn("event=fd_reserve_refill_failed error=\"{}\" held={} of {}", std::strerror(err),
                 reserve.held(), kReserveCount);
    refill_logged = now;
  }
}

void Server::Impl::reserve_returned() {
  if (stopping.load()) return;  // the strand may be gone with the io_context
  net::post(*accept_strand, [this] {
    if (stopping.load()) return;
    --reserve_loans;
    refill_reserve();
    accept_pause->cancel();  // a paused acceptor looks at the backlog now
  });
}

// ---- Server ----

Redirect Server::Impl::redirect_newcomer() const {
  std::lock_guard lock(sessions_mutex);
  Door door;
  door.stopping = stopping.load();
  door.players = players();
  door.handshakes = handshakes;
  door.max_connections = static_cast<size_t>(config.max_connections);
  door.max_handshakes = static_cast<size_t>(config.max_handshakes);
  if (admission) {
    door.admission = true;
    door.admitted = admission->admitted();
    door.queued = admission->queued();
    door.max_players = admission->config().max_players;
    door.behind = admission->behind();
    door.burst_left = admission->burst_left();
  }
  return grotto::server::redirect_newcomer(door);
}

Entry Server::Impl::enter(uint64_t id, bool can_queue) {
  std::lock_guard lock(sessions_mutex);
  if (!admission) return {};
  auto decision = admission->enter(id, can_queue, Clock::now());
  Entry e;
  if (decision) {
    if (auto* q = std::get_if<adm::Queued>(&*decision)) {
      e = Entry{Entry::Kind::kQueued, q->position, q->wait_ms, q->queue, 0, false};
      queued.insert(id);
      queue_length.store(queued.size());
      --handshakes;
      metrics.handshakes_open.set(static_cast<int64_t>(handshakes));
      metrics.sessions_queued.set(static_cast<int64_t>(queued.size()));
    } else if (auto* r = std::get_if<adm::Refuse>(&*decision)) {
      e = Entry{Entry::Kind::kRefused, 0, 0, 0, r->retry_after_ms, r->queue_full};
    }
  }
  carry_out(admission->take(), id);
  return e;
}

void Server::Impl::carry_out(std::vector<AdmissionAction> actions, uint64_t entering) {
  for (AdmissionAction& a : actions) {
    if (auto* admit = std::get_if<adm::Admit>(&a)) {
      if (admit->session == entering || !queued.erase(admit->session)) continue;
      // A handshake again until its world opens (promote()).
      ++handshakes;
      metrics.handshakes_open.set(static_cast<int64_t>(handshakes));
      metrics.sessions_admitted_from_queue.add();
      auto it = sessions.find(admit->session);
      if (it == sessions.end()) continue;
      if (auto p = it->second.lock()) admit_session(*p);
    } else if (auto* place = std::get_if<adm::Queued>(&a)) {
      if (place->session == entering) continue;
      auto it = sessions.find(place->session);
      if (it == sessions.end()) continue;
      if (auto p = it->second.lock()) tell_session(*p, *place);
    }
  }
  queue_length.store(queued.size());
  metrics.sessions_queued.set(static_cast<int64_t>(queued.size()));
}

void Server::Impl::start_measuring() {
  if (!admission || stopping.load()) return;
  measure_timer->expires_after(kMeasureEvery);
  measure_timer->async_wait([this](beast::error_code ec) {
    if (ec || stopping.load()) return;
    measure();
    start_measuring();
  });
}

void Server::Impl::measure() {
  AdmissionSample sample;
  sample.oldest_urgent = generator->oldest_urgent();  // the generator's lock, not ours
  sample.oldest_want = generator->oldest_want();
  const uint64_t served = metrics.rooms_served.value();
  sample.rooms_per_s = static_cast<double>(served - rooms_served_before) * 1000.0 /
                       static_cast<double>(kMeasureEvery.count());
  rooms_served_before = served;
  std::lock_guard lock(sessions_mutex);
  admission->measure(sample, Clock::now());
  carry_out(admission->take(), 0);
  metrics.oldest_urgent_ms.set(sample.oldest_urgent.count());
  metrics.admission_behind.set(admission->behind() ? 1 : 0);
  metrics.admission_capacity.set(static_cast<int64_t>(admission->capacity()));
  metrics.admission_burst.set(static_cast<int64_t>(admission->burst()));
}

Server::Server(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Server::~Server() {
  stop(impl_->config.drain_timeout);
}

Result<std::unique_ptr<Server>> Server::start(const ServerConfig& config) {
  if (auto st = validate(config); !st) return st.error();
  auto world = cave::World::create(config.seed, config.layout);
  if (!world) return invalid_argument("layout: " + world.error().message);
  int threads = config.io_threads > 0
                    ? config.io_threads
                    : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  auto impl = std::make_unique<Impl>(threads);
  impl->config = config;
  impl->params_digest = proto::world_params_digest(config.layout, config.mesh);
  auto generator = Generator::create(*world, config.mesh, config.generator, impl->metrics);
  if (!generator) return generator.error();
  impl->generator = std::move(generator).value();
  impl->metrics.set_compute_path(impl->generator->compute_path());
  if (config.admission.late_after.count() > 0 || config.admission.max_players > 0) {
    AdmissionConfig a = config.admission;
    if (a.late_after.count() == 0) a.late_after = std::chrono::hours{24};  // max_players alone
    // Caught up needs clearly less than late: a margin, so the two thresholds never cross.
    a.caught_up_below = std::min(a.caught_up_below, a.late_after / 2);
    impl->admission.emplace(a);
    impl->measure_timer.emplace(net::make_strand(impl->ioc));
  }

  beast::error_code ec;
  auto address = net::ip::make_address(config.bind, ec);
  if (ec) return invalid_argument("bind: '" + proto::echo(config.bind) + "' is not an IP address");
  tcp::endpoint endpoint(address, config.port);
  impl->accept_strand.emplace(net::make_strand(impl->ioc));
  impl->acceptor.emplace(*impl->accept_strand);
  impl->accept_pause.emplace(*impl->accept_strand);
  auto& acc = *impl->acceptor;
  auto where = config.bind + ":" + std::to_string(config.port);
  if (acc.open(endpoint.protocol(), ec); ec) {
    return Error{ErrorCode::kUnavailable,
                 "cannot open a socket for " + where + ": " + ec.message()};
  }
  if (acc.set_option(net::socket_base::reuse_address(true), ec); ec) {
    return Error{ErrorCode::kUnavailable, "cannot set SO_REUSEADDR: " + ec.message()};
  }
  if (acc.bind(endpoint, ec); ec) {
    return Error{ErrorCode::kUnavailable, "cannot bind " + where + ": " + ec.message()};
  }
  if (acc.listen(net::socket_base::max_listen_connections, ec); ec) {
    return Error{ErrorCode::kUnavailable, "cannot listen on " + where + ": " + ec.message()};
  }
  impl->bound = acc.local_endpoint(ec);
  // Sync accepts (serve_from_reserve) must not block; async_accept is unaffected.
  if (acc.non_blocking(true, ec); ec) {
    return Error{ErrorCode::kUnavailable, "cannot make the listener non-blocking: " + ec.message()};
  }
  impl->refill_reserve();  // before any thread runs: the accept strand is not yet in use
  net::dispatch(*impl->accept_strand, [p = impl.get()] { p->do_accept(); });
  if (impl->measure_timer) {
    net::dispatch(impl->measure_timer->get_executor(), [p = impl.get()] { p->start_measuring(); });
  }
  for (int i = 0; i < threads; ++i) {
    impl->threads.emplace_back([p = impl.get()] {
      name_this_thread("grotto-io");
      p->ioc.run();
    });
  }
  spdlog::info(
      "event=listening address={}:{} io_threads={} compute=\"{}\" seed={} max_connections={} "
      "token={}",
      impl->bound.address().to_string(), impl->bound.port(), threads,
      impl->generator->compute_path(), config.seed, config.max_connections,
      config.token.empty() ? "off" : "required");
  return std::unique_ptr<Server>(new Server(std::move(impl)));
}

uint16_t Server::port() const {
  return impl_->bound.port();
}

std::string Server::address() const {
  auto a = impl_->bound.address();
  std::string host = a.is_v6() ? "[" + a.to_string() + "]" : a.to_string();
  return host + ":" + std::to_string(impl_->bound.port());
}

const ServerConfig& Server::config() const {
  return impl_->config;
}
Metrics& Server::metrics() {
  return impl_->metrics;
}
Generator& Server::generator() {
  return *impl_->generator;
}
bool Server::stopping() const {
  return impl_->stopping.load();
}

size_t Server::sessions() const {
  std::lock_guard lock(impl_->sessions_mutex);
  return impl_->sessions.size();
}

void Server::stop(std::chrono::milliseconds drain) {
  std::lock_guard stop_lock(impl_->stop_mutex);
  if (impl_->stopped) return;
  impl_->stopped = true;
  auto& s = *impl_;
  auto deadline = Clock::now() + drain;
  spdlog::info("event=stopping drain_ms={}", drain.count());
  // From here on admit() refuses every upgrade with service_restart, but the acceptor stays open
  // until the drain ends (PROTOCOL.md, Closing): a client that arrives during it is told to go
  // elsewhere with a random delay, as the players being drained are, instead of meeting a TCP
  // refusal it cannot tell from a dead server. Bounded: by max_sockets() and the drain.
  s.stopping.store(true);
  if (s.measure_timer) {
    net::dispatch(s.measure_timer->get_executor(), [&s] { s.measure_timer->cancel(); });
  }
  std::vector<std::shared_ptr<WsSession>> live;
  {
    std::lock_guard lock(s.sessions_mutex);
    for (auto& [id, weak] : s.sessions) {
      if (auto p = weak.lock()) live.push_back(std::move(p));
    }
  }
  for (auto& p : live)
    shutdown_session(*p);
  // Queued rooms fail with service_restart; building ones finish within their batch.
  s.generator->shutdown(
      std::max(std::chrono::milliseconds{0},
               std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now())));
  live.clear();
  {
    std::unique_lock lock(s.sessions_mutex);
    s.sessions_cv.wait_until(lock, deadline, [&] { return s.sessions.empty(); });
    for (auto& [id, weak] : s.sessions) {
      if (auto p = weak.lock()) live.push_back(std::move(p));
    }
  }
  {
    // The drain is over: stop accepting (on the acceptor's strand; wait for it so no accept races
    // the rest). Connections arriving from now on are refused at TCP.
    std::promise<void> closed;
    auto done = closed.get_future();
    net::dispatch(*s.accept_strand, [&] {
      beast::error_code ignored;
      s.acceptor->close(ignored);
      s.accept_pause->cancel();
      closed.set_value();
    });
    done.wait_for(std::chrono::milliseconds{1000});
  }
  if (!live.empty()) {
    spdlog::warn("event=drain_timeout sessions_left={}", live.size());
    for (auto& p : live)
      cut_session(*p);
    live.clear();
    std::unique_lock lock(s.sessions_mutex);
    s.sessions_cv.wait_for(lock, std::chrono::milliseconds{200},
                           [&] { return s.sessions.empty(); });
  }
  {
    std::lock_guard lock(s.gate->mutex);
    s.gate->open = false;
  }
  s.ioc.stop();
  for (auto& t : s.threads)
    t.join();
  s.threads.clear();
  spdlog::info("event=stopped");
}

}  // namespace grotto::server
