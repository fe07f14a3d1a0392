// A player's WebSocket session: the protocol's sans-I/O conversation (server/conversation.hpp)
// behind a Beast WebSocket stream. The session reads and writes bytes, runs the conversation's
// timers and carries out its actions (send, want and drop rooms at the generator, close); a send
// queue paces rooms to the link and drops a client that cannot keep up.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <boost/asio/dispatch.hpp>
#include <boost/asio/post.hpp>
#include <boost/beast/websocket.hpp>
#include <deque>

#include "proto/world_digest.hpp"
#include "server/conversation.hpp"
#include "server/send_queue.hpp"
#include "server/server_impl.hpp"

namespace grotto::server {
namespace {

namespace websocket = beast::websocket;

// A dropped client, or one closed for `timeout`, gets this long to take its close frame (and answer
// it) before the socket is cut.
constexpr auto kCloseGrace = std::chrono::milliseconds{1000};
// How much of a message is read at a time (bounds what a message over the limit costs).
constexpr std::size_t kReadPiece = 16 * 1024;

}  // namespace

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

  Entry enter(bool can_queue) override { return server_.enter(registry_id_, can_queue); }

 public:
  // From the admission queue (under the server's sessions lock: post only).
  void admitted() {
    net::post(ws_.get_executor(), [self = shared_from_this()] {
      if (self->closing_ || !self->conversation_) return;
      self->conversation_->admitted();
      self->apply();
    });
  }
  void told(adm::Queued place) {
    net::post(ws_.get_executor(), [self = shared_from_this(), place] {
      if (self->closing_ || !self->conversation_) return;
      self->conversation_->queue_update(place.position, place.wait_ms, place.queue);
      self->apply();
    });
  }

 private:
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
    // A slow client lingers: its frame in flight and then the close frame wait up to
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

void start_ws_session(Server::Impl& server, beast::tcp_stream&& stream, SocketSlot slot,
                      http::request<http::string_body>&& req) {
  std::make_shared<WsSession>(server, std::move(stream), std::move(slot))->run(std::move(req));
}

void shutdown_session(WsSession& session) {
  session.shutdown();
}
void admit_session(WsSession& session) {
  session.admitted();
}
void tell_session(WsSession& session, adm::Queued place) {
  session.told(place);
}
void cut_session(WsSession& session) {
  session.cut();
}

}  // namespace grotto::server
