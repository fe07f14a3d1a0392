#include "tests/server/server_harness.hpp"

#include "tests/server/harness_plain.hpp"

#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <boost/asio/connect.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <span>
#include <sstream>
#include <thread>

#include "common/codec/room_codec.hpp"
#include "proto/room_frame.hpp"

namespace grotto::server_test {

namespace http = beast::http;

ServerConfig test_config() {
  ServerConfig c;
  c.port = 0;
  c.io_threads = 2;
  c.generator.workers = 2;
  c.generator.builder.device.device = "none";  // the CPU reference: no OpenCL start-up in tests
  c.drain_timeout = 3000ms;
  c.log_level = "warn";
  return c;
}

std::unique_ptr<Server> start(const ServerConfig& c) {
  auto s = Server::start(c);
  EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
  if (!s.ok()) return nullptr;
  return std::move(s).value();
}

std::vector<grotto::cave::Room> sector_rooms(uint64_t seed, grotto::cave::SectorCoord sector) {
  auto world = grotto::cave::World::create(seed, {});
  return grotto::cave::generate_sector(*world, sector).rooms;
}

std::vector<grotto::cave::Room> many_rooms(size_t count) {
  std::vector<grotto::cave::Room> out;
  for (int x = 0; out.size() < count; ++x) {
    for (int z = 0; z < 8 && out.size() < count; ++z) {
      for (auto& r : sector_rooms(7, {x, 0, z})) {
        if (out.size() < count) out.push_back(std::move(r));
      }
    }
  }
  return out;
}

grotto::proto::Request request_of(const std::vector<grotto::cave::Room>& rooms, size_t from,
                                  size_t count, uint64_t ref, uint32_t priority) {
  grotto::proto::Request r;
  r.ref = ref;
  for (size_t i = from; i < from + count && i < rooms.size(); ++i) {
    r.rooms.push_back({rooms[i].id, 0, priority});
  }
  return r;
}

RoomId frame_id(const std::string& frame) {
  auto f = grotto::proto::decode_room_frame(
      std::span(reinterpret_cast<const uint8_t*>(frame.data()), frame.size()),
      grotto::proto::Limits{});
  EXPECT_TRUE(f.ok());
  return f.ok() ? f->room.id : RoomId::interior({}, 0);
}

// ---- Client ----

Client::Client(uint16_t port) : port_(port), ws_(ioc_) {}
Client::~Client() = default;

template <class Start>
beast::error_code Client::run(Start start, std::chrono::milliseconds timeout) {
  std::optional<beast::error_code> result;
  ioc_.restart();
  start([&](beast::error_code ec, auto&&...) { result = ec; });
  auto deadline = Clock::now() + timeout;
  while (!result && Clock::now() < deadline)
    ioc_.run_one_until(deadline);
  if (!result) {
    beast::get_lowest_layer(ws_).cancel();
    for (int i = 0; i < 5 && !result; ++i)
      ioc_.run_one_for(1s);
    return net::error::timed_out;
  }
  return *result;
}

beast::error_code Client::connect(const std::string& target) {
  tcp::resolver resolver(ioc_);
  beast::error_code ec;
  auto results = resolver.resolve("127.0.0.1", std::to_string(port_), ec);
  if (ec) return ec;
  ec = run([&](auto h) { beast::get_lowest_layer(ws_).async_connect(*results.begin(), h); });
  if (ec) return ec;
  return run([&](auto h) { ws_.async_handshake(response_, "127.0.0.1", target, h); });
}

void Client::set_receive_buffer(int bytes) {
  auto& socket = beast::get_lowest_layer(ws_).socket();
  socket.open(tcp::v4());
  socket.set_option(net::socket_base::receive_buffer_size(bytes));
}

void Client::set_upgrade_header(const std::string& name, const std::string& value) {
  ws_.set_option(websocket::stream_base::decorator(
      [name, value](websocket::request_type& req) { req.set(name, value); }));
}

std::pair<beast::error_code, Incoming> Client::read(std::chrono::milliseconds timeout) {
  beast::flat_buffer buffer;
  auto ec = run([&](auto h) { ws_.async_read(buffer, h); }, timeout);
  Incoming in;
  if (ec) return {ec, in};
  in.text = ws_.got_text();
  in.data = beast::buffers_to_string(buffer.data());
  if (in.text) {
    auto m = grotto::proto::parse_server_message(in.data, grotto::proto::Limits{});
    EXPECT_TRUE(m.ok()) << in.data;
    if (m.ok()) in.message = std::move(m).value();
  }
  return {ec, in};
}

std::optional<Incoming> Client::next_text(std::chrono::milliseconds timeout) {
  auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline) {
    auto [ec, in] =
        read(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (ec) {
      last_error_ = ec;
      return std::nullopt;
    }
    if (in.text) return in;
    frames.push_back(std::move(in.data));
  }
  return std::nullopt;
}

beast::error_code Client::send(const std::string& text) {
  ws_.text(true);
  return run([&](auto h) { ws_.async_write(net::buffer(text), h); });
}

beast::error_code Client::send(const grotto::proto::ClientMessage& m) {
  return send(grotto::proto::serialize(m));
}

beast::error_code Client::send_binary(const std::string& bytes) {
  ws_.binary(true);
  return run([&](auto h) { ws_.async_write(net::buffer(bytes), h); });
}

grotto::proto::Welcome Client::hello(std::string name, std::vector<uint32_t> versions) {
  grotto::proto::Hello h;
  h.ref = 1;
  h.versions = std::move(versions);
  h.name = std::move(name);
  EXPECT_FALSE(send(h));
  auto in = next_text();
  EXPECT_TRUE(in && in->as<grotto::proto::Welcome>()) << (in ? in->data : "no reply");
  if (in && in->as<grotto::proto::Welcome>()) {
    seed_ = in->as<grotto::proto::Welcome>()->seed;
    return *in->as<grotto::proto::Welcome>();
  }
  return {};
}

bool Client::alive(uint64_t ref) {
  grotto::proto::Ping p;
  p.ref = ref;
  p.t = 1.5;
  if (send(p)) return false;
  auto in = next_text();
  while (in && !in->as<grotto::proto::Pong>())
    in = next_text();
  return in && in->as<grotto::proto::Pong>() && in->as<grotto::proto::Pong>()->ref == ref;
}

std::optional<grotto::proto::ErrorMessage> Client::next_error() {
  auto in = next_text();
  while (in && !in->as<grotto::proto::ErrorMessage>())
    in = next_text();
  if (!in) return std::nullopt;
  return *in->as<grotto::proto::ErrorMessage>();
}

websocket::close_reason Client::wait_close(std::chrono::milliseconds timeout) {
  auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline) {
    auto [ec, in] =
        read(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()));
    if (ec == websocket::error::closed) return ws_.reason();
    if (ec) {
      // Beast reports some closes (the peer's teardown racing our close reply) as another
      // error; the close frame it read still tells the code.
      last_error_ = ec;
      return ws_.reason();
    }
  }
  return {};
}

