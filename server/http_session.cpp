// The HTTP side of the server's one port: health and readiness, metrics, the version, the
// browser viewer's files, rooms and their extras over HTTP (immutable, cacheable), and the
// upgrade to /ws, after which the connection is a WebSocket session (ws_session.cpp). A
// connection served from the fd reserve is answered health-only.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <boost/asio/dispatch.hpp>
#include <boost/asio/post.hpp>
#include <boost/beast/websocket.hpp>

#include "common/core/random.hpp"
#include "proto/room_path.hpp"
#include "proto/token.hpp"
#include "proto/world_digest.hpp"
#include "server/extras.hpp"
#include "server/room_fetch.hpp"
#include "server/server_impl.hpp"
#include "server/viewer.hpp"

namespace grotto::server {
namespace {

namespace websocket = beast::websocket;

constexpr std::size_t kHttpHeaderLimit = 8 * 1024;  // request line and headers
constexpr std::size_t kHttpBodyLimit = 8 * 1024;    // no endpoint takes a body
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
// A balancer that can try several replicas marks a newcomer's upgrade with this header
// (PROTOCOL.md, "Balancers"): a replica that would not let the newcomer in at once declines it
// with 403 before the upgrade, and the balancer tries the next one. 403 rather than 503: nginx's
// proxy_next_upstream counts a 5xx it acts on as a failed attempt (max_fails takes the replica out
// of rotation for fail_timeout), a 403 never.
constexpr const char* kBalancerHeader = "X-Grotto-Balancer";
constexpr const char* kTryOthers = "try-others";

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
      if (beast::iequals(req[kBalancerHeader], kTryOthers)) {
        if (Redirect why = server_.redirect_newcomer(); why != Redirect::kNone)
          return redirect(req, why);
      }
      return start_ws_session(server_, std::move(stream_), std::move(slot_), std::move(req));
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
      // Not ready while newcomers wait in the admission queue: a balancer sends them elsewhere.
      const size_t waiting = server_.queue_length.load();
      bool ready = server_.generator != nullptr && !server_.stopping.load() && waiting == 0;
      std::string body = ready ? "ready\n" : "not ready\n";
      if (waiting > 0) body += "queued: " + std::to_string(waiting) + "\n";
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

  // A marked newcomer's upgrade that this replica would not let in at once: 403 with why and
  // when to come back, before any WebSocket (no session, no player refused), then the connection
  // closes. The balancer tries the next replica.
  template <class Request>
  void redirect(const Request& req, Redirect why) {
    server_.metrics.count_redirect(why);
    const std::string_view name = redirect_name(why);
    spdlog::debug("event=newcomer_redirected reason={}", name);
    auto res =
        std::make_shared<http::response<http::string_body>>(http::status::forbidden, req.version());
    res->set(http::field::server, product_version());
    res->set(http::field::content_type, "text/plain");
    res->set(http::field::cache_control, "no-store");
    res->set(http::field::retry_after, "1");
    res->keep_alive(false);
    res->body() = std::string(name) + ": no place for a newcomer here at once (" +
                  std::string(kBalancerHeader) + ": " + std::string(kTryOthers) +
                  "); try another replica\n";
    res->prepare_payload();
    stream_.expires_after(server_.config.http_timeout);
    http::async_write(stream_, *res,
                      [self = shared_from_this(), res](beast::error_code ec, std::size_t) {
                        self->on_write(ec, false);
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

void start_http_session(Server::Impl& server, tcp::socket&& socket, SocketSlot slot,
                        std::optional<ReserveLoan> loan) {
  std::make_shared<HttpSession>(server, std::move(socket), std::move(slot), std::move(loan))->run();
}

}  // namespace grotto::server
