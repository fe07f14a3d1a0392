// The in-process grotto-server that grotto-client and grotto-load start when no --server is
// given: one way to start it, written once. Like server.hpp it names no Beast or Asio type, so
// the programs that embed a server compile none of the network layer's headers.
#pragma once

#include <memory>
#include <string>

#include "common/core/result.hpp"
#include "server/config.hpp"
#include "server/server.hpp"

namespace grotto::server {

// The settings an embedded server starts from: the defaults, and a 2 s drain at shutdown (the
// program is leaving; its own streams have stopped first). The caller sets the world, token,
// device and whatever else it needs before start_embedded.
ServerConfig embedded_config();

struct EmbeddedServer {
  std::unique_ptr<Server> server;
  std::string url;  // "ws://127.0.0.1:<port>/ws": what a stream::Stream connects to
};

// Server::start(config) on loopback: `bind` and `port` are replaced by 127.0.0.1 and an
// ephemeral port, so an embedded server is never reachable from elsewhere and never collides
// with another. Errors: those of Server::start.
Result<EmbeddedServer> start_embedded(ServerConfig config);

}  // namespace grotto::server