void Client::close(websocket::close_code code) {
  run([&](auto h) { ws_.async_close(code, h); });
}

void Client::close_tcp() {
  beast::error_code ignored;
  beast::get_lowest_layer(ws_).socket().close(ignored);
}

// ---- HTTP ----

HttpReply http_get(uint16_t port, const std::string& target, size_t body_bytes, size_t header_bytes,
                   std::chrono::milliseconds timeout) {
  net::io_context ioc;
  beast::tcp_stream stream(ioc);
  HttpReply out;
  stream.expires_after(timeout);
  beast::error_code ec;
  stream.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), port), ec);
  if (ec) return out;
  http::request<http::string_body> req(http::verb::get, target, 11);
  req.set(http::field::host, "127.0.0.1");
  if (header_bytes > 0) req.set("X-Padding", std::string(header_bytes, 'h'));
  if (body_bytes > 0) {
    req.body() = std::string(body_bytes, 'b');
    req.prepare_payload();
  }
  http::response<http::string_body> res;
  beast::flat_buffer buffer;
  http::async_write(stream, req, [&](beast::error_code e, std::size_t) {
    if (e) return;
    http::async_read(stream, buffer, res, [&](beast::error_code e2, std::size_t) {
      if (e2) return;
      out.status = static_cast<int>(res.result_int());
      out.body = res.body();
      out.content_type = std::string(res[http::field::content_type]);
      out.connection = std::string(res[http::field::connection]);
    });
  });
  ioc.run_for(timeout);
  return out;
}

