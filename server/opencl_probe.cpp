#include "server/opencl_probe.hpp"

#include <spawn.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>

#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <system_error>
#include <vector>

#include "kernels/binary_cache.hpp"
#include "kernels/room_builder.hpp"
#include "mesh/context.hpp"

extern char** environ;

namespace grotto::server {
namespace {

struct ChildResult {
  bool ok = false;
  std::string why;  // when not ok
};

// The last non-empty line of `text`, at most 300 bytes.
std::string last_line(const std::string& text) {
  size_t end = text.find_last_not_of("\r\n");
  if (end == std::string::npos) return {};
  size_t begin = text.rfind('\n', end);
  begin = begin == std::string::npos ? 0 : begin + 1;
  std::string line = text.substr(begin, end - begin + 1);
  return line.size() > 300 ? line.substr(0, 300) + "..." : line;
}

ChildResult run_child(int argc, char** argv) {
  int pipe_fds[2];
  if (pipe(pipe_fds) != 0) return {false, std::string("pipe: ") + std::strerror(errno)};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], STDERR_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addclose(&actions, pipe_fds[0]);
  std::vector<std::string> env_text;
  for (char** e = environ; *e != nullptr; ++e)
    env_text.emplace_back(*e);
  env_text.push_back(std::string(kProbeEnv) + "=1");
  std::vector<char*> envp;
  for (auto& e : env_text)
    envp.push_back(e.data());
  envp.push_back(nullptr);
  std::vector<char*> args(argv, argv + argc);
  args.push_back(nullptr);
  pid_t pid = 0;
  int err = posix_spawn(&pid, "/proc/self/exe", &actions, nullptr, args.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  close(pipe_fds[1]);
  if (err != 0) {
    close(pipe_fds[0]);
    return {false, std::string("cannot start the probe: ") + std::strerror(err)};
  }
  std::string output;
  char buf[4096];
  for (ssize_t n; (n = read(pipe_fds[0], buf, sizeof buf)) != 0;) {
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) break;
    output.append(buf, static_cast<size_t>(n));
    if (output.size() > 65536) output.erase(0, output.size() - 4096);
  }
  close(pipe_fds[0]);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status) && (WEXITSTATUS(status) == 0 || WEXITSTATUS(status) == 3))
    return {true, {}};
  std::string how = WIFSIGNALED(status) ? "killed by signal " + std::to_string(WTERMSIG(status))
                                        : "exit " + std::to_string(WEXITSTATUS(status));
  std::string line = last_line(output);
  return {false, "the OpenCL probe failed (" + how + (line.empty() ? ")" : "): " + line)};
}

// Whether `dir` holds nothing but what PoCL 3 writes in its cache (directories named by two
// capital letters of a hash, and tempfile_* files): only then is emptying it safe when the
// operator chose it through POCL_CACHE_DIR.
bool looks_like_pocl_cache(const std::filesystem::path& dir) {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    const bool hash_dir =
        e.is_directory(ec) && name.size() == 2 && std::isupper(name[0]) && std::isupper(name[1]);
    if (!hash_dir && !name.starts_with("tempfile")) return false;
  }
  return !ec;
}

// Empties PoCL's cache directory (keeps the directory itself).
void empty_dir(const std::filesystem::path& dir) {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec))
    std::filesystem::remove_all(e.path(), ec);
}

}  // namespace

int probe_child(const ServerConfig& config) {
  auto world = cave::World::create(config.seed, config.layout);
  if (!world) return 2;
  auto ctx = mesh::MeshContext::create(*world, config.mesh);
  if (!ctx) return 2;
  auto builder = kernels::RoomBuilder::create(*ctx, config.generator.builder);
  return builder.path().starts_with("opencl") ? 0 : 3;
}

std::optional<std::string> probe_opencl(const ServerConfig& config, int argc, char** argv) {
  const auto& device = config.generator.builder.device;
  if (kernels::opencl_disabled(device)) return std::nullopt;
  // PoCL's own cache under a directory Grotto owns, so it can be discarded when it is broken;
  // one the operator chose is emptied only when it holds nothing but PoCL's cache.
  std::filesystem::path pocl_dir;
  bool owned = false;
  const char* pocl = std::getenv("POCL_CACHE_DIR");
  if (pocl == nullptr || *pocl == '\0') {
    std::filesystem::path dir = kernels::resolve_cache_dir(device.cache_dir);
    if (!dir.empty()) {
      pocl_dir = dir / "pocl";
      owned = true;
      setenv("POCL_CACHE_DIR", pocl_dir.c_str(), 1);
    }
  } else {
    pocl_dir = pocl;
  }
  ChildResult first = run_child(argc, argv);
  if (first.ok) return std::nullopt;
  spdlog::warn("event=opencl_probe_failed attempt=1 detail=\"{}\"", first.why);
  // Both caches are Grotto's to discard: PoCL's when it lives under Grotto's, and Grotto's own
  // program binaries (an entry can pass its checksum and still hold a cut binary that crashes
  // the driver, if it was cut before it was written).
  std::error_code ignored;
  if (!pocl_dir.empty() && (owned || looks_like_pocl_cache(pocl_dir))) {
    empty_dir(pocl_dir);
    spdlog::info("event=pocl_cache_discarded dir={}", pocl_dir.string());
  } else if (!pocl_dir.empty()) {
    spdlog::warn("event=pocl_cache_kept dir={} reason=\"it holds more than PoCL's cache\"",
                 pocl_dir.string());
  }
  if (std::filesystem::path dir = kernels::resolve_cache_dir(device.cache_dir); !dir.empty()) {
    size_t removed = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir, ignored)) {
      if (e.path().extension() == ".clbin" && std::filesystem::remove(e.path(), ignored)) ++removed;
    }
    spdlog::info("event=program_cache_discarded dir={} files={}", dir.string(), removed);
  }
  ChildResult second = run_child(argc, argv);
  if (second.ok) return std::nullopt;
  spdlog::warn("event=opencl_probe_failed attempt=2 detail=\"{}\"", second.why);
  return second.why;
}

}  // namespace grotto::server
