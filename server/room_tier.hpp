// Rooms from their owner: in a cluster, a replica asks the room tier for a room instead
// of building it. The tier is nginx in front of every replica (deploy/nginx): `hash $uri
// consistent` sends each room URL to one owner replica, which builds it (or has it cached), and
// proxy_cache with proxy_cache_lock keeps and collapses what passes, so a room is built once
// across the cluster. The generator (GeneratorConfig::owners) calls fetch() for a room nobody on
// this replica is building yet and builds the room itself when the answer is an error or late.
//
// This is a small HTTP/1.1 client: GET over keep-alive connections to one address, a bounded pool,
// a timeout per fetch covering connect, request and answer. It knows nothing of rooms but the
// path: RoomTierConfig::path_of turns a key into the URL path (PROTOCOL.md, "Rooms over HTTP").
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "common/core/result.hpp"
#include "server/rooms.hpp"

namespace grotto::server {

// Where the generator can get a room other than from its own builders.
class RoomSource {
 public:
  using Done = std::function<void(Result<std::vector<uint8_t>>)>;
  virtual ~RoomSource() = default;
  // Asks for the room's frame bytes. `done` runs exactly once, never inside fetch(), on another
  // thread: with the bytes of a 200 answer, or an error saying what went wrong (unreachable,
  // timed out, an HTTP status other than 200 with the first line of its body). The bytes are
  // not checked here: the caller decodes them like any untrusted frame.
  // `priority_ms` is how soon the room is needed (a want's priority), passed to the owner.
  virtual void fetch(const RoomKey& key, uint32_t priority_ms, std::chrono::milliseconds timeout,
                     Done done) = 0;
};

struct RoomTierConfig {
  std::string url;                                     // http://HOST:PORT, the tier's address
  std::function<std::string(const RoomKey&)> path_of;  // the room's URL path, from '/'
  size_t max_connections = 16;                         // kept-alive connections to the tier at most
  // The cluster's shared token (ServerConfig::token), sent as Authorization: Bearer so that an
  // owner with a token serves the room (PROTOCOL.md, "Rooms over HTTP"); empty: none sent.
  std::string token;
  size_t max_body_bytes = size_t{4} << 20;  // a longer answer is an error
};

class RoomTier final : public RoomSource {
 public:
  // Errors: invalid_argument naming what is wrong with the URL (only http://HOST:PORT, with an
  // optional trailing '/', is taken: the tier is on the replicas' private network) or the
  // other settings. Starts one I/O thread; the host is resolved at each new connection.
  static Result<std::unique_ptr<RoomTier>> create(RoomTierConfig config);
  ~RoomTier() override;  // fails what is pending ("room tier stopped"), joins the thread

  // GET of path_of(key) with Grotto-Priority: priority_ms (PROTOCOL.md, "Rooms over HTTP").
  void fetch(const RoomKey& key, uint32_t priority_ms, std::chrono::milliseconds timeout,
             Done done) override;

  struct Impl;

 private:
  explicit RoomTier(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Splits http://HOST:PORT[/] into host and port; errors name what is wrong.
Result<std::pair<std::string, std::string>> parse_tier_url(const std::string& url);

}  // namespace grotto::server
