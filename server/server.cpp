// The listener, the HTTP sessions and the WebSocket sessions in one translation unit: Beast's
// headers cost about 25 s and 0.8 GB per file to compile, so everything that includes them lives
// here. Structure after Beast's examples (example/advanced/server, websocket/server/async): a
// session is enable_shared_from_this, owns its stream and buffer, runs on its own strand and
// reads as do_x/on_x pairs; sends go through a queue with one async_write in flight.
#include "server/server.hpp"

#include <fcntl.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <boost/asio/dispatch.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/asio/thread_pool.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <future>
#include <mutex>
#include <optional>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include "cave/layout.hpp"
#include "core/random.hpp"
#include "core/thread_name.hpp"
#include "proto/room_path.hpp"
#include "proto/token.hpp"
#include "proto/world_digest.hpp"
#include "server/conversation.hpp"
#include "server/extras.hpp"
#include "server/fd_limit.hpp"
#include "server/room_fetch.hpp"
#include "server/send_queue.hpp"
#include "server/viewer.hpp"

namespace grotto::server {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

constexpr std::size_t kHttpHeaderLimit = 8 * 1024;  // request line and headers
constexpr std::size_t kHttpBodyLimit = 8 * 1024;    // no endpoint takes a body
// A dropped client, or one closed for `timeout`, gets this long to take its close frame (and answer
// it) before the socket is cut.
constexpr auto kCloseGrace = std::chrono::milliseconds{1000};
// How much of a message is read at a time (bounds what a message over the limit costs).
constexpr std::size_t kReadPiece = 16 * 1024;
// Sockets accepted beyond players and handshakes (plain HTTP: probes, scrapes; upgrades on their
// way): fd_limit.hpp's kSpareSockets, which the descriptor limit is sized with.
constexpr int kSpareSocketCount = static_cast<int>(kSpareSockets);
// The fd reserve (issue 17): descriptors on /dev/null held back so that, with the process out of
// file descriptors, /healthz, /readyz and /metrics still answer. Each is traded for one pending
// connection, answered health-only (its request and its answer each within kReserveDeadline), then
// closed; the reserve is opened again on the accept strand. Its size is fd_limit.hpp's kFdReserve.
constexpr int kReserveCount = static_cast<int>(kFdReserve);
constexpr auto kReserveDeadline = std::chrono::milliseconds{1000};
// While the reserve holds descriptors, a paused acceptor looks again at least this often, so a
// probe waits at most this long in the backlog (with none held, the pause doubles up to 1 s).
constexpr auto kReservePause = std::chrono::milliseconds{100};
// Silent connections closed in one turn of the accept strand (the rest wait for the next turn).
constexpr int kReserveDrainPerTurn = 256;
// Rooms over HTTP (PROTOCOL.md, "Rooms over HTTP"). A room GET is a want due in half a second:
// most are a player's room fetched from its owner or through a cache, soon needed, but it should
// not go before the rooms players stand in (priority 0).
constexpr uint32_t kRoomGetPriorityMs = 500;
// A room GET may say how soon it is needed (a replica's owner fetch passes its player's want):
// the Grotto-Priority header, whole milliseconds up to this.
constexpr uint32_t kMaxRoomGetPriorityMs = 3'600'000;
constexpr const char* kRoomCacheControl = "public, max-age=31536000, immutable";
// Room extras (server/extras.hpp): /extras/ then a room URL's path after /rooms/.
constexpr std::string_view kExtrasPathPrefix = "/extras/";
constexpr const char* kRoomContentType = "application/octet-stream";

class WsSession;

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

}  // namespace

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
    return config.max_connections + config.max_handshakes + kSpareSocketCount;
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
      if (!player) --handshakes;
      metrics.handshakes_open.set(static_cast<int64_t>(handshakes));
    }
    sessions_cv.notify_all();
  }
  size_t players() const { return sessions.size() - handshakes; }  // under sessions_mutex

  void do_accept();
  void on_accept(beast::error_code ec, tcp::socket socket);
  void serve_from_reserve();
  bool connection_waiting();
  void refill_reserve();
  // A reserve connection ended (its socket is closed): open the reserve again, and look at the
  // backlog at once if the acceptor is paused. From any thread.
  void reserve_returned();
};

namespace {

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

// ---- WebSocket session ----

class WsSession : public std::enable_shared_from_this<WsSession>, private WorldPort {
 public:
  WsSession(Server::Impl& server, beast::tcp_stream&& stream, SocketSlot slot)
      : slot_(std::move(slot)),
        server_(server),
        limits_(server.config.limits),
        ws_(std::move(stream)),
        timer_(ws_.get_executor()),
        pace_timer_(ws_.get_executor()) {}

  ~WsSession() {
    if (client_ != 0) server_.generator->remove_client(client_);
    if (registry_id_ != 0) {
      server_.metrics.connections_open.add(-1);
      server_.leave(registry_id_, player_);
    }
  }