std::vector<HttpAnswer> http_exchange(uint16_t port, const std::vector<HttpRequest>& requests,
                                      std::chrono::milliseconds timeout) {
  net::io_context ioc;
  beast::tcp_stream stream(ioc);
  std::vector<HttpAnswer> out;
  beast::error_code ec;
  stream.expires_after(timeout);
  stream.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), port), ec);
  if (ec) return out;
  beast::flat_buffer buffer;
  for (const HttpRequest& r : requests) {
    http::request<http::empty_body> req(http::verb::get, r.target, 11);
    if (auto verb = http::string_to_verb(r.method); verb != http::verb::unknown) {
      req.method(verb);
    } else {
      req.method_string(r.method);
    }
    req.set(http::field::host, "127.0.0.1");
    for (const auto& [name, value] : r.headers)
      req.set(name, value);
    http::response_parser<http::string_body> parser;
    parser.body_limit(64 << 20);
    if (req.method() == http::verb::head) parser.skip(true);
    bool answered = false;
    stream.expires_after(timeout);
    http::async_write(stream, req, [&](beast::error_code e, std::size_t) {
      if (e) return;
      http::async_read(stream, buffer, parser,
                       [&](beast::error_code e2, std::size_t) { answered = !e2; });
    });
    ioc.restart();
    ioc.run_for(timeout);
    if (!answered) break;
    auto res = parser.release();
    HttpAnswer a;
    a.status = static_cast<int>(res.result_int());
    for (const auto& f : res) {
      std::string name(f.name_string());
      for (char& c : name)
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      a.headers[name] = std::string(f.value());
    }
    a.body = std::move(res.body());
    out.push_back(std::move(a));
  }
  return out;
}

std::string websocket_room_frame(uint16_t port, RoomId room, uint32_t lod, uint32_t version,
                                 const std::string& token) {
  Client client(port);
  EXPECT_FALSE(client.connect());
  grotto::proto::Hello h;
  h.ref = 1;
  h.versions = {version};
  h.name = "room-frame";
  if (!token.empty()) h.token = token;
  EXPECT_FALSE(client.send(h));
  auto welcome = client.next_text();
  if (!welcome || !welcome->as<grotto::proto::Welcome>()) {
    ADD_FAILURE() << "no welcome: " << (welcome ? welcome->data : "nothing");
    return {};
  }
  grotto::proto::Request r;
  r.ref = 2;
  r.rooms.push_back({room, lod, 0});
  EXPECT_FALSE(client.send(r));
  auto [ec, in] = client.read();
  if (ec || in.text) {
    ADD_FAILURE() << "no room frame: " << (ec ? ec.message() : in.data);
    return {};
  }
  client.close();
  return in.data;
}

std::optional<double> metric(const std::string& exposition, const std::string& name) {
  std::istringstream lines(exposition);
  for (std::string line; std::getline(lines, line);) {
    if (line.size() > name.size() && line.compare(0, name.size(), name) == 0 &&
        line[name.size()] == ' ') {
      return std::stod(line.substr(name.size() + 1));
    }
  }
  return std::nullopt;
}

// ---- the fault suite's check ----

void expect_player_gets_rooms(Client& player) {
  auto rooms = sector_rooms(player.seed(), {0, 0, 0});
  ASSERT_FALSE(rooms.empty());
  // Another room on each call (while the sector lasts), so some are built, not only cached. One
  // at a time: a test's send queue may be as small as one frame.
  const auto& room = rooms[player.next_ref() % rooms.size()];
  ASSERT_FALSE(player.send(request_of({room}, 0, 1, player.next_ref())));
  for (;;) {
    auto [ec, in] = player.read();
    ASSERT_FALSE(ec) << "the player got no room: " << ec.message();
    if (in.text) {
      // Pongs and stats may arrive; an error means the player was refused.
      ASSERT_FALSE(in.as<grotto::proto::ErrorMessage>()) << in.data;
      continue;
    }
    auto frame = grotto::proto::decode_room_frame(
        std::span(reinterpret_cast<const uint8_t*>(in.data.data()), in.data.size()),
        grotto::proto::Limits{});
    ASSERT_TRUE(frame.ok()) << frame.error().message;
    if (frame->room.id != room.id) continue;  // an earlier request's room
    grotto::codec::DecodeLimits limits;
    limits.normals = grotto::proto::payload_has_normals(frame->version);
    auto mesh = grotto::codec::decode_room(frame->payload, limits);
    ASSERT_TRUE(mesh.ok()) << mesh.error().message;
    EXPECT_GT(mesh->triangle_count(), 0u);
    if (!limits.normals) {
      std::vector<grotto::codec::PortalDisc> discs;
      for (const auto& p : frame->room.portals)
        discs.push_back({p.centre, p.normal});
      ASSERT_TRUE(grotto::codec::derive_normals(mesh.value(), frame->origin, discs).ok());
      EXPECT_EQ(mesh->normals.size(), mesh->vertex_count());
    }
    return;
  }
}

