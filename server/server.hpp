// grotto-server's network half: one port serving HTTP (/healthz, /readyz, /metrics, /version)
// and the WebSocket protocol (proto/PROTOCOL.md) on /ws, in front of a Generator. Embeddable:
// no global state and no signal handling, so grotto-client and grotto-load can run one
// in-process on loopback.
//
// Threads: `io_threads` Asio threads run every socket; each connection has its own strand, so a
// session's handlers never run concurrently. Generation runs on the Generator's workers, whose
// deliveries are posted to the session's strand. Thread safety: every public member function
// may be called from any thread; stop() from one thread at a time.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "common/core/result.hpp"
#include "server/config.hpp"
#include "server/generator.hpp"
#include "server/metrics.hpp"

namespace grotto::server {

class Server {
 public:
  // Validates the config, creates the Generator, binds and listens (port 0: an ephemeral port),
  // and starts the I/O threads. Errors: invalid configuration (names the setting), a generator
  // that cannot start, an address that cannot be bound (kUnavailable, naming it).
  static Result<std::unique_ptr<Server>> start(const ServerConfig& config);
  ~Server();  // stop(config.drain_timeout) unless stopped already

  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  uint16_t port() const;        // the bound port
  std::string address() const;  // "127.0.0.1:7878", as bound
  const ServerConfig& config() const;

  // Graceful and bounded: refuses new work, sends every session an error `service_restart` and
  // closes it (close code 1001, reason "service_restart"), shuts the generator down (queued rooms
  // fail, building ones finish), waits up to `drain` for the sessions to close, then stops
  // accepting, cuts what is left and joins the I/O threads. Connections arriving during the
  // drain are accepted and sent `service_restart` as they upgrade (PROTOCOL.md, "Refused at the
  // door"). Returns within about `drain` plus the time to join. Idempotent.
  void stop(std::chrono::milliseconds drain);
  bool stopping() const;

  Metrics& metrics();
  Generator& generator();
  size_t sessions() const;  // WebSocket sessions open now

  struct Impl;

 private:
  explicit Server(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace grotto::server
