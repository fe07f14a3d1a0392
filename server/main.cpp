// grotto-server: the generation server as a program. Settings from flags, a JSON config file and
// defaults (server/config.hpp); runs until SIGINT or SIGTERM, then stops gracefully within the
// drain timeout and exits 0. Exit codes: 0 after a clean stop (or --help), 1 when the server
// cannot start (address in use, no generator), 2 for invalid settings.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>

#include "proto/room_path.hpp"
#include "proto/world_digest.hpp"
#include "server/config.hpp"
#include "server/fd_limit.hpp"
#include "server/opencl_probe.hpp"
#include "server/room_tier.hpp"
#include "server/server.hpp"

int main(int argc, char** argv) {
  auto cli = grotto::server::parse_command_line(argc, argv);
  if (!cli.run) {
    std::fprintf(cli.exit_code == 0 ? stdout : stderr, "%s\n", cli.text.c_str());
    return cli.exit_code;
  }
  auto& config = cli.config;
  // Logs go to stderr, one line per event; stdout carries only the listening address.
  auto logger = spdlog::stderr_color_mt("grotto-server");
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(config.log_level));
  if (const char* probe = std::getenv(grotto::server::kProbeEnv); probe && *probe) {
    return grotto::server::probe_child(config);
  }
  // Every player is a descriptor: the soft limit goes up to the hard one, and a limit still short
  // of what --max-connections and --max-handshakes need is said now, not at the first EMFILE.
  grotto::server::raise_fd_limit(config);
  // A device build that would kill the process (PoCL's compiler on a full or broken cache) is
  // found by a child first; the server then serves from the CPU and says why.
  if (auto why = grotto::server::probe_opencl(config, argc, argv)) {
    spdlog::warn("event=compute_path_fallback reason=\"{}\"", *why);
    config.generator.builder.device.device = "none";
    config.generator.builder.device.none_reason = "CPU fallback: " + *why;
  }

  // In a cluster, rooms come from their owner replica through the room tier first.
  if (!config.room_tier.empty()) {
    grotto::server::RoomTierConfig tier;
    tier.url = config.room_tier;
    tier.max_body_bytes = config.limits.max_frame_bytes;
    tier.token = config.token;  // the owners share it (one cluster, one token)
    const uint64_t params = grotto::proto::world_params_digest(config.layout, config.mesh);
    tier.path_of = [params](const grotto::server::RoomKey& key) {
      return grotto::proto::room_path({key.version, key.seed, params, key.lod, key.id});
    };
    auto opened = grotto::server::RoomTier::create(std::move(tier));
    if (!opened) {
      std::fprintf(stderr, "grotto-server: %s\n", opened.error().message.c_str());
      return 2;
    }
    config.generator.owners = std::move(opened).value();
    spdlog::info("event=room_tier url={} owner_timeout_ms={}", config.room_tier,
                 config.generator.owner_timeout.count());
  }

  // Block the signals before any thread starts, so every thread inherits the mask and sigwait
  // below is the only place they arrive.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  auto server = grotto::server::Server::start(config);
  if (!server) {
    spdlog::error("event=start_failed error=\"{}\"", server.error().message);
    std::fprintf(stderr, "grotto-server: %s\n", server.error().message.c_str());
    return server.error().code == grotto::ErrorCode::kInvalidArgument ? 2 : 1;
  }
  std::printf("grotto-server listening on http://%s (WebSocket: ws://%s/ws)\n",
              (*server)->address().c_str(), (*server)->address().c_str());
  std::fflush(stdout);

  int signal = 0;
  sigwait(&signals, &signal);
  spdlog::info("event=signal signal={}", signal == SIGINT ? "SIGINT" : "SIGTERM");
  (*server)->stop(config.drain_timeout);
  spdlog::info("event=exit code=0");
  return 0;
}
