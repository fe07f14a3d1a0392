// The room tier's HTTP client: Beast's http over asio, on one I/O thread of its own (every member
// of Impl is touched only there). Its own translation unit: Beast's http headers without the
// WebSocket ones, compiled once.
#include "server/room_tier.hpp"

#include <spdlog/spdlog.h>

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <deque>
#include <set>
#include <thread>

#include "common/core/thread_name.hpp"

namespace grotto::server {

namespace beast = boost::beast;
namespace http = beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

Result<std::pair<std::string, std::string>> parse_tier_url(const std::string& url) {
  const std::string scheme = "http://";
  if (url.rfind(scheme, 0) != 0) {
    return invalid_argument("room tier URL '" + url +
                            "' must start with http:// (HTTP/1.1 on "
                            "the replicas' network, e.g. http://127.0.0.1:8080)");
  }
  std::string rest = url.substr(scheme.size());
  if (!rest.empty() && rest.back() == '/') rest.pop_back();
  const size_t colon = rest.rfind(':');
  if (rest.find('/') != std::string::npos || colon == std::string::npos || colon == 0) {
    return invalid_argument("room tier URL '" + url + "' must be http://HOST:PORT (no path)");
  }
  std::string host = rest.substr(0, colon), port = rest.substr(colon + 1);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  const bool digits = !port.empty() && port.size() <= 5 &&
                      port.find_first_not_of("0123456789") == std::string::npos;
  if (!digits || std::stoi(port) < 1 || std::stoi(port) > 65535) {
    return invalid_argument("room tier URL '" + url + "' needs a port in 1..65535");
  }
  return std::make_pair(host, port);
}

namespace {

using Stream = beast::tcp_stream;
using Response = http::response_parser<http::vector_body<uint8_t>>;

struct Fetch {
  std::string target;
  uint32_t priority_ms = 0;
  Clock::time_point deadline;
  RoomSource::Done done;
  std::unique_ptr<Stream> stream;
  bool reused = false;  // on a kept-alive connection (which the tier may have closed meanwhile)
  http::request<http::empty_body> request;
  beast::flat_buffer buffer;
  std::optional<Response> response;
};
using FetchPtr = std::shared_ptr<Fetch>;

std::string first_line(const std::vector<uint8_t>& body) {
  std::string s(body.begin(), body.begin() + static_cast<long>(std::min<size_t>(body.size(), 200)));
  if (auto nl = s.find('\n'); nl != std::string::npos) s.resize(nl);
  return s;
}

}  // namespace

struct RoomTier::Impl {
  explicit Impl(RoomTierConfig c, std::string h, std::string p)
      : config(std::move(c)), host(std::move(h)), port(std::move(p)), work(io.get_executor()) {}

  RoomTierConfig config;
  std::string host, port;
  net::io_context io;
  net::executor_work_guard<net::io_context::executor_type> work;
  std::thread thread;
  // ---- on the I/O thread only ----
  bool stopping = false;
  size_t open = 0;                            // connections open, idle or busy
  std::vector<std::unique_ptr<Stream>> idle;  // kept alive, most recently used last
  std::deque<FetchPtr> waiting;               // for a connection
  std::set<Stream*> busy;

  void fail(const FetchPtr& f, std::string why) {
    auto done = std::move(f->done);
    if (done) done(Error{ErrorCode::kUnavailable, "room tier " + host + ":" + port + ": " + why});
  }

  void start(const FetchPtr& f) {
    if (stopping) return fail(f, "stopped");
    if (Clock::now() >= f->deadline) return fail(f, "timed out waiting for a connection");
    if (!idle.empty()) {
      f->stream = std::move(idle.back());
      idle.pop_back();
      f->reused = true;
      return send(f);
    }
    if (open >= config.max_connections) {
      waiting.push_back(f);
      return;
    }
    ++open;
    connect(f);
  }

  void connect(const FetchPtr& f) {
    f->stream = std::make_unique<Stream>(io);
    f->reused = false;
    busy.insert(f->stream.get());
    auto resolver = std::make_shared<tcp::resolver>(io);
    resolver->async_resolve(
        host, port, [this, f, resolver](beast::error_code ec, tcp::resolver::results_type found) {
          if (ec) return close_and_fail(f, "cannot resolve: " + ec.message());
          f->stream->expires_at(f->deadline);
          f->stream->async_connect(found, [this, f](beast::error_code ec2, const tcp::endpoint&) {
            if (ec2) return close_and_fail(f, "cannot connect: " + ec2.message());
            send(f);
          });
        });
  }