  template <class Body, class Allocator>
  void run(http::request<Body, http::basic_fields<Allocator>> req) {
    beast::get_lowest_layer(ws_).expires_never();
    websocket::stream_base::timeout t{};
    // The close handshake is bounded by handshake_timeout too; the protocol's own handshake and
    // idle timeouts are the conversation's timer, so the client hears `timeout` before the close.
    t.handshake_timeout = server_.config.http_timeout;
    t.idle_timeout = websocket::stream_base::none();
    t.keep_alive_pings = false;
    ws_.set_option(t);
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& res) { res.set(http::field::server, product_version()); }));
    // No limit in Beast: messages are read in pieces, and one that grows past max_message_bytes
    // is refused by the conversation (too_large, close 1009) without being read whole.
    ws_.read_message_max(0);
    peer_ = endpoint_text();
    ws_.async_accept(req, beast::bind_front_handler(&WsSession::on_accept, shared_from_this()));
  }

  // From stop(), on any thread.
  void shutdown() {
    net::dispatch(ws_.get_executor(), [self = shared_from_this()] {
      if (!self->conversation_) return;
      self->conversation_->shutdown();
      self->apply();
    });
  }

  // Cuts the TCP connection (stop() after the drain timeout).
  void cut() {
    net::dispatch(ws_.get_executor(), [self = shared_from_this()] { self->cut_socket(); });
  }

 private:
  std::string endpoint_text() {
    beast::error_code ec;
    auto ep = beast::get_lowest_layer(ws_).socket().remote_endpoint(ec);
    if (ec) return "?";
    return ep.address().to_string() + ":" + std::to_string(ep.port());
  }

  void on_accept(beast::error_code ec) {
    if (ec) {
      spdlog::debug("event=ws_accept_failed peer={} error=\"{}\"", peer_, ec.message());
      return;
    }
    Admission refusal = Admission::kAdmitted;
    registry_id_ = server_.admit(shared_from_this(), refusal);
    ConversationConfig c;
    c.limits = limits_;
    c.token = server_.config.token;
    c.params_digest = server_.params_digest;
    c.server_name = product_version();
    c.max_connections = server_.config.max_connections;
    c.max_handshakes = server_.config.max_handshakes;
    c.session = registry_id_;
    c.peer = peer_;
    conversation_.emplace(std::move(c), static_cast<WorldPort&>(*this), &server_.metrics);
    if (registry_id_ == 0) {
      server_.metrics.connections_rejected.add();
      spdlog::warn("event=connection_rejected peer={} reason={}", peer_,
                   refusal == Admission::kStopping ? "stopping"
                   : refusal == Admission::kFull   ? "max_connections"
                                                   : "max_handshakes");
      conversation_->admit(refusal);
      apply();
      return;
    }
    server_.metrics.connections_total.add();
    server_.metrics.connections_open.add(1);
    spdlog::info("event=connected session={} peer={}", registry_id_, peer_);
    conversation_->admit(Admission::kAdmitted);
    apply();
    do_read();
  }

  // ---- the conversation's world questions, answered by the generator ----

  uint64_t own_seed() const override { return server_.generator->world().seed(); }

  Result<ClientId> open(uint64_t seed, uint32_t version) override {
    if (!player_) {
      if (!server_.promote()) {
        server_.metrics.connections_rejected.add();
        return Error{ErrorCode::kOverloaded, "too many players (max_connections " +
                                                 std::to_string(server_.config.max_connections) +
                                                 "); retry later"};
      }
      player_ = true;
    }
    std::weak_ptr<WsSession> weak = weak_from_this();
    auto executor = ws_.get_executor();
    auto gate = server_.gate;
    auto client = server_.generator->add_client(
        seed,
        [weak, executor, gate](Delivery d) {
          std::lock_guard lock(gate->mutex);
          if (!gate->open) return;
          net::post(executor, [weak, d = std::move(d)]() mutable {
            if (auto self = weak.lock()) self->on_delivery(std::move(d));
          });
        },
        version);
    if (client) client_ = *client;
    return client;
  }

  std::optional<cave::RoomId> locate(ClientId client, Vec3 point) override {
    return server_.generator->locate(client, point);
  }

  cave::Spawn spawn(ClientId client) override { return server_.generator->spawn(client); }

  void on_delivery(Delivery d) {
    if (closing_) return;
    conversation_->delivery(std::move(d));
    apply();
  }

  // ---- carrying out the conversation's actions ----

  void apply() {
    for (Action& a : conversation_->take()) {
      std::visit([this](auto& x) { carry_out(x); }, a);
    }
  }

  void carry_out(act::SendText& a) { enqueue(Outgoing{std::move(a.text), nullptr, 0}); }
  void carry_out(act::SendRoom& a) { enqueue(Outgoing{{}, std::move(a.room), a.due_ms}); }
  void carry_out(act::Want& a) { server_.generator->request(a.client, a.rooms); }
  void carry_out(act::Drop& a) { server_.generator->cancel(a.client, a.rooms); }
  void carry_out(act::Release& a) {
    server_.generator->remove_client(a.client);
    if (client_ == a.client) client_ = 0;
  }
  void carry_out(act::Timer& a) {
    timer_.expires_after(a.after);
    timer_.async_wait(beast::bind_front_handler(&WsSession::on_timer, shared_from_this()));
  }
  void carry_out(act::Pace& a) {
    pace_timer_.expires_after(a.after);
    pace_timer_.async_wait(beast::bind_front_handler(&WsSession::on_pace, shared_from_this()));
  }
  void carry_out(act::Close& a) {
    if (closing_) return;
    close_code_ = websocket::close_reason(static_cast<websocket::close_code>(a.code), a.reason);
    close_after_flush_ = true;
    // A slow client lingers (issue 45): its frame in flight and then the close frame wait up to
    // the HTTP timeout for it to read again, while what it sends is read and dropped (on_read),
    // so that a client that resumes reading gets the close, not a reset. A client that said
    // nothing for the whole idle timeout gets 1 s: it may be stuck in the middle of a frame.
    begin_closing(dropped_ || a.await_reply ? server_.config.http_timeout : kCloseGrace);
    if (!queue_.writing()) do_write();
  }

  void on_timer(beast::error_code ec) {
    if (ec || closing_) return;  // cancelled or re-armed
    if (timer_.expiry() > Clock::now()) return;
    conversation_->deadline();
    apply();
  }

  void on_pace(beast::error_code ec) {
    if (ec || closing_) return;  // cancelled or re-armed
    if (pace_timer_.expiry() > Clock::now()) return;
    conversation_->pace();
    apply();
  }

  // ---- reading: in pieces, so a message over the limit is refused before it is held whole ----

  void do_read() {
    ws_.async_read_some(buffer_, kReadPiece,
                        beast::bind_front_handler(&WsSession::on_read, shared_from_this()));
  }

  void on_read(beast::error_code ec, std::size_t) {
    if (ec) {
      if (!closing_ && ec != websocket::error::closed && ec != net::error::operation_aborted) {
        spdlog::debug("event=read_failed session={} error=\"{}\"", registry_id_, ec.message());
      } else if (ec == websocket::error::closed && !closing_) {
        spdlog::info("event=closed session={} reason=client_closed", registry_id_);
      }
      closing_ = true;
      timer_.cancel();
      pace_timer_.cancel();
      release();
      return;
    }
    if (closing_) {
      // Lingering (nginx's lingering close): whatever the client still sends is read and
      // dropped until its close frame or the end of the grace, so that unread bytes in the
      // socket do not turn the close into a TCP reset that discards what was sent before it.
      buffer_.consume(buffer_.size());
      return do_read();
    }
    if (!ws_.got_text()) {
      buffer_.consume(buffer_.size());
      conversation_->binary();
    } else if (buffer_.size() > limits_.max_message_bytes) {
      buffer_.consume(buffer_.size());
      conversation_->oversized();
    } else if (!ws_.is_message_done()) {
      return do_read();
    } else {
      std::string text = beast::buffers_to_string(buffer_.data());
      buffer_.consume(buffer_.size());
      conversation_->text(text);
    }
    apply();
    do_read();
  }

  // ---- writing: one async_write in flight, the rest queued (SendQueue: the most urgent room
  // first) up to send_queue_bytes ----

  void enqueue(Outgoing out) {
    if (dropped_) return;
    queue_.push(std::move(out));
    // A single message larger than the limit still goes out when nothing else waits.
    if (queue_.size() > 1 && queue_.bytes() > server_.config.send_queue_bytes) {
      drop_slow_client();
      return;
    }
    if (!queue_.writing()) do_write();
  }

  void do_write() {
    if (queue_.empty()) {
      if (close_after_flush_) do_close();
      return;
    }
    queue_.start_write();
    const Outgoing& front = queue_.front();
    if (front.room) {
      ws_.binary(true);
      ws_.async_write(net::buffer(front.room->frame),
                      beast::bind_front_handler(&WsSession::on_write, shared_from_this()));
    } else {
      ws_.text(true);
      ws_.async_write(net::buffer(front.text),
                      beast::bind_front_handler(&WsSession::on_write, shared_from_this()));
    }
  }

  void on_write(beast::error_code ec, std::size_t bytes) {
    if (ec) {
      queue_.pop_front();  // Beast is done with its buffer
      closing_ = true;
      timer_.cancel();
      pace_timer_.cancel();
      release();
      return;
    }
    conversation_->sent(bytes);
    server_.metrics.bytes_sent.add(bytes);
    queue_.pop_front();
    do_write();
  }

  // The client does not read: it is disconnected and its queue released. Its close frame waits
  // behind the write in flight, so the socket is cut if that does not finish within kCloseGrace.
  void drop_slow_client() {
    dropped_ = true;
    // The front is being written (Beast holds its buffer); everything behind it goes now.
    queue_.drop_waiting();
    conversation_->slow_client(queue_.bytes());
    apply();
  }

  void begin_closing(std::chrono::milliseconds grace) {
    closing_ = true;
    pace_timer_.cancel();
    timer_.expires_after(grace);
    timer_.async_wait([self = shared_from_this()](beast::error_code ec) {
      if (!ec) self->cut_socket();
    });
  }

  void do_close() {
    if (close_started_) return;
    close_started_ = true;
    ws_.async_close(close_code_, [self = shared_from_this()](beast::error_code) {
      self->timer_.cancel();
      self->cut_socket();
    });
  }

  void cut_socket() {
    beast::error_code ignored;
    auto& socket = beast::get_lowest_layer(ws_).socket();
    if (socket.is_open()) {
      socket.shutdown(tcp::socket::shutdown_both, ignored);
      socket.close(ignored);
    }
    closing_ = true;
    release();
  }

  // Memory this session holds for the client, released as soon as it is closing.
  void release() {
    if (conversation_) {
      conversation_->transport_closed();
      apply_releases();
    }
    if (!queue_.writing()) queue_.clear();
  }

  // After the transport is gone only releases are carried out; nothing more is sent.
  void apply_releases() {
    for (Action& a : conversation_->take()) {
      if (auto* r = std::get_if<act::Release>(&a)) carry_out(*r);
    }
  }

  SocketSlot slot_;
  Server::Impl& server_;
  const proto::Limits limits_;
  websocket::stream<beast::tcp_stream> ws_;
  beast::flat_buffer buffer_;
  net::steady_timer timer_;
  net::steady_timer pace_timer_;  // the bandwidth cap's (act::Pace)
  std::string peer_;
  uint64_t registry_id_ = 0;
  bool player_ = false;  // said hello and took a player slot (else counts as a handshake)
  std::optional<Conversation> conversation_;  // from the upgrade on
  ClientId client_ = 0;  // the generator's client, until the conversation releases it
  bool closing_ = false;
  bool dropped_ = false;
  bool close_after_flush_ = false;
  bool close_started_ = false;
  websocket::close_reason close_code_;
  SendQueue queue_;
};

