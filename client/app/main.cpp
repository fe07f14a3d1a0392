// grotto-client: the player's program. A GLFW window over client/render, fed by a
// client/stream Stream connected to --server or to a server started in-process; a player that
// walks or flies and collides with the cave (client/play); headless --screenshot and --bench,
// through EGL where there is no display. Flags live in options.cpp, the loops in app.cpp, the
// window or EGL context in gl_context.cpp; this file makes the context, the renderer, the server
// and the stream, and tears them down in order.
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "client/app/app.hpp"
#include "client/app/gl_context.hpp"
#include "client/app/options.hpp"
#include "client/render/gl.hpp"
#include "server/embedded.hpp"

namespace {

namespace app = grotto::app;
namespace stream = grotto::stream;
namespace render = grotto::render;

int fail(const std::string& message) {
  std::fprintf(stderr, "grotto-client: %s\n", message.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  app::Options o;
  if (auto exit_code = app::parse_options(argc, argv, o)) return *exit_code;
  spdlog::set_level(spdlog::level::from_str(o.log_level));

  // The GL context first: without one nothing else is worth starting.
  const bool headless = !o.screenshot.empty() || o.bench_s.has_value();
  const app::GlBackend backend =
      app::choose_backend(o.gl, headless, std::getenv("DISPLAY"), std::getenv("WAYLAND_DISPLAY"));
  auto context_or = backend == app::GlBackend::kEgl
                        ? app::GlContext::open_egl()
                        : app::GlContext::open_window(headless ? 64 : o.width,
                                                      headless ? 64 : o.height, !headless);
  if (!context_or) return fail(context_or.error().message);
  app::GlContext context = std::move(context_or).value();
  spdlog::info("event=gl_context backend={} from=\"{}\" {}",
               context.backend() == app::GlBackend::kEgl ? "egl" : "glfw", context.origin(),
               render::describe_context());
  // Mesa's llvmpipe (3D in software) drops triangles from patches tessellated at level 16 and
  // above (levels up to 14 are whole; seen with Mesa 22.3): cap the level there rather than show
  // holes in the cave.
  constexpr float kLlvmpipeMaxTess = 14;
  const auto* gl_renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  if (gl_renderer != nullptr && std::string(gl_renderer).find("llvmpipe") != std::string::npos &&
      o.tess_max > kLlvmpipeMaxTess) {
    std::fprintf(stderr,
                 "grotto-client: --tess-max %.0f lowered to %.0f on llvmpipe (software GL drops "
                 "triangles above it)\n",
                 o.tess_max, kLlvmpipeMaxTess);
    o.tess_max = kLlvmpipeMaxTess;
  }

  auto renderer_or = render::Renderer::create();
  if (!renderer_or) return fail(renderer_or.error().message);
  // GL objects: released below while the context still exists.
  auto renderer = std::make_unique<render::Renderer>(std::move(renderer_or).value());
  auto overlay_or = render::Overlay::create();
  if (!overlay_or) return fail(overlay_or.error().message);
  auto overlay = std::make_unique<render::Overlay>(std::move(overlay_or).value());
  auto cache = std::make_unique<render::GpuRoomCache>();

  // The in-process server when no --server was given.
  std::unique_ptr<grotto::server::Server> server;
  std::string url = o.server_url;
  if (url.empty()) {
    grotto::server::ServerConfig config = grotto::server::embedded_config();
    if (o.seed) config.seed = *o.seed;
    config.token = o.token;
    config.generator.builder.device.device = o.device;
    config.log_level = o.log_level;
    auto started = grotto::server::start_embedded(config);
    if (!started) return fail("in-process server: " + started.error().message);
    url = started.value().url;
    server = std::move(started.value().server);
  }
  stream::Runtime runtime(1, 0);
  stream::StreamOptions so;
  so.url = url;
  so.seed = o.seed;
  so.token = o.token;
  so.name = "grotto-client";
  so.protocol_version = o.protocol_version;
  so.spawn = !o.pose.has_value();
  so.net = o.net;
  // Pictures and benchmarks wait for every room within the fixed horizon before they shoot, so
  // that what a frame shows does not depend on how quickly the server answered (the adaptive
  // horizon, the default for play, follows the server's latency).
  if (headless) so.min_horizon_s = 0;
  auto stream_or = stream::Stream::start(so, runtime);
  if (!stream_or) return fail(stream_or.error().message);
  std::unique_ptr<stream::Stream> stream = std::move(stream_or).value();

  int status = 0;
  {
    app::Session session(o, *renderer, *overlay, *cache, *stream);
    status = headless ? app::run_headless(session) : app::run_window(session, context.window());
  }

  stream->stop();
  stream.reset();
  cache.reset();
  overlay.reset();
  renderer.reset();
  // The GL context goes at the end of main, after every GL object.
  if (server) server->stop(server->config().drain_timeout);
  return status;
}