  void send(const FetchPtr& f) {
    busy.insert(f->stream.get());
    f->request = {http::verb::get, f->target, 11};
    f->request.set(http::field::host, host + ":" + port);
    f->request.set(http::field::user_agent, "grotto-server room tier");
    f->request.set("Grotto-Priority", std::to_string(f->priority_ms));
    if (!config.token.empty()) f->request.set(http::field::authorization, "Bearer " + config.token);
    f->request.keep_alive(true);
    f->stream->expires_at(f->deadline);
    http::async_write(*f->stream, f->request, [this, f](beast::error_code ec, size_t) {
      if (ec) return retry_or_fail(f, ec, "cannot send the request");
      f->response.emplace();
      f->response->body_limit(config.max_body_bytes);
      // The header first: Boost 1.74's parser holds a Content-Length to body_limit only when the
      // header is parsed before the body arrives (one read of both takes any length).
      http::async_read_header(*f->stream, f->buffer, *f->response,
                              [this, f](beast::error_code ec2, size_t) {
                                if (ec2) return retry_or_fail(f, ec2, "no answer");
                                http::async_read(*f->stream, f->buffer, *f->response,
                                                 [this, f](beast::error_code ec3, size_t) {
                                                   if (ec3)
                                                     return retry_or_fail(f, ec3, "no answer");
                                                   answered(f);
                                                 });
                              });
    });
  }

  // A kept-alive connection the tier closed meanwhile fails at once, with nothing of an answer:
  // once more on a new one. Any other failure is the fetch's.
  void retry_or_fail(const FetchPtr& f, beast::error_code ec, const std::string& what) {
    const bool closed = ec == http::error::end_of_stream || ec == net::error::eof ||
                        ec == net::error::connection_reset || ec == net::error::broken_pipe;
    const bool stale = f->reused && closed && Clock::now() < f->deadline && !stopping;
    const std::string why = what + ": " + ec.message();
    busy.erase(f->stream.get());
    f->stream.reset();
    f->buffer.clear();
    if (!stale) {
      --open;
      fail(f, why);
      next_waiting();
      return;
    }
    connect(f);  // the connection count stays: this one replaces the dead one
  }

  void close_and_fail(const FetchPtr& f, std::string why) {
    busy.erase(f->stream.get());
    f->stream.reset();
    --open;
    fail(f, why);
    next_waiting();
  }

  void answered(const FetchPtr& f) {
    http::response<http::vector_body<uint8_t>> res = f->response->release();
    busy.erase(f->stream.get());
    if (res.keep_alive() && !stopping) {
      f->stream->expires_never();
      idle.push_back(std::move(f->stream));
    } else {
      f->stream.reset();
      --open;
    }
    auto done = std::move(f->done);
    if (res.result() == http::status::ok) {
      done(std::move(res.body()));
    } else {
      done(Error{ErrorCode::kUnavailable, "room tier " + host + ":" + port + " answered " +
                                              std::to_string(res.result_int()) + " for " +
                                              f->target + ": " + first_line(res.body())});
    }
    next_waiting();
  }

  void next_waiting() {
    while (!waiting.empty() && (!idle.empty() || open < config.max_connections)) {
      FetchPtr f = waiting.front();
      waiting.pop_front();
      start(f);
    }
  }

  void stop() {
    stopping = true;
    idle.clear();
    for (Stream* s : busy)
      s->socket().close();  // their handlers run with operation_aborted and fail
    while (!waiting.empty()) {
      fail(waiting.front(), "stopped");
      waiting.pop_front();
    }
  }
};

Result<std::unique_ptr<RoomTier>> RoomTier::create(RoomTierConfig config) {
  auto hp = parse_tier_url(config.url);
  if (!hp) return hp.error();
  if (!config.path_of) return invalid_argument("room tier: no path_of");
  if (config.max_connections < 1 || config.max_connections > 1024) {
    return invalid_argument("room tier: max_connections must be in [1, 1024], got " +
                            std::to_string(config.max_connections));
  }
  auto impl = std::make_unique<Impl>(std::move(config), hp->first, hp->second);
  Impl* i = impl.get();
  i->thread = std::thread([i] {
    name_this_thread("grotto-tier");
    i->io.run();
  });
  return std::unique_ptr<RoomTier>(new RoomTier(std::move(impl)));
}

RoomTier::RoomTier(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

RoomTier::~RoomTier() {
  Impl* i = impl_.get();
  net::post(i->io, [i] { i->stop(); });
  i->work.reset();
  if (i->thread.joinable()) i->thread.join();
}

void RoomTier::fetch(const RoomKey& key, uint32_t priority_ms, std::chrono::milliseconds timeout,
                     Done done) {
  auto f = std::make_shared<Fetch>();
  f->target = impl_->config.path_of(key);
  f->priority_ms = priority_ms;
  f->deadline = Clock::now() + timeout;
  f->done = std::move(done);
  Impl* i = impl_.get();
  net::post(i->io, [i, f] { i->start(f); });
}

}  // namespace grotto::server