void expect_still_serving(uint16_t port, Client* player) {
  EXPECT_EQ(http_get(port, "/healthz").status, 200);
  if (player) return expect_player_gets_rooms(*player);
  Client fresh(port);
  ASSERT_FALSE(fresh.connect());
  fresh.hello("fresh");
  expect_player_gets_rooms(fresh);
}

// ---- the program ----

Process spawn(std::vector<std::string> args, unsigned long max_fds) {
  int pipe_fds[2];
  EXPECT_EQ(pipe(pipe_fds), 0);
  Process p;
  p.pid = fork();
  if (p.pid == 0) {
    dup2(pipe_fds[1], 1);
    dup2(pipe_fds[1], 2);  // the log too
    close(pipe_fds[0]);
    if (max_fds != 0) {
      rlimit limit{max_fds, max_fds};
      setrlimit(RLIMIT_NOFILE, &limit);
    }
    std::vector<char*> argv;
    std::string bin = GROTTO_SERVER_BIN;
    argv.push_back(bin.data());
    for (auto& a : args)
      argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(bin.c_str(), argv.data());
    _exit(127);
  }
  close(pipe_fds[1]);
  p.out = pipe_fds[0];
  return p;
}

std::string read_until(int fd, const std::string& needle, std::chrono::milliseconds timeout) {
  std::string text;
  auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline && text.find(needle) == std::string::npos) {
    pollfd pfd{fd, POLLIN, 0};
    if (poll(&pfd, 1, 100) <= 0) continue;
    char buf[4096];
    ssize_t n = ::read(fd, buf, sizeof buf);
    if (n <= 0) break;
    text.append(buf, static_cast<size_t>(n));
  }
  return text;
}

int wait_exit(pid_t pid, std::chrono::milliseconds timeout) {
  auto deadline = Clock::now() + timeout;
  int status = 0;
  while (Clock::now() < deadline) {
    if (waitpid(pid, &status, WNOHANG) == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : -2;
    std::this_thread::sleep_for(10ms);
  }
  kill(pid, SIGKILL);
  waitpid(pid, &status, 0);
  return -1;
}

void stop_process(const Process& p) {
  kill(p.pid, SIGTERM);
  EXPECT_EQ(wait_exit(p.pid, 15s), 0);
  close(p.out);
}

uint16_t listening_port(const std::string& text) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex(R"(http://127\.0\.0\.1:(\d+))"))) return 0;
  return static_cast<uint16_t>(std::stoi(m[1]));
}

double cpu_seconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::istringstream fields(stat.substr(stat.rfind(')') + 2));
  std::string f;
  double ticks = 0;
  for (int i = 3; i <= 15 && fields >> f; ++i) {
    if (i >= 14) ticks += std::stod(f);  // utime, stime
  }
  return ticks / static_cast<double>(sysconf(_SC_CLK_TCK));
}

std::tuple<Process, uint16_t, std::string> start_with_cache(const std::string& cache,
                                                            const std::string& pocl_cache,
                                                            const std::vector<std::string>& flags) {
  std::string pocl = getenv("POCL_CACHE_DIR") ? getenv("POCL_CACHE_DIR") : "";
  setenv("GROTTO_CACHE_DIR", cache.c_str(), 1);
  unsetenv("POCL_CACHE_DIR");
  if (!pocl_cache.empty()) setenv("POCL_CACHE_DIR", pocl_cache.c_str(), 1);
  std::vector<std::string> args = {"--port", "0", "--workers", "1", "--io-threads", "1"};
  args.insert(args.end(), flags.begin(), flags.end());
  auto p = spawn(args);
  unsetenv("GROTTO_CACHE_DIR");
  unsetenv("POCL_CACHE_DIR");
  if (!pocl.empty()) setenv("POCL_CACHE_DIR", pocl.c_str(), 1);
  std::string text = read_until(p.out, "/ws)", 60s);
  return {p, listening_port(text), text};
}

}  // namespace grotto::server_test