// ---- HTTP session: health, metrics, version, and the upgrade to /ws ----

class HttpSession : public std::enable_shared_from_this<HttpSession> {
 public:
  // With a loan, the connection holds a reserve descriptor and is answered health-only.
  HttpSession(Server::Impl& server, tcp::socket&& socket, SocketSlot slot,
              std::optional<ReserveLoan> loan = std::nullopt)
      : slot_(std::move(slot)),
        loan_(std::move(loan)),
        server_(server),
        stream_(std::move(socket)) {}

  void run() {
    net::dispatch(stream_.get_executor(),
                  beast::bind_front_handler(&HttpSession::do_read, shared_from_this()));
  }

 private:
  void do_read() {
    parser_.emplace();
    parser_->header_limit(kHttpHeaderLimit);
    parser_->body_limit(kHttpBodyLimit);
    // A new connection gets the shorter of the HTTP and the handshake budget for its first
    // request, so sockets that never send one go soon.
    auto timeout = server_.config.http_timeout;
    if (first_request_) {
      timeout =
          std::min(timeout, std::chrono::milliseconds{server_.config.limits.handshake_timeout_ms});
      first_request_ = false;
    }
    if (loan_) timeout = std::min<std::chrono::milliseconds>(timeout, kReserveDeadline);
    stream_.expires_after(timeout);
    http::async_read(stream_, buffer_, *parser_,
                     beast::bind_front_handler(&HttpSession::on_read, shared_from_this()));
  }

