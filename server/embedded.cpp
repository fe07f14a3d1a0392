#include "server/embedded.hpp"

#include <chrono>
#include <utility>

namespace grotto::server {

ServerConfig embedded_config() {
  ServerConfig config;
  config.drain_timeout = std::chrono::milliseconds(2'000);
  return config;
}

Result<EmbeddedServer> start_embedded(ServerConfig config) {
  config.bind = "127.0.0.1";
  config.port = 0;
  auto started = Server::start(config);
  if (!started) return started.error();
  EmbeddedServer out;
  out.server = std::move(started).value();
  out.url = "ws://127.0.0.1:" + std::to_string(out.server->port()) + "/ws";
  return out;
}

}  // namespace grotto::server
