// What the listener (server.cpp) and its sessions (http_session.cpp, ws_session.cpp) share: the
// server's state, the socket slot and reserve loan a session holds, and how each session starts.
// Internal to the server: it includes Beast, whose headers cost about 25 s and 0.8 GB per file to
// compile, so only those three files include it. Structure after Beast's examples
// (example/advanced/server, websocket/server/async): a session is enable_shared_from_this, owns its
// stream and buffer, runs on its own strand and reads as do_x/on_x pairs; sends go through a queue
// with one async_write in flight.
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "server/admission.hpp"
#include "server/conversation.hpp"
#include "server/fd_limit.hpp"
#include "server/server.hpp"

namespace grotto::server {

namespace beast = boost::beast;
namespace http = beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

// Sockets accepted beyond players and handshakes (plain HTTP: probes, scrapes; upgrades on their
// way): fd_limit.hpp's kSpareSockets, which the descriptor limit is sized with.
inline constexpr int kSpareSocketCount = static_cast<int>(kSpareSockets);
// The fd reserve: descriptors on /dev/null held back so that, with the process out of file
// descriptors, /healthz, /readyz and /metrics still answer (an operator's probes and scrapes see
// the server's state when it needs them most). Each is traded for one pending connection,
// answered health-only (its request and its answer each within kReserveDeadline), then closed;
// the reserve is opened again on the accept strand. Its size is fd_limit.hpp's kFdReserve.
inline constexpr int kReserveCount = static_cast<int>(kFdReserve);
inline constexpr auto kReserveDeadline = std::chrono::milliseconds{1000};

// Descriptors held back for health checks while the process has none left. Only the accept strand
// touches it.
class FdReserve {
 public:
  FdReserve() = default;
  FdReserve(const FdReserve&) = delete;
  FdReserve& operator=(const FdReserve&) = delete;
  ~FdReserve() {
    for (int fd : fds_)
      ::close(fd);
  }
  // Opens descriptors until `target` are held: 0, or the errno of the open that failed.
  int refill(int target) {
    while (held() < target) {
      int fd = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
      if (fd < 0) return errno;
      fds_.push_back(fd);
    }
    return 0;
  }
  // Closes one held descriptor so that the next accept can have its number; false if none held.
  bool release() {
    if (fds_.empty()) return false;
    ::close(fds_.back());
    fds_.pop_back();
    return true;
  }
  int held() const { return static_cast<int>(fds_.size()); }

 private:
  std::vector<int> fds_;
};

class WsSession;  // ws_session.cpp

// Shared by every session: configuration, metrics, the generator, the session registry.
struct Server::Impl {
  ServerConfig config;
  uint64_t params_digest = 0;
  Metrics metrics;
  // Declared before the io_context so it is destroyed after it: sessions destroyed with the
  // io_context's pending handlers still call remove_client.
  std::unique_ptr<Generator> generator;
  net::io_context ioc;
  // Room extras (server/extras.hpp: a formation placement, milliseconds) are computed here, off
  // the I/O threads. Declared after the io_context so it is joined first: its jobs hold sessions.
  net::thread_pool extras_pool{2};
  std::optional<tcp::acceptor> acceptor;
  std::optional<net::strand<net::io_context::executor_type>> accept_strand;
  // Accepting pauses after a failure (EMFILE: no file descriptors left), doubling up to a
  // second, and logs once per pause instead of once per failure.
  std::optional<net::steady_timer> accept_pause;
  std::chrono::milliseconds accept_backoff{0};
  uint64_t accept_failures_unlogged = 0;
  FdReserve reserve;      // on the accept strand
  int reserve_loans = 0;  // on the accept strand: reserve descriptors out with connections
  Clock::time_point refill_logged{};
  // Every accepted TCP socket, upgraded or not, holds a slot until its session ends; over
  // max_sockets() new ones are closed at once (shed), so sockets that never send a request
  // cannot use up the process's file descriptors.
  std::atomic<int> sockets{0};
  Clock::time_point shed_logged{};
  int max_sockets() const {
    return config.max_connections + config.max_handshakes +
           static_cast<int>(admission ? config.admission.max_queue : 0) + kSpareSocketCount;
  }
  Clock::time_point accept_logged{};
  std::vector<std::thread> threads;
  tcp::endpoint bound;
  std::atomic<bool> stopping{false};
  // Room GETs waiting for the generator, all HTTP connections together (at most max_connections).
  std::atomic<int> room_gets{0};
  bool stopped = false;  // guarded by stop_mutex
  std::mutex stop_mutex;

  // Sessions on /ws that were admitted: `handshakes` of them have not said hello yet (they count
  // against max_handshakes), the others are players (against max_connections).
  mutable std::mutex sessions_mutex;
  std::condition_variable sessions_cv;
  std::unordered_map<uint64_t, std::weak_ptr<WsSession>> sessions;
  size_t handshakes = 0;
  uint64_t next_session = 1;

  // Admission past capacity (server/admission.hpp), under sessions_mutex; none with
  // admission-late-ms 0. `queued` sessions said a valid hello and wait: neither handshakes nor
  // players. One admitted from the queue counts as a handshake again until promote().
  std::optional<AdmissionQueue> admission;
  std::unordered_set<uint64_t> queued;
  std::atomic<size_t> queue_length{0};  // queued.size(), for /readyz without the lock
  std::optional<net::steady_timer> measure_timer;
  uint64_t rooms_served_before = 0;  // on the timer's handler only
  static constexpr auto kMeasureEvery = std::chrono::milliseconds{250};