  void on_read(beast::error_code ec, std::size_t) {
    if (ec == http::error::end_of_stream) {
      beast::error_code ignored;
      stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
      return;
    }
    if (ec) {
      if (ec == http::error::body_limit) {
        respond_and_close(http::status::payload_too_large, "request body too large\n");
      } else if (ec == http::error::header_limit || ec == http::error::buffer_overflow) {
        respond_and_close(http::status::request_header_fields_too_large,
                          "request headers too large\n");
      }
      return;  // timeouts and resets: the connection just goes
    }
    auto req = parser_->release();
    std::string_view target(req.target().data(), req.target().size());
    std::string_view path = target.substr(0, target.find('?'));
    if (loan_) return respond_from_reserve(req, path);
    if (websocket::is_upgrade(req)) {
      if (path != proto::kWebSocketPath) {
        server_.metrics.http_requests_total.add();
        return respond(req, http::status::not_found, "text/plain", "not found\n");
      }
      std::make_shared<WsSession>(server_, std::move(stream_), std::move(slot_))
          ->run(std::move(req));
      return;
    }
    server_.metrics.http_requests_total.add();
    if (path.starts_with(proto::kRoomPathPrefix)) return serve_room(req, path);
    if (path.starts_with(kExtrasPathPrefix)) {
      if (!server_.config.viewer) {
        return respond(req, http::status::not_found, "text/plain",
                       "room extras are served with the viewer, which is off here (--no-viewer)\n");
      }
      return serve_room(req, path, true);
    }
    if (req.method() != http::verb::get && req.method() != http::verb::head) {
      return respond(req, http::status::method_not_allowed, "text/plain", "GET only\n");
    }
    if (path == "/healthz") {
      // Touches nothing but this process: answers while generation is saturated.
      return respond(req, http::status::ok, "text/plain", "ok\n");
    }
    if (path == "/readyz") {
      // Ready on the CPU path too (slower, still serving); the body says which path it runs.
      bool ready = server_.generator != nullptr && !server_.stopping.load();
      std::string body = ready ? "ready\n" : "not ready\n";
      if (server_.generator) body += "compute: " + server_.generator->compute_path() + "\n";
      return respond(req, ready ? http::status::ok : http::status::service_unavailable,
                     "text/plain", std::move(body));
    }
    if (path == "/metrics") {
      return respond(req, http::status::ok, "text/plain; version=0.0.4; charset=utf-8",
                     server_.metrics.render());
    }
    if (path == "/version") {
      std::string versions;
      for (uint32_t v = proto::kMinProtocolVersion; v <= proto::kProtocolVersion; ++v)
        versions += (versions.empty() ? "" : ",") + std::to_string(v);
      return respond(req, http::status::ok, "application/json",
                     "{\"server\":\"" + product_version() + "\",\"protocol\":" +
                         std::to_string(proto::kProtocolVersion) + ",\"protocols\":[" + versions +
                         "],\"seed\":\"" + std::to_string(server_.generator->world().seed()) +
                         "\",\"params\":\"" + proto::digest_text(server_.params_digest) + "\"}\n");
    }
    if (server_.config.viewer) {
      if (const ViewerAsset* asset = find_viewer_asset(path)) return serve_asset(req, *asset);
    }
    if (path == proto::kWebSocketPath) {
      return respond(req, http::status::upgrade_required, "text/plain",
                     "this path speaks WebSocket (proto/PROTOCOL.md): send an upgrade request\n",
                     true);
    }
    return respond(req, http::status::not_found, "text/plain", "not found\n");
  }

