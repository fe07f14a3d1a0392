// What the tests of a real server share (server_tests and fault_tests): a Server started
// in-process on 127.0.0.1, port 0; Beast WebSocket and HTTP clients on loopback; the grotto-server
// program as a child process; and the one check every fault test makes, that the server still
// answers /healthz and a player still gets rooms. Every wait is bounded (kWait), so a broken
// server fails a test instead of hanging it.
//
// The Beast code is instantiated in server_harness.cpp only (each translation unit that
// instantiates Beast's operations costs ~25 s and ~0.8 GB to compile); including this header
// costs the parse.
#pragma once

#include <sys/types.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/websocket/stream.hpp>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <variant>
#include <vector>

#include "common/cave/layout.hpp"
#include "proto/messages.hpp"
#include "server/config.hpp"
#include "server/server.hpp"

namespace grotto::server_test {

namespace beast = boost::beast;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using grotto::ErrorCode;
using grotto::cave::RoomId;
using grotto::server::Server;
using grotto::server::ServerConfig;

constexpr auto kWait = 20s;  // the longest any single step may take before the test fails

// Port 0, two I/O threads and two workers on the CPU reference (no OpenCL start-up), log at warn.
ServerConfig test_config();
// Server::start, failing the test (and returning null) when it does not start.
std::unique_ptr<Server> start(const ServerConfig& c);

std::vector<grotto::cave::Room> sector_rooms(uint64_t seed, grotto::cave::SectorCoord sector);
// `count` rooms of seed 7, sector after sector.
std::vector<grotto::cave::Room> many_rooms(size_t count);
grotto::proto::Request request_of(const std::vector<grotto::cave::Room>& rooms, size_t from,
                                  size_t count, uint64_t ref, uint32_t priority = 0);
RoomId frame_id(const std::string& frame);

// A message from the server: a text frame (parsed) or a binary room frame.
struct Incoming {
  bool text = false;
  std::string data;
  std::optional<grotto::proto::ServerMessage> message;
  template <class T>
  const T* as() const {
    return message ? std::get_if<T>(&*message) : nullptr;
  }
};

// A WebSocket client on its own io_context; every operation runs with a deadline.
class Client {
 public:
  explicit Client(uint16_t port);
  ~Client();

  // Connects and upgrades (on a refused upgrade, response() holds the server's answer).
  beast::error_code connect(const std::string& target = "/ws");
  // Before connect: a small receive buffer, so that the server's writes back up soon.
  void set_receive_buffer(int bytes);
  // Before connect: a header field the upgrade request carries (a balancer's mark, say).
  void set_upgrade_header(const std::string& name, const std::string& value);
  // Reads for at most `timeout`: a frame, or the error (websocket::error::closed after a close).
  std::pair<beast::error_code, Incoming> read(std::chrono::milliseconds timeout = kWait);
  // The next text message, skipping room frames (kept in `frames`).
  std::optional<Incoming> next_text(std::chrono::milliseconds timeout = kWait);
  beast::error_code send(const std::string& text);
  beast::error_code send(const grotto::proto::ClientMessage& m);
  beast::error_code send_binary(const std::string& bytes);
  // hello offering `versions`, then the welcome (its seed is kept for expect_player_gets_rooms);
  // fails the test otherwise.
  grotto::proto::Welcome hello(std::string name = "test", std::vector<uint32_t> versions = {2, 1});
  // A ping answered: the connection still works.
  bool alive(uint64_t ref = 99);
  // The next error message.
  std::optional<grotto::proto::ErrorMessage> next_error();
  // Reads until the server closes; returns its close reason (code 0 if it never closed).
  websocket::close_reason wait_close(std::chrono::milliseconds timeout = kWait);
  // A WebSocket close handshake with `code`, bounded like every operation.
  void close(websocket::close_code code = websocket::close_code::normal);
  void close_tcp();

  websocket::stream<beast::tcp_stream>& ws() { return ws_; }
  const websocket::response_type& response() const { return response_; }
  uint64_t seed() const { return seed_; }
  uint64_t next_ref() { return next_ref_++; }

  std::vector<std::string> frames;  // room frames received while waiting for text
  beast::error_code last_error_;

 private:
  template <class Start>
  beast::error_code run(Start start, std::chrono::milliseconds timeout = kWait);

  uint16_t port_;
  net::io_context ioc_;
  websocket::stream<beast::tcp_stream> ws_;
  websocket::response_type response_;
  uint64_t seed_ = 0;
  uint64_t next_ref_ = 1000;
};

struct HttpReply {
  int status = 0;  // 0: no answer (refused, reset, or none within the timeout)
  std::string body;
  std::string content_type;
  std::string connection;  // the Connection header
};

// One GET on a fresh connection, within `timeout`; optionally with a body or padded headers.
HttpReply http_get(uint16_t port, const std::string& target, size_t body_bytes = 0,
                   size_t header_bytes = 0, std::chrono::milliseconds timeout = kWait);

// A metric's value in a /metrics body (the first sample named exactly `name`, labels included);
// nullopt if absent.
std::optional<double> metric(const std::string& exposition, const std::string& name);

// ---- the fault suite's check ----

// A real player's part: asks for a room of the spawn sector of the world it was welcomed to (a
// different one each call), then decodes its room frame and Draco payload. `player` has said
// hello.
void expect_player_gets_rooms(Client& player);
// /healthz answers 200 and a player gets rooms: `player` (already in: during some faults new
// players are rightly kept out) or, without one, a new player that connects and says hello.
void expect_still_serving(uint16_t port, Client* player = nullptr);

// ---- the grotto-server program ----

struct Process {
  pid_t pid = -1;
  int out = -1;  // its stdout and stderr
};

// Runs grotto-server with `args`; `max_fds` sets its RLIMIT_NOFILE (0: inherited).
Process spawn(std::vector<std::string> args, unsigned long max_fds = 0);
// Reads the process's output until `needle` appears or the timeout passes; what was read.
std::string read_until(int fd, const std::string& needle, std::chrono::milliseconds timeout);
// Waits for the process; its exit status, or -1 if it had to be killed.
int wait_exit(pid_t pid, std::chrono::milliseconds timeout);
// SIGTERM, expecting exit 0 within 15 s.
void stop_process(const Process& p);
// The port of "grotto-server listening on http://127.0.0.1:PORT ..." in `text`; 0 if absent.
uint16_t listening_port(const std::string& text);
// CPU seconds the process has used (user + system).
double cpu_seconds(pid_t pid);
// Starts grotto-server (OpenCL auto) with `cache` as GROTTO_CACHE_DIR and PoCL's cache left to
// it; returns the process and its port (0 if it never listened), and what it printed.
// `pocl_cache` sets POCL_CACHE_DIR as a deployment does; `flags` go after the harness's own.
std::tuple<Process, uint16_t, std::string> start_with_cache(
    const std::string& cache, const std::string& pocl_cache = {},
    const std::vector<std::string>& flags = {});

}  // namespace grotto::server_test