  // Generator deliveries go through this gate: once stop() closes it, no worker posts into the
  // io_context any more (a straggling worker may outlive the drain timeout).
  struct Gate {
    std::mutex mutex;
    bool open = true;
  };
  std::shared_ptr<Gate> gate = std::make_shared<Gate>();

  explicit Impl(int threads_hint) : ioc(threads_hint) {}

  // Admission at the upgrade: the session's registry id, or 0 when stopping, when every player
  // slot is taken, or when max_handshakes sessions are still waiting for their hello.
  uint64_t admit(const std::shared_ptr<WsSession>& s, Admission& refusal) {
    std::lock_guard lock(sessions_mutex);
    if (stopping.load()) {
      refusal = Admission::kStopping;
      return 0;
    }
    if (players() >= static_cast<size_t>(config.max_connections)) {
      refusal = Admission::kFull;
      return 0;
    }
    if (handshakes >= static_cast<size_t>(config.max_handshakes)) {
      refusal = Admission::kHandshakesFull;
      return 0;
    }
    uint64_t id = next_session++;
    sessions.emplace(id, s);
    ++handshakes;
    metrics.handshakes_open.set(static_cast<int64_t>(handshakes));
    return id;
  }
  // At hello: the session becomes a player, unless max_connections players are connected.
  bool promote() {
    std::lock_guard lock(sessions_mutex);
    if (players() >= static_cast<size_t>(config.max_connections)) return false;
    --handshakes;
    metrics.handshakes_open.set(static_cast<int64_t>(handshakes));
    return true;
  }
  void leave(uint64_t id, bool player) {
    {
      std::lock_guard lock(sessions_mutex);
      sessions.erase(id);
      const bool was_queued = queued.erase(id) > 0;
      queue_length.store(queued.size());
      if (!player && !was_queued) --handshakes;
      if (admission) {
        admission->leave(id, Clock::now());
        carry_out(admission->take(), 0);
      }
      metrics.handshakes_open.set(static_cast<int64_t>(handshakes));
    }
    sessions_cv.notify_all();
  }
  size_t players() const {  // under sessions_mutex
    return sessions.size() - handshakes - queued.size();
  }

  // A balancer asks, at a marked upgrade, whether a newcomer would get in at once here
  // (server/admission.hpp, redirect_newcomer): kNone, or why it should try another replica.
  Redirect redirect_newcomer() const;
  // A valid hello asks to enter (WorldPort::enter). Admitted, queued or refused.
  Entry enter(uint64_t id, bool can_queue);
  // Periodically (kMeasureEvery): how the players are served, fed to the admission queue.
  void start_measuring();
  void measure();
  // Carries out the admission queue's actions, but those about `entering` (answered in enter()).
  // Under sessions_mutex.
  void carry_out(std::vector<AdmissionAction> actions, uint64_t entering);

  void do_accept();
  void on_accept(beast::error_code ec, tcp::socket socket);
  void serve_from_reserve();
  bool connection_waiting();
  void refill_reserve();
  // A reserve connection ended (its socket is closed): open the reserve again, and look at the
  // backlog at once if the acceptor is paused. From any thread.
  void reserve_returned();
};

// One accepted socket's place in Impl::sockets, held by whichever session owns the socket.
class SocketSlot {
 public:
  SocketSlot(std::atomic<int>& count, Metrics& metrics) : count_(&count), metrics_(&metrics) {}
  SocketSlot(SocketSlot&& other) noexcept
      : count_(std::exchange(other.count_, nullptr)), metrics_(other.metrics_) {}
  SocketSlot& operator=(SocketSlot&&) = delete;
  ~SocketSlot() {
    if (count_) metrics_->sockets_open.set(count_->fetch_sub(1) - 1);
  }

 private:
  std::atomic<int>* count_;
  Metrics* metrics_;
};

// A reserve connection's hold on the reserve. Declared before the session's stream, so the
// socket is closed before the reserve is opened again.
class ReserveLoan {
 public:
  explicit ReserveLoan(Server::Impl& server) : server_(&server) {}
  ReserveLoan(ReserveLoan&& other) noexcept : server_(std::exchange(other.server_, nullptr)) {}
  ReserveLoan& operator=(ReserveLoan&&) = delete;
  ~ReserveLoan() {
    if (server_) server_->reserve_returned();
  }

 private:
  Server::Impl* server_;
};

// Serves one accepted connection over HTTP (health, metrics, the viewer, rooms) until it upgrades
// to /ws or goes. With a loan, it holds a reserve descriptor and is answered health-only.
void start_http_session(Server::Impl& server, tcp::socket&& socket, SocketSlot slot,
                        std::optional<ReserveLoan> loan = std::nullopt);
// Runs the protocol on an upgraded connection: the WebSocket handshake answers `req`.
void start_ws_session(Server::Impl& server, beast::tcp_stream&& stream, SocketSlot slot,
                      http::request<http::string_body>&& req);
// At stop: close a session with service_restart (drain), or cut its socket (drain timed out).
void shutdown_session(WsSession& session);
// The admission queue let a queued session in, or has news of its place (posted to its strand).
void admit_session(WsSession& session);
void tell_session(WsSession& session, adm::Queued place);
void cut_session(WsSession& session);

}  // namespace grotto::server