  // ---- rooms over HTTP (PROTOCOL.md, "Rooms over HTTP"): the bytes of the WebSocket room frame,
  // immutable and cacheable, built through the generator like any want ----

  // What the answer needs of the request, kept while the room is fetched.
  struct RoomRequest {
    unsigned http_version = 11;
    bool keep_alive = true;
    bool head = false;
    std::string if_none_match;
    bool extras = false;  // /extras/...: the room's extras as JSON, not its frame
    uint64_t seed = 0;    // the world the path names
  };

  // A file of the browser viewer: revalidated on every load (no-cache) by its ETag, so a new
  // server's viewer replaces the old one at once and an unchanged one costs a 304.
  template <class Request>
  void serve_asset(const Request& req, const ViewerAsset& asset) {
    auto inm = req[http::field::if_none_match];
    auto res = tagged_answer(req.version(), "no-cache", asset.etag,
                             std::string_view(inm.data(), inm.size()));
    if (res->result() == http::status::ok) {
      set_body(
          *res, asset.content_type,
          std::string_view(reinterpret_cast<const char*>(asset.bytes.data()), asset.bytes.size()),
          req.method() == http::verb::head);
    }
    send_room_answer(std::move(res), req.keep_alive());
  }

  using Answer = std::shared_ptr<http::response<http::string_body>>;

  // A cacheable answer (a room, its extras, a file of the viewer): the server's name,
  // `cache_control` and the strong `etag`; 304 Not Modified when `if_none_match` lists the tag,
  // else 200 for the caller to give its body (set_body).
  static Answer tagged_answer(unsigned http_version, std::string_view cache_control,
                              std::string_view etag, std::string_view if_none_match) {
    auto res = std::make_shared<http::response<http::string_body>>(http::status::ok, http_version);
    res->set(http::field::server, product_version());
    res->set(http::field::cache_control, std::string(cache_control));
    res->set(http::field::etag, std::string(etag));
    if (etag_matches(if_none_match, etag)) res->result(http::status::not_modified);
    return res;
  }

  // A 200's body: its type (never sniffed), its length, and the bytes unless it answers a HEAD.
  static void set_body(http::response<http::string_body>& res, std::string_view type,
                       std::string_view bytes, bool head) {
    res.set(http::field::content_type, std::string(type));
    res.set("X-Content-Type-Options", "nosniff");
    res.content_length(bytes.size());
    if (!head) res.body().assign(bytes.begin(), bytes.end());
  }

