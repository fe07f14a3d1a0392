#include "server/opencl_probe.hpp"

#include <spawn.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <latch>
#include <mutex>
#include <span>
#include <string_view>
#include <system_error>
#include <thread>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/kernels/binary_cache.hpp"
#include "common/kernels/room_builder.hpp"
#include "common/mesh/context.hpp"

extern char** environ;

namespace grotto::server {
namespace {

// The child's report lines (stderr, whatever the log level): "step <where>" before each step,
// then "passed <fields>", "no_device <why>" or "error <why>".
constexpr std::string_view kReport = "opencl_probe: ";

struct ChildResult {
  bool ok = false;
  std::string why;     // when not ok
  std::string passed;  // when ok on OpenCL: the child's "passed" fields
};

std::string clip(std::string line) {
  return line.size() > 300 ? line.substr(0, 300) + "..." : line;
}

// What the child's output says: the last step it began, its last report of `kind` ("error",
// "passed"), and its last line that is not a report (the driver's own words, or a log line).
struct ChildOutput {
  std::string step;
  std::string error;
  std::string passed;
  std::string last_other;
};

ChildOutput read_report(const std::string& text) {
  ChildOutput out;
  size_t begin = 0;
  while (begin < text.size()) {
    size_t end = text.find('\n', begin);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + begin, end - begin);
    begin = end + 1;
    while (!line.empty() && (line.back() == '\r' || line.back() == ' '))
      line.remove_suffix(1);
    if (line.empty()) continue;
    if (!line.starts_with(kReport)) {
      out.last_other = clip(std::string(line));
      continue;
    }
    line.remove_prefix(kReport.size());
    auto field = [&](std::string_view kind, std::string& to) {
      if (!line.starts_with(kind)) return false;
      to = clip(std::string(line.substr(kind.size())));
      return true;
    };
    field("step ", out.step) || field("error ", out.error) || field("passed ", out.passed);
  }
  return out;
}

ChildResult run_child(int argc, char** argv) {
  int pipe_fds[2];
  if (pipe(pipe_fds) != 0) return {false, std::string("pipe: ") + std::strerror(errno), {}};
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
    return {false, std::string("cannot start the probe: ") + std::strerror(err), {}};
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
  ChildOutput report = read_report(output);
  if (WIFEXITED(status) && (WEXITSTATUS(status) == 0 || WEXITSTATUS(status) == 3))
    return {true, {}, report.passed};
  std::string how = WIFSIGNALED(status) ? "killed by signal " + std::to_string(WTERMSIG(status))
                                        : "exit " + std::to_string(WEXITSTATUS(status));
  // Which step failed, then why: the child's own error, else the last thing it (or the driver)
  // wrote.
  std::string line = report.error.empty() ? report.last_other : report.error;
  std::string where = report.step.empty() ? "start-up" : report.step;
  return {false,
          "the OpenCL probe failed at " + where + " (" + how + (line.empty() ? ")" : "): " + line),
          {}};
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

// The life cycle the child drives. The server's generator opens one RoomBuilder per worker, each
// on its own thread and one at a time, every builder on the one shared device (an OpenCL context,
// a queue, the deformation program) the generator opened first, or (--opencl-queue per-worker)
// each on a context, queue and program of its own; then the workers build batches side by side,
// and at stop every builder is released, then the shared device.
// PoCL 5.0 (Ubuntu 24.04's) passed a probe that only built the program, then aborted the server
// as soon as its 14 workers ran the kernel at once (pocl_release_dlhandle_cache: Assertion
// 'found->ref_count > 0' failed); a child with two builders still passed there, and
// the server still aborted. So the child does what the server will do, twice: as many builders
// as the server has workers (at least two) opened one after another, batches of each size in
// kProbeBatchRooms (up to the server's max_batch_rooms) at each level of detail built on every
// builder at once, all released; then again, with the programs coming from the caches the first
// cycle filled. The sizes vary because the server's batches do, and a driver may compile a
// kernel anew for a new launch size (PoCL specializes its work-group functions).
constexpr int kProbeCycles = 2;
constexpr size_t kProbeBatchRooms[] = {1, 2, 8, 32};

// The builders the child opens: the server's workers (0: one per hardware thread), at least 2.
int probe_builders(const ServerConfig& config) {
  return std::max(2, static_cast<int>(resolved_workers(config.generator)));
}

void report(std::string_view kind, const std::string& text) {
  std::fprintf(stderr, "%.*s%.*s %s\n", static_cast<int>(kReport.size()), kReport.data(),
               static_cast<int>(kind.size()), kind.data(), text.c_str());
  std::fflush(stderr);
}

// kProbeFaultEnv "<cycle>:<builder>:<step>": the step at which the child aborts.
struct ProbeFault {
  int cycle = 0;  // 0: none
  int builder = 0;
  std::string step;
};

Result<ProbeFault> parse_fault(const char* text, int builders) {
  ProbeFault f;
  if (text == nullptr || *text == '\0') return f;
  char step[16] = {};
  int used = 0;
  if (std::sscanf(text, "%d:%d:%15[a-z]%n", &f.cycle, &f.builder, step, &used) != 3 ||
      text[used] != '\0' || f.cycle < 1 || f.cycle > kProbeCycles || f.builder < 1 ||
      f.builder > builders ||
      (std::string_view(step) != "open" && std::string_view(step) != "run" &&
       std::string_view(step) != "release")) {
    return invalid_argument(std::string(kProbeFaultEnv) + "='" + text +
                            "' is not <cycle>:<builder>:open|run|release within " +
                            std::to_string(kProbeCycles) + " cycles of " +
                            std::to_string(builders) + " builders");
  }
  f.step = step;
  return f;
}

std::string cycle_text(int cycle) {
  return "cycle " + std::to_string(cycle) + "/" + std::to_string(kProbeCycles);
}

std::string step_text(int cycle, int builder, int builders, std::string_view step) {
  return cycle_text(cycle) + ", builder " + std::to_string(builder) + "/" +
         std::to_string(builders) + ", " + std::string(step);
}

// Aborts when the fault names this step of this builder, as the driver did.
void inject_fault(const ProbeFault& fault, int cycle, int builder, int builders,
                  std::string_view step) {
  if (fault.cycle != cycle || fault.builder != builder || fault.step != step) return;
  std::fprintf(stderr, "%s=%d:%d:%s: aborting at %s\n", kProbeFaultEnv, cycle, builder,
               fault.step.c_str(), step_text(cycle, builder, builders, step).c_str());
  std::fflush(stderr);
  std::abort();
}

// One builder's part of a cycle, on a thread of its own as a worker's builder is.
struct BuilderRun {
  std::optional<kernels::RoomBuilder> builder;
  std::string error;
  size_t batches = 0;
  size_t rooms = 0;
};

void run_batches(BuilderRun& r, std::span<const cave::Room> rooms) {
  for (size_t size : kProbeBatchRooms) {
    for (int l = 0; l < mesh::kLodCount; ++l) {
      auto meshes =
          r.builder->build(rooms.first(std::min(size, rooms.size())), static_cast<mesh::Lod>(l));
      ++r.batches;
      for (const auto& m : meshes) {
        if (!m) {
          r.error = "a room failed to build: " + m.error().message;
          return;
        }
        ++r.rooms;
      }
    }
    if (size >= rooms.size()) break;
  }
  if (r.builder->fallbacks() > 0) r.error = "the device's launch failed (built on the CPU)";
}

}  // namespace

int probe_child(const ServerConfig& config) {
  const int builders = probe_builders(config);
  auto fault = parse_fault(std::getenv(kProbeFaultEnv), builders);
  if (!fault) {
    report("error", fault.error().message);
    return 2;
  }
  auto world = cave::World::create(config.seed, config.layout);
  if (!world) {
    report("error", "layout: " + world.error().message);
    return 2;
  }
  auto ctx = mesh::MeshContext::create(*world, config.mesh);
  if (!ctx) {
    report("error", "mesh parameters: " + ctx.error().message);
    return 2;
  }
  // Enough rooms for the largest batch, or the server's own largest if that is smaller.
  std::vector<cave::Room> rooms = cave::generate_sector(*world, {0, 0, 0}).rooms;
  rooms.resize(
      std::min({rooms.size(), config.generator.max_batch_rooms, std::end(kProbeBatchRooms)[-1]}));
  size_t batches = 0;
  size_t built = 0;
  const bool shared = config.generator.share_device;
  for (int cycle = 1; cycle <= kProbeCycles; ++cycle) {
    kernels::RoomBuilder::Options options = config.generator.builder;
    if (shared) {
      report("step", cycle_text(cycle) + ", shared device, open");
      auto device = kernels::SharedDeform::open(options.device, *ctx);
      if (!device) {
        // From the first cycle on: nothing to protect (the server says why), as a first builder
        // without a device of its own; after a good first cycle, the device failed.
        if (cycle == 1) {
          report("no_device", "cpu: " + device.error().message);
          return 3;
        }
        report("error", cycle_text(cycle) + ", shared device, open: " + device.error().message);
        return 4;
      }
      options.shared_device = std::move(device).value();
    }
    std::vector<BuilderRun> runs(builders);
    std::mutex open_mutex;  // builders open one at a time, as in the generator
    std::latch opened(builders);
    std::latch go(1);
    bool all_opened = false;  // written before go, read after it
    std::vector<std::thread> threads;
    for (int b = 0; b < builders; ++b) {
      threads.emplace_back([&, b] {
        BuilderRun& r = runs[b];
        {
          std::lock_guard lock(open_mutex);
          report("step", step_text(cycle, b + 1, builders, "open"));
          inject_fault(*fault, cycle, b + 1, builders, "open");
          r.builder.emplace(kernels::RoomBuilder::create(*ctx, options));
          if (!r.builder->uses_opencl()) r.error = r.builder->path();
        }
        opened.count_down();
        go.wait();
        if (!all_opened) return;
        inject_fault(*fault, cycle, b + 1, builders, "run");
        run_batches(r, rooms);
      });
    }
    opened.wait();
    all_opened =
        std::all_of(runs.begin(), runs.end(), [](const BuilderRun& r) { return r.error.empty(); });
    // The runs overlap, so the step names them all: which builder's launch killed the child is
    // not knowable from outside, only that running side by side did.
    if (all_opened) {
      report("step",
             cycle_text(cycle) + ", builders 1-" + std::to_string(builders) + " at once, run");
    }
    go.count_down();
    for (std::thread& t : threads)
      t.join();
    // No device at all, from the first builder on: nothing to protect (the server says why).
    if (cycle == 1 && !runs[0].builder->uses_opencl()) {
      report("no_device", runs[0].error);
      return 3;
    }
    for (int b = 0; b < builders; ++b) {
      batches += runs[b].batches;
      built += runs[b].rooms;
      if (runs[b].error.empty()) continue;
      report("error", step_text(cycle, b + 1, builders, runs[b].batches > 0 ? "run" : "open") +
                          ": " + runs[b].error);
      return 4;
    }
    // Released on this thread after the workers are gone, as ~Generator releases them.
    for (int b = 0; b < builders; ++b) {
      report("step", step_text(cycle, b + 1, builders, "release"));
      inject_fault(*fault, cycle, b + 1, builders, "release");
      runs[b].builder.reset();
    }
    if (shared) {
      report("step", cycle_text(cycle) + ", shared device, release");
      options.shared_device.reset();
    }
  }
  report("passed", "cycles=" + std::to_string(kProbeCycles) +
                       " builders=" + std::to_string(builders) +
                       " contexts=" + std::to_string(kProbeCycles * (shared ? 1 : builders)) +
                       " batches=" + std::to_string(batches) + " rooms=" + std::to_string(built) +
                       " released=" + std::to_string(kProbeCycles * builders));
  return 0;
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
  if (first.ok) {
    if (!first.passed.empty()) spdlog::info("event=opencl_probe_passed attempt=1 {}", first.passed);
    return std::nullopt;
  }
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
  if (second.ok) {
    if (!second.passed.empty()) {
      spdlog::info("event=opencl_probe_passed attempt=2 {}", second.passed);
    }
    return std::nullopt;
  }
  spdlog::warn("event=opencl_probe_failed attempt=2 detail=\"{}\"", second.why);
  return second.why;
}

}  // namespace grotto::server
