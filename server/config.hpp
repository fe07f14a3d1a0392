// grotto-server's settings: built-in defaults, overridden by an optional JSON config file
// (--config FILE, keys named like the long flags without "--"), overridden by command-line flags.
// A plain struct: brace-init gives defaults that work (loopback, a thread per core).
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

#include "common/cave/params.hpp"
#include "common/core/result.hpp"
#include "common/mesh/params.hpp"
#include "proto/messages.hpp"
#include "server/admission.hpp"
#include "server/generator.hpp"

namespace grotto::server {

inline constexpr uint16_t kDefaultPort = 7878;

struct ServerConfig {
  std::string bind = "127.0.0.1";      // listen address; "0.0.0.0" or "::" to open it up
  uint16_t port = kDefaultPort;        // 0: an ephemeral port (Server::port() tells which)
  int io_threads = 0;                  // Asio threads; 0: one per hardware thread
  uint64_t seed = cave::kDefaultSeed;  // the world served
  cave::LayoutParams layout{};         // its layout parameters (a few are settings)
  mesh::MeshParams mesh{};
  proto::Limits limits{};      // announced in welcome and enforced
  int max_connections = 1024;  // players (sessions past hello) at once; more are refused
  // Sessions upgraded but not yet past hello, counted apart from players so that sockets which
  // never say hello cannot take the players' places; each has handshake_timeout_ms.
  int max_handshakes = 512;
  // Past capacity a valid hello waits in a queue or is refused (server/admission.hpp): queue
  // length (--max-queue) and how late the oldest urgent want may be before newcomers wait
  // (--admission-late-ms; 0: every hello is admitted as it comes, up to max_connections).
  AdmissionConfig admission{};
  size_t send_queue_bytes = size_t{8} << 20;       // unsent bytes per client before it is dropped
  std::chrono::milliseconds http_timeout{10'000};  // a plain HTTP request or a WebSocket upgrade
  std::chrono::milliseconds drain_timeout{5'000};  // stop(): bound on the graceful close
  GeneratorConfig generator{};
  // The room tier (deploy/nginx): http://HOST:PORT where this replica asks for rooms
  // before building them (their owner replica answers, through nginx's cache); empty: none.
  // grotto-server opens it (server/room_tier) into generator.owners.
  std::string room_tier;
  std::string log_level = "info";  // trace, debug, info, warn, error, off
  // The shared secret every hello must carry (proto/token.hpp); empty: none required.
  // parse_command_line reads it from token_file, else from $GROTTO_TOKEN. Never logged.
  std::string token;
  std::string token_file;  // where the token came from ("" for the environment or none)
  // The browser viewer (web/) at / and the room extras it reads (/extras/...); false: both
  // answer 404 (--no-viewer), the rooms and the WebSocket are served as before.
  bool viewer = true;
};

// Range checks the settings cannot express alone (layout and mesh parameters, limit minimums).
// The message names the setting.
Status validate(const ServerConfig& config);

// Applies a JSON config file over `config`. Errors name the file and the key: an unknown key, a
// value of the wrong type or out of range, an unreadable or invalid file.
Status apply_config_file(const std::string& path, ServerConfig& config);

// What the command line asks for: run with `config`, or print `text` and exit with `exit_code`
// (0 after --help or --version, 2 for an invalid flag, file or value; `text` names the setting).
struct CommandLine {
  ServerConfig config;
  bool run = false;
  int exit_code = 0;
  std::string text;
};
CommandLine parse_command_line(int argc, const char* const* argv);

// "grotto-server 0.3.0"
std::string product_version();

}  // namespace grotto::server