  // The checks in PROTOCOL.md's order: method, path, token, rate, then what the path asks (the
  // version, the world's parameters, the lod, the world and the room).
  // The room's extras (/extras/..., PROTOCOL.md "Room extras over HTTP") take the same path after
  // their prefix, the same checks and the same fetch, and answer JSON computed from the frame.
  template <class Request>
  void serve_room(const Request& req, std::string_view path, bool extras = false) {
    RoomRequest r{req.version(), req.keep_alive(), req.method() == http::verb::head,
                  std::string(req[http::field::if_none_match]), extras};
    if (req.method() != http::verb::get && req.method() != http::verb::head) {
      return refuse_room(r, http::status::method_not_allowed, "room URLs take GET and HEAD only");
    }
    std::string room_path;
    if (extras) {
      room_path =
          std::string(proto::kRoomPathPrefix) + std::string(path.substr(kExtrasPathPrefix.size()));
      path = room_path;
    }
    auto parsed = proto::parse_room_path(path);
    if (!parsed) return refuse_room(r, http::status::bad_request, parsed.error().message);
    if (const std::string& token = server_.config.token; !token.empty()) {
      // The WebSocket's rule: a server with a token serves nothing to a client without it.
      constexpr std::string_view kBearer = "Bearer ";
      auto field = req[http::field::authorization];
      std::string_view given(field.data(), field.size());
      if (given.empty()) {
        return refuse_room(r, http::status::unauthorized,
                           "missing token (send Authorization: Bearer <token>)");
      }
      if (!given.starts_with(kBearer) ||
          !proto::token_equals(token, given.substr(kBearer.size()))) {
        return refuse_room(r, http::status::unauthorized, "wrong token");
      }
    }
    const proto::Limits& limits = server_.config.limits;
    if (!take_room_token()) {
      return refuse_room(r, http::status::too_many_requests,
                         "request rate over request_rate (" + std::to_string(limits.request_rate) +
                             " rooms/s, request_burst " + std::to_string(limits.request_burst) +
                             " on this connection); slow down");
    }
    uint32_t priority = kRoomGetPriorityMs;
    if (auto field = req["Grotto-Priority"]; !field.empty()) {
      std::string_view text(field.data(), field.size());
      uint64_t ms = 0;
      const bool digits = text.size() <= 7 && text.find_first_not_of("0123456789") == text.npos;
      for (char c : text)
        ms = ms * 10 + static_cast<uint64_t>(c - '0');
      if (!digits || ms > kMaxRoomGetPriorityMs) {
        return refuse_room(r, http::status::bad_request,
                           "Grotto-Priority must be whole milliseconds from 0 to " +
                               std::to_string(kMaxRoomGetPriorityMs));
      }
      priority = static_cast<uint32_t>(ms);
    }
    const proto::RoomPath& p = *parsed;
    r.seed = p.seed;
    if (!proto::speaks_version(p.version)) {
      return refuse_room(r, http::status::not_found,
                         "protocol version " + std::to_string(p.version) +
                             " is not served here (versions " +
                             std::to_string(proto::kMinProtocolVersion) + " to " +
                             std::to_string(proto::kProtocolVersion) + ")");
    }
    if (p.params != server_.params_digest) {
      return refuse_room(r, http::status::not_found,
                         "world parameters " + proto::digest_text(p.params) +
                             " are not this server's (" +
                             proto::digest_text(server_.params_digest) + ")");
    }
    if (p.lod > limits.max_lod) {
      return refuse_room(r, http::status::not_found,
                         "lod " + std::to_string(p.lod) + " is not served here (max_lod " +
                             std::to_string(limits.max_lod) + ")");
    }
    if (server_.room_gets.fetch_add(1) >= server_.config.max_connections) {
      server_.room_gets.fetch_sub(1);
      return refuse_room(r, http::status::service_unavailable,
                         "overloaded: " + std::to_string(server_.config.max_connections) +
                             " room requests already wait for a build (max_connections); retry "
                             "later");
    }
    auto executor = stream_.get_executor();
    auto gate = server_.gate;
    fetch_room(
        *server_.generator, RoomKey{p.id, static_cast<uint8_t>(p.lod), p.seed, p.version}, priority,
        Build::kHere,
        [executor, gate](std::function<void()> f) {
          std::lock_guard lock(gate->mutex);
          if (gate->open) net::post(executor, std::move(f));
        },
        [self = shared_from_this(), r = std::move(r)](Result<RoomPtr> room) mutable {
          self->server_.room_gets.fetch_sub(1);
          self->on_room(std::move(r), std::move(room));
        });
  }

  void on_room(RoomRequest r, Result<RoomPtr> room) {
    if (!room) {
      const Error& e = room.error();
      switch (e.code) {
        case ErrorCode::kNotFound:
        case ErrorCode::kWorldMismatch:  // a seed this server does not serve
          return refuse_room(r, http::status::not_found, e.message);
        case ErrorCode::kOverloaded:
        case ErrorCode::kServiceRestart:
          return refuse_room(r, http::status::service_unavailable,
                             std::string(proto::wire_code_name(e.code)) + ": " + e.message);
        default:
          return refuse_room(r, http::status::internal_server_error, e.message);
      }
    }
    const std::vector<uint8_t>& frame = (*room)->frame;
    // Strong: the same bytes give the same tag on every replica and build (FNV-1a, as the world
    // digest), different bytes a different one.
    const std::string etag = "\"" + proto::digest_text(fnv1a64(frame.data(), frame.size())) + "\"";
    if (r.extras) return on_room_extras(std::move(r), std::move(*room), etag);
    auto res = tagged_answer(r.http_version, kRoomCacheControl, etag, r.if_none_match);
    if (res->result() == http::status::not_modified) {
      server_.metrics.rooms_http_not_modified.add();
    } else {
      set_body(*res, kRoomContentType,
               std::string_view(reinterpret_cast<const char*>(frame.data()), frame.size()), r.head);
      server_.metrics.rooms_http_served.add();
      if (!r.head) server_.metrics.rooms_http_bytes.add(frame.size());
    }
    send_room_answer(std::move(res), r.keep_alive);
  }

  // The extras are a function of the frame and the world (seed and parameters, both in the URL),
  // so their tag is the frame's with an "x": a revalidation costs no placement.
  void on_room_extras(RoomRequest r, RoomPtr room, const std::string& frame_etag) {
    const std::string etag = "\"x" + frame_etag.substr(1);
    auto res = tagged_answer(r.http_version, kRoomCacheControl, etag, r.if_none_match);
    if (res->result() == http::status::not_modified)
      return send_room_answer(std::move(res), r.keep_alive);
    auto executor = stream_.get_executor();
    net::post(server_.extras_pool, [self = shared_from_this(), r = std::move(r), room, res,
                                    executor, gate = server_.gate]() mutable {
      auto json = room_extras_json(room->frame, r.seed, self->server_.config.layout);
      std::lock_guard lock(gate->mutex);
      if (!gate->open) return;
      net::post(executor, [self, r = std::move(r), res, json = std::move(json)]() mutable {
        if (!json)
          return self->refuse_room(r, http::status::internal_server_error, json.error().message);
        set_body(*res, "application/json", *json, r.head);
        self->send_room_answer(std::move(res), r.keep_alive);
      });
    });
  }

  // RFC 9110 13.1.2: If-None-Match compares weakly, "*" matches any tag.
  static bool etag_matches(std::string_view header, std::string_view etag) {
    while (!header.empty()) {
      size_t comma = header.find(',');
      std::string_view tag = header.substr(0, comma);
      while (!tag.empty() && (tag.front() == ' ' || tag.front() == '\t'))
        tag.remove_prefix(1);
      while (!tag.empty() && (tag.back() == ' ' || tag.back() == '\t'))
        tag.remove_suffix(1);
      if (tag.starts_with("W/")) tag.remove_prefix(2);
      if (tag == "*" || tag == etag) return true;
      if (comma == std::string_view::npos) break;
      header.remove_prefix(comma + 1);
    }
    return false;
  }

  // A refused room URL: the status, a one-line reason, never stored by a cache (a 404 for another
  // world's parameters is true of this replica only, e.g. during a roll-out).
  void refuse_room(const RoomRequest& r, http::status status, const std::string& reason) {
    server_.metrics.count_room_http_refusal(static_cast<int>(status));
    spdlog::debug("event=room_http_refused status={} reason=\"{}\"", static_cast<int>(status),
                  proto::echo(reason));
    auto res = std::make_shared<http::response<http::string_body>>(status, r.http_version);
    res->set(http::field::server, product_version());
    res->set(http::field::content_type, "text/plain");
    res->set(http::field::cache_control, "no-store");
    if (status == http::status::method_not_allowed) res->set(http::field::allow, "GET, HEAD");
    if (status == http::status::unauthorized) {
      res->set(http::field::www_authenticate, "Bearer realm=\"grotto\"");
    }
    if (status == http::status::too_many_requests || status == http::status::service_unavailable) {
      res->set(http::field::retry_after, "1");
    }
    res->body() = reason + "\n";
    res->prepare_payload();
    if (r.head) res->body().clear();
    send_room_answer(std::move(res), r.keep_alive);
  }

  void send_room_answer(std::shared_ptr<http::response<http::string_body>> res, bool keep_alive) {
    res->keep_alive(keep_alive);
    stream_.expires_after(server_.config.http_timeout);
    http::async_write(stream_, *res,
                      [self = shared_from_this(), res](beast::error_code ec, std::size_t) {
                        self->on_write(ec, res->keep_alive());
                      });
  }

  // The request rate of a WebSocket connection (PROTOCOL.md, Rooms in flight), per HTTP
  // connection: one room a GET, from a bucket of request_burst refilled at request_rate a second.
  bool take_room_token() {
    const proto::Limits& l = server_.config.limits;
    if (l.request_rate == 0) return true;
    const auto now = Clock::now();
    if (!room_tokens_at_) {
      room_tokens_ = l.request_burst;
    } else {
      const double seconds = std::chrono::duration<double>(now - *room_tokens_at_).count();
      room_tokens_ = std::min<double>(l.request_burst, room_tokens_ + seconds * l.request_rate);
    }
    room_tokens_at_ = now;
    if (room_tokens_ < 1) return false;
    room_tokens_ -= 1;
    return true;
  }

  // Out of file descriptors, this connection holds a reserve descriptor: health and metrics answer
  // as usual (the process lives; it is not ready for new players, and says why); anything else,
  // an upgrade included, gets 503. Never kept alive, so the descriptor comes back soon.
  template <class Request>
  void respond_from_reserve(const Request& req, std::string_view path) {
    static const std::string kWhy =
        "out of file descriptors: new connections are refused until some close (answered from "
        "the fd reserve)\n";
    server_.metrics.http_requests_total.add();
    bool get = req.method() == http::verb::get || req.method() == http::verb::head;
    if (get && path == "/healthz") {
      return respond(req, http::status::ok, "text/plain", "ok\n" + kWhy);
    }
    if (get && path == "/readyz") {
      std::string body = "not ready: " + kWhy;
      if (server_.generator) body += "compute: " + server_.generator->compute_path() + "\n";
      return respond(req, http::status::service_unavailable, "text/plain", std::move(body));
    }
    if (get && path == "/metrics") {
      return respond(req, http::status::ok, "text/plain; version=0.0.4; charset=utf-8",
                     server_.metrics.render());
    }
    return respond(
        req, http::status::service_unavailable, "text/plain",
        kWhy + "only GET /healthz, /readyz and /metrics are answered now; retry later\n");
  }

  template <class Request>
  void respond(const Request& req, http::status status, const char* type, std::string body,
               bool upgrade = false) {
    auto res = std::make_shared<http::response<http::string_body>>(status, req.version());
    res->set(http::field::server, product_version());
    res->set(http::field::content_type, type);
    if (upgrade) {
      res->set(http::field::upgrade, "websocket");
      res->set(http::field::connection, "Upgrade");
    }
    if (loan_ && status == http::status::service_unavailable)
      res->set(http::field::retry_after, "1");
    res->keep_alive(req.keep_alive() && !upgrade && !loan_);
    bool head = req.method() == http::verb::head;
    res->body() = std::move(body);
    res->prepare_payload();
    if (head) res->body().clear();
    stream_.expires_after(loan_ ? kReserveDeadline : server_.config.http_timeout);
    http::async_write(stream_, *res,
                      [self = shared_from_this(), res](beast::error_code ec, std::size_t) {
                        self->on_write(ec, res->keep_alive());
                      });
  }

  void respond_and_close(http::status status, std::string body) {
    auto res = std::make_shared<http::response<http::string_body>>(status, 11);
    res->set(http::field::server, product_version());
    res->set(http::field::content_type, "text/plain");
    res->keep_alive(false);
    res->body() = std::move(body);
    res->prepare_payload();
    http::async_write(stream_, *res,
                      [self = shared_from_this(), res](beast::error_code ec, std::size_t) {
                        self->on_write(ec, false);
                      });
  }

  void on_write(beast::error_code ec, bool keep_alive) {
    if (ec) return;
    if (!keep_alive || server_.stopping.load()) {
      beast::error_code ignored;
      stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
      return;
    }
    do_read();
  }

  SocketSlot slot_;
  std::optional<ReserveLoan> loan_;  // destroyed after stream_: the socket closes first
  Server::Impl& server_;
  beast::tcp_stream stream_;
  bool first_request_ = true;
  double room_tokens_ = 0;                           // take_room_token's bucket
  std::optional<Clock::time_point> room_tokens_at_;  // unset until the first room GET
  beast::flat_buffer buffer_{kHttpHeaderLimit + kHttpBodyLimit};
  std::optional<http::request_parser<http::string_body>> parser_;
};

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
    std::make_shared<HttpSession>(*this, std::move(socket), SocketSlot(sockets, metrics))->run();
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
    std::make_shared<HttpSession>(*this, std::move(socket), SocketSlot(sockets, metrics),
                                  ReserveLoan(*this))
        ->run();
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
  std::vector<std::shared_ptr<WsSession>> live;
  {
    std::lock_guard lock(s.sessions_mutex);
    for (auto& [id, weak] : s.sessions) {
      if (auto p = weak.lock()) live.push_back(std::move(p));
    }
  }
  for (auto& p : live)
    p->shutdown();
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
      p->cut();
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
