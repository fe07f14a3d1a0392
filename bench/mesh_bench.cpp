// The thesis's own experiment (Figures 3-10 to 3-12), side by side: a 100-room cave at the
// thesis's density, time per stage for the CPU reference on one thread and for OpenCL, vertices/s
// against buffer size, and one launch per room against one batched launch. Writes a JSON report.
// Command and results: docs/BENCHMARKS.md.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "bench/flags.hpp"
#include "bench/timing.hpp"
#include "common/kernels/deform.hpp"
#include "common/kernels/room_builder.hpp"
#include "common/mesh/room_mesh.hpp"

namespace {

using namespace grotto;
using bench::median_ms;

// FNV-1a over every byte of the meshes: equal digests before and after a change mean the change
// kept the meshes bit-identical.
struct Digest {
  uint64_t h = 1469598103934665603ull;
  template <class T>
  void add(const std::vector<T>& v) {
    const auto* p = reinterpret_cast<const unsigned char*>(v.data());
    for (size_t i = 0; i < v.size() * sizeof(T); ++i)
      h = (h ^ p[i]) * 1099511628211ull;
  }
  void add(const mesh::RoomMesh& m) {
    add(m.positions);
    add(m.normals);
    add(m.roughness);
    add(m.mineral);
    add(m.rim_portal);
    add(m.rim_index);
    add(m.indices);
  }
};

// One part of a launch's time (a LaunchStats field), the median over several launches' stats.
double median_of(const std::vector<kernels::LaunchStats>& runs,
                 double kernels::LaunchStats::*field) {
  std::vector<double> v;
  for (const kernels::LaunchStats& r : runs)
    v.push_back(r.*field);
  return bench::median(v);
}

struct Deformed {
  std::vector<std::vector<mesh::core::float3>> positions;
  std::vector<std::vector<float>> clearance;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mesh_bench: the thesis's cave-building experiment on this machine (CPU reference "
      "on one thread vs OpenCL), with a JSON report"};
  std::string json_path = "mesh_bench.json";
  int reps = 5, room_count = 100;
  uint64_t seed = 7;  // every binary's default world
  int lanes = 0;
  std::string lod_name = "detail";
  app.add_option("--json", json_path, "Write the report here")->capture_default_str();
  app.add_option("--repetitions", reps, "Runs per measurement (the median is reported)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--rooms", room_count, "Rooms in the cave")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--seed", seed, "World seed")->capture_default_str();
  app.add_option("--lanes", lanes,
                 "Vertices per OpenCL work item: 0 picks by device (8 on CPUs, 1 on GPUs)")
      ->check(CLI::IsMember(std::vector<int>{0, 1, 8}))
      ->capture_default_str();
  app.add_option("--lod", lod_name,
                 "Level of detail: detail (the thesis's cave) or patch (what "
                 "the server streams)")
      ->check(CLI::IsMember(std::vector<std::string>{"detail", "patch"}))
      ->capture_default_str();
  std::string device_choice;
  app.add_option("--device", device_choice,
                 "OpenCL device: auto, gpu, accelerator, cpu or a name substring; empty: "
                 "$GROTTO_OPENCL_DEVICE, else auto (bench/gpu.sh runs each it finds)");
  bool no_profiling = false;
  app.add_flag("--no-profiling", no_profiling,
               "Open OpenCL queues without CL_QUEUE_PROFILING_ENABLE (the device split reads 0): "
               "to check that profiling costs nothing");
  std::string channels_choice = "auto";
  app.add_option("--channels", channels_choice,
                 "Where the whole cave's detail channels run with a device: auto (with the "
                 "deformation unless the device is a CPU), device (with the deformation) or host")
      ->check(CLI::IsMember(std::vector<std::string>{"auto", "device", "host"}))
      ->capture_default_str();
  if (auto rc = bench::parse_flags(app, argc, argv)) return *rc;
  using Channels = kernels::RoomBuilder::Options::Channels;
  const Channels channels = channels_choice == "device" ? Channels::kDevice
                            : channels_choice == "host" ? Channels::kHost
                                                        : Channels::kAuto;

  cave::World world = cave::World::create(seed, cave::LayoutParams{}).value();
  mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
  const mesh::Lod lod = lod_name == "patch" ? mesh::Lod::kPatch : mesh::Lod::kDetail;

  // Layout: enough sectors for the cave, timed as one stage.
  cave::Region region;
  double layout_ms = median_ms(reps, [&] {
    region = cave::generate_region(world, {0, 0, 0}, {0, 0, 0});
  });
  std::vector<cave::Room> rooms(
      region.rooms.begin(),
      region.rooms.begin() + std::min<size_t>(room_count, region.rooms.size()));

  std::vector<mesh::DeformInput> inputs;
  double prepare_ms = median_ms(reps, [&] {
    inputs.clear();
    for (const cave::Room& r : rooms)
      inputs.push_back(mesh::prepare_room(ctx, r, lod));
  });
  size_t donor_vertices = 0;
  for (auto& in : inputs)
    donor_vertices += in.donor->directions.size();

  Deformed cpu;
  double deform_cpu_time_ms = 0;
  double deform_cpu_ms = median_ms(
      reps,
      [&] {
        cpu.positions.assign(inputs.size(), {});
        cpu.clearance.assign(inputs.size(), {});
        for (size_t i = 0; i < inputs.size(); ++i) {
          size_t n = inputs[i].donor->directions.size();
          cpu.positions[i].resize(n);
          cpu.clearance[i].resize(n);
          mesh::deform_cpu(ctx, inputs[i], cpu.positions[i], cpu.clearance[i]);
        }
      },
      &deform_cpu_time_ms);

  mesh::AssembleStats stage{};
  size_t out_vertices = 0;
  // The slowest room's assembly: what the whole cave on many threads cannot go under while rooms
  // are the unit of work (RoomBuilder's threads take whole rooms), less its channels, which a
  // build on several threads computes in pieces on every thread.
  double slowest_room_ms = 0;
  double slowest_room_channels_ms = 0;
  size_t slowest_room_vertices = 0;
  Digest digest;
  double assemble_cpu_time_ms = 0;
  double assemble_ms = median_ms(
      reps,
      [&] {
        stage = {};
        out_vertices = 0;
        slowest_room_ms = 0;
        for (size_t i = 0; i < inputs.size(); ++i) {
          mesh::AssembleStats s;
          const auto t0 = std::chrono::steady_clock::now();
          auto m = mesh::assemble_room(ctx, inputs[i], cpu.positions[i], cpu.clearance[i], &s);
          const double room_ms =
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                  .count();
          if (room_ms > slowest_room_ms) {
            slowest_room_ms = room_ms;
            slowest_room_channels_ms = 1000.0 * s.channels_seconds;
            slowest_room_vertices = inputs[i].donor->directions.size();
          }
          out_vertices += m.ok() ? m->vertex_count() : 0;
          stage.cut_seconds += s.cut_seconds;
          stage.stitch_seconds += s.stitch_seconds;
          stage.normals_seconds += s.normals_seconds;
          stage.channels_seconds += s.channels_seconds;
        }
      },
      &assemble_cpu_time_ms);

  // The digest, outside the timed runs (hashing every byte costs about half the assembly).
  for (size_t i = 0; i < inputs.size(); ++i) {
    auto m = mesh::assemble_room(ctx, inputs[i], cpu.positions[i], cpu.clearance[i]);
    if (m.ok()) digest.add(*m);
  }

  // The whole cave as a caller builds it (kernels::RoomBuilder: prepare, deform on the device or
  // in the CPU's lanes, assemble) on 1 and 2 threads, plus the layout: the report's "whole cave".
  nlohmann::json whole = nlohmann::json::array();
  spdlog::set_level(spdlog::level::warn);
  // 1 and 2 threads, and every hardware thread where there are more (the CPU stages
  // must use every core).
  std::vector<int> thread_counts = {1, 2};
  if (const int hw = static_cast<int>(std::thread::hardware_concurrency()); hw > 2) {
    thread_counts.push_back(hw);
  }
  // Each sector the region needs, laid out alone on one thread: on many threads the layout takes
  // its slowest sector's time, and build_region builds the interior rooms once the block's own
  // sector is laid out.
  nlohmann::json layout_sectors = nlohmann::json::array();
  {
    const cave::RegionPlan plan = cave::plan_region(world, {0, 0, 0}, {0, 0, 0});
    std::vector<cave::SectorCoord> coords = plan.block;
    coords.insert(coords.end(), plan.outside.begin(), plan.outside.end());
    for (size_t i = 0; i < coords.size(); ++i) {
      int attempts = 0;
      const double ms =
          median_ms(reps, [&] { attempts = cave::generate_sector(world, coords[i]).attempts; });
      layout_sectors.push_back({{"sector", cave::to_string(coords[i])},
                                {"in_block", i < plan.block.size()},
                                {"attempts", attempts},
                                {"ms", ms}});
    }
  }
  // The layout on as many threads (the region's sectors, and those beyond its faces, at once).
  std::map<int, double> layout_threads_ms{{1, layout_ms}};
  for (int threads : thread_counts) {
    if (threads == 1) continue;  // timed above
    layout_threads_ms[threads] = median_ms(reps, [&] {
      (void)cave::generate_region(world, {0, 0, 0}, {0, 0, 0}, threads);
    });
  }
  for (std::string device : {device_choice, std::string("none")}) {
    for (int threads : thread_counts) {
      auto builder = kernels::RoomBuilder::create(
          ctx,
          {kernels::DeviceConfig{.device = device, .profiling = !no_profiling}, threads, channels});
      (void)builder.build(rooms, lod);  // warm-up (PoCL compiles for the work-group size)
      double cpu_ms = 0;
      double ms = median_ms(
          reps, [&] { (void)builder.build(rooms, lod); }, &cpu_ms);
      // The detail channels' launches (on GPUs: RoomBuilder's kAuto), each part per launch.
      // The region's every room (its gates beyond the 100 too) as a pipeline against laying out
      // then building: build_region builds the block's interior rooms while the sectors beyond its
      // faces are laid out.
      const auto [pipeline_ms, staged_ms] = bench::median_ms_alternating(
          reps,
          [&] {
            (void)builder.build_region({0, 0, 0}, {0, 0, 0}, lod);
          },
          [&] {
            const cave::Region r = cave::generate_region(world, {0, 0, 0}, {0, 0, 0}, threads);
            (void)builder.build(r.rooms, lod);
          });
      // The detail channels: computed with the deformation in its launch (the rim vertices' at
      // assembly), or on the CPU's lanes.
      const std::string channel_split =
          builder.channels_on_device() ? "with the deformation" : "cpu";
      whole.push_back({{"device", device.empty() ? std::string("auto") : device},
                       {"path", builder.path()},
                       {"channels", channel_split},
                       {"threads", threads},
                       {"build_ms", ms},
                       {"build_cpu_time_ms", cpu_ms},
                       {"layout_ms", layout_threads_ms[threads]},
                       {"whole_cave_ms", layout_threads_ms[threads] + ms},
                       {"region",
                        {{"rooms", region.rooms.size()},
                         {"pipeline_ms", pipeline_ms},
                         {"layout_then_build_ms", staged_ms}}}});
    }
  }
  spdlog::set_level(spdlog::level::info);

  nlohmann::json report;
  report["seed"] = seed;
  report["rooms"] = rooms.size();
  report["lod"] = lod_name;
  char digest_hex[17];
  std::snprintf(digest_hex, sizeof digest_hex, "%016llx",
                static_cast<unsigned long long>(digest.h));
  report["mesh_digest"] = digest_hex;
  report["donor_vertices"] = donor_vertices;
  report["mesh_vertices"] = out_vertices;
  report["repetitions"] = reps;
  report["stages_ms"] = {{"layout", layout_ms},
                         {"prepare", prepare_ms},
                         {"deform_cpu", deform_cpu_ms},
                         {"fix_triangles", 1000 * stage.cut_seconds},
                         {"stitch", 1000 * stage.stitch_seconds},
                         {"normals", 1000 * stage.normals_seconds},
                         {"channels", 1000 * stage.channels_seconds},
                         {"assemble_total", assemble_ms}};
  double total_cpu = layout_ms + prepare_ms + deform_cpu_ms + assemble_ms;
  report["total_cpu_ms"] = total_cpu;
  report["assemble_cpu_time_ms"] = assemble_cpu_time_ms;
  report["assemble_slowest_room"] = {{"ms", slowest_room_ms},
                                     {"channels_ms", slowest_room_channels_ms},
                                     {"donor_vertices", slowest_room_vertices}};
  report["whole_cave"] = whole;
  report["layout_sectors"] = layout_sectors;
  report["deform_cpu_time_ms"] = deform_cpu_time_ms;

  auto device = kernels::ComputeContext::create(
      kernels::DeviceConfig{.device = device_choice, .profiling = !no_profiling});
  if (!device) {
    spdlog::warn("no OpenCL device: {}", device.error().message);
    report["opencl"] = {{"available", false}, {"reason", device.error().message}};
  } else {
    kernels::ComputeContext& dev = device.value();
    auto kernel_result = kernels::DeformKernel::create(dev, ctx, lanes);
    if (!kernel_result) {
      std::fprintf(stderr, "kernel build failed: %s\n", kernel_result.error().message.c_str());
      return 1;
    }
    kernels::DeformKernel kernel = std::move(kernel_result).value();
    std::vector<kernels::DeformOutput> out;
    (void)kernel.run(inputs, out);  // warm-up: PoCL compiles for the work-group size here
    std::vector<kernels::LaunchStats> runs;
    double deform_cl_cpu_ms = 0;
    double deform_cl_ms = median_ms(
        reps,
        [&] {
          kernels::LaunchStats s;
          (void)kernel.run(inputs, out, &s);
          runs.push_back(s);
        },
        &deform_cl_cpu_ms);
    const kernels::LaunchStats& stats = runs.front();
    // Where the batched launch's time goes, each part the median over the runs above.
    // What one work item does per vertex (grotto_deform_vertex in common/mesh/deform_core.h):
    // loops over its room's n portals (rim noise, collars, the noise fade, the clearance), over the
    // n(n-1)/2 portal pairs in small rooms (two Hermite splines each), and 3D noise evaluations:
    // one rim noise per portal, the surface octaves, the big-room octave (always evaluated), two
    // for a floor. Averaged over the batch's vertices.
    double portals_per_vertex = 0, pairs_per_vertex = 0, noises_per_vertex = 0;
    double big_share = 0, floor_share = 0;
    const mesh::core::GrottoShape& shape = ctx.shape(lod);
    for (const mesh::DeformInput& in : inputs) {
      const double v = static_cast<double>(in.donor->directions.size());
      const double n = static_cast<double>(in.portals.size());
      const bool big = in.record.big_amplitude != 0.0f && shape.keep_distance > 0.0f;
      portals_per_vertex += v * n;
      pairs_per_vertex += big ? 0 : v * n * (n - 1) / 2;
      noises_per_vertex += v * (n + shape.octaves + 1 + (in.record.has_floor ? 2 : 0));
      big_share += big ? v : 0;
      floor_share += in.record.has_floor ? v : 0;
    }
    const double all = static_cast<double>(std::max<size_t>(donor_vertices, 1));
    nlohmann::json work_per_vertex = {{"portals", portals_per_vertex / all},
                                      {"portal_pairs", pairs_per_vertex / all},
                                      {"noise_evaluations", noises_per_vertex / all},
                                      {"surface_octaves", shape.octaves},
                                      {"share_in_big_rooms", big_share / all},
                                      {"share_in_floored_rooms", floor_share / all}};
    using LS = kernels::LaunchStats;
    nlohmann::json deform_split = {
        {"profiled", dev.profiling()},
        {"run_ms", deform_cl_ms},
        {"prepare_ms", median_of(runs, &LS::prepare_ms)},
        {"allocate_ms", median_of(runs, &LS::allocate_ms)},
        {"upload_ms", median_of(runs, &LS::upload_ms)},
        {"kernel_ms", median_of(runs, &LS::kernel_ms)},
        {"download_ms", median_of(runs, &LS::download_ms)},
        {"device_span_ms", median_of(runs, &LS::device_span_ms)},
        {"queue_wall_ms", median_of(runs, &LS::queue_wall_ms)},
        {"unpack_ms", median_of(runs, &LS::unpack_ms)},
        {"upload_bytes", stats.upload_bytes},
        {"download_bytes", stats.download_bytes},
        {"launches", stats.launches},
        {"vertices", stats.vertices},
        {"lanes", kernel.lanes()},
        {"work_group_size", stats.local_size},
        {"global_size", stats.global_size},
        {"work_groups", stats.local_size ? stats.global_size / stats.local_size : 0},
        {"work_per_vertex", work_per_vertex},
        {"kernel_info",
         {{"max_work_group_size", kernel.info().max_work_group_size},
          {"preferred_work_group_multiple", kernel.info().preferred_multiple},
          {"private_mem_bytes", kernel.info().private_mem_bytes},
          {"local_mem_bytes", kernel.info().local_mem_bytes}}}};

    // Figure 3-11: time per launch against buffer size.
    nlohmann::json sizes = nlohmann::json::array();
    for (size_t k : {1, 2, 5, 10, 25, 50, 100, 200}) {
      if (k > inputs.size()) break;
      std::span<const mesh::DeformInput> part(inputs.data(), k);
      size_t verts = 0;
      for (auto& in : part)
        verts += in.donor->directions.size();
      double ms = median_ms(reps, [&] { (void)kernel.run(part, out); });
      double cpu_ms = median_ms(reps, [&] {
        for (auto& in : part) {
          std::vector<mesh::core::float3> p(in.donor->directions.size());
          std::vector<float> c(p.size());
          mesh::deform_cpu(ctx, in, p, c);
        }
      });
      sizes.push_back({{"rooms", k},
                       {"vertices", verts},
                       {"opencl_ms", ms},
                       {"cpu_ms", cpu_ms},
                       {"opencl_vertices_per_s", verts / (ms / 1000)},
                       {"cpu_vertices_per_s", verts / (cpu_ms / 1000)}});
    }
    // §4.2.1: one launch per room against one launch for all.
    double single_ms = median_ms(reps, [&] {
      for (size_t i = 0; i < inputs.size(); ++i) {
        (void)kernel.run(std::span<const mesh::DeformInput>(inputs.data() + i, 1), out);
      }
    });
    // The fixed cost: a launch of the smallest room.
    size_t smallest = 0;
    for (size_t i = 0; i < inputs.size(); ++i) {
      if (inputs[i].donor->directions.size() < inputs[smallest].donor->directions.size()) {
        smallest = i;
      }
    }
    double tiny_ms = median_ms(std::max(reps, 20), [&] {
      (void)kernel.run(std::span<const mesh::DeformInput>(inputs.data() + smallest, 1), out);
    });
    // The same launch computing every vertex's detail channels too (one lane; RoomBuilder's on
    // devices that are not CPUs): what the channels add to the launch, beside what they cost the
    // CPU (stages_ms.channels).
    nlohmann::json with_channels = "unavailable";
    if (auto created = kernels::DeformKernel::create(dev, ctx, 0, 0, true); created) {
      kernels::DeformKernel fused = std::move(created).value();
      (void)fused.run(inputs, out);  // warm-up
      std::vector<kernels::LaunchStats> fused_runs;
      const double ms = median_ms(reps, [&] {
        kernels::LaunchStats s;
        (void)fused.run(inputs, out, &s);
        fused_runs.push_back(s);
      });
      with_channels = {{"run_ms", ms},
                       {"upload_ms", median_of(fused_runs, &LS::upload_ms)},
                       {"kernel_ms", median_of(fused_runs, &LS::kernel_ms)},
                       {"download_ms", median_of(fused_runs, &LS::download_ms)},
                       {"unpack_ms", median_of(fused_runs, &LS::unpack_ms)},
                       {"download_bytes", fused_runs.front().download_bytes}};
    } else {
      with_channels = created.error().message;
    }
    double total_cl = layout_ms + prepare_ms + deform_cl_ms + assemble_ms;
    report["opencl"] = {
        {"available", true},
        {"device", dev.describe()},
        {"deform_ms", deform_cl_ms},
        {"launches_per_run", stats.launches},
        // Per stage on the device, the one batched launch of every room.
        {"device_stages", {{"deform", deform_split}, {"deform_with_channels", with_channels}}},
        {"lanes", kernel.lanes()},
        {"deform_speedup_vs_cpu", deform_cpu_ms / deform_cl_ms},
        // CPU time of all of PoCL's threads: the work per core, whatever else
        // the machine runs (a 2-core device can be at most 2x this ratio's wall).
        {"deform_cpu_time_ms", deform_cl_cpu_ms},
        {"deform_work_ratio_vs_cpu", deform_cpu_time_ms / deform_cl_cpu_ms},
        {"total_ms", total_cl},
        {"total_vs_thesis_cpp_9s", 9000.0 / total_cl},
        {"buffer_sizes", sizes},
        {"one_launch_per_room_ms", single_ms},
        {"one_batched_launch_ms", deform_cl_ms},
        {"smallest_room_launch_ms", tiny_ms},
        {"smallest_room_vertices", inputs[smallest].donor->directions.size()}};
  }

  std::printf(
      "100-room cave (%zu rooms, %s level, %zu donor vertices, %zu mesh vertices, mesh digest "
      "%s), median of %d\n",
      rooms.size(), lod_name.c_str(), donor_vertices, out_vertices, digest_hex, reps);
  std::printf("%-26s %10s\n", "stage", "ms");
  for (auto& [k, v] : report["stages_ms"].items())
    std::printf("%-26s %10.1f\n", k.c_str(), v.get<double>());
  std::printf("%-26s %10.1f\n", "total (CPU, 1 thread)", total_cpu);
  std::printf("%-26s %10.1f\n", "assemble CPU time", assemble_cpu_time_ms);
  std::printf(
      "%-26s %10.1f  (%zu donor vertices; its channels %.1f, which several threads share: the "
      "rest is the floor of a build on many threads)\n",
      "slowest room's assembly", slowest_room_ms, slowest_room_vertices, slowest_room_channels_ms);
  std::printf("the region's sectors laid out alone, one thread (ms):");
  for (const auto& l : layout_sectors) {
    std::printf(" %s%s %.1f (%d attempt%s)", l["sector"].get<std::string>().c_str(),
                l["in_block"].get<bool>() ? " [block]" : "", l["ms"].get<double>(),
                l["attempts"].get<int>(), l["attempts"].get<int>() == 1 ? "" : "s");
  }
  std::printf("\n");
  std::printf(
      "whole cave through RoomBuilder (layout + build), wall and the process's CPU time:\n");
  for (auto& w : whole) {
    std::printf(
        "  %-6s %d thread(s) %10.1f ms (layout %.1f ms, build %.1f ms, CPU time %.1f ms)  %s\n",
        w["device"].get<std::string>().c_str(), w["threads"].get<int>(),
        w["whole_cave_ms"].get<double>(), w["layout_ms"].get<double>(), w["build_ms"].get<double>(),
        w["build_cpu_time_ms"].get<double>(), w["path"].get<std::string>().c_str());
    std::printf(
        "         the region's %zu rooms: %.1f ms as a pipeline (build_region), %.1f ms laid out "
        "then built\n",
        w["region"]["rooms"].get<size_t>(), w["region"]["pipeline_ms"].get<double>(),
        w["region"]["layout_then_build_ms"].get<double>());
    std::printf("         detail channels: %s\n", w["channels"].get<std::string>().c_str());
  }
  if (report["opencl"]["available"]) {
    auto& cl = report["opencl"];
    std::printf("%-26s %10.1f  (%.1fx the CPU; %d lanes)\n", "deform (OpenCL)",
                cl["deform_ms"].get<double>(), cl["deform_speedup_vs_cpu"].get<double>(),
                cl["lanes"].get<int>());
    std::printf("%-26s %10.1f  (%.1fx less CPU time than the reference)\n",
                "deform (OpenCL) CPU time", cl["deform_cpu_time_ms"].get<double>(),
                cl["deform_work_ratio_vs_cpu"].get<double>());
    std::printf("%-26s %10.1f  (thesis C++: 9000 ms, %.0fx faster)\n", "total (OpenCL)",
                cl["total_ms"].get<double>(), cl["total_vs_thesis_cpp_9s"].get<double>());
    auto& split = cl["device_stages"]["deform"];
    std::printf(
        "deform split (ms, median): prepare %.2f  allocate %.2f  upload %.2f  kernel %.2f  "
        "download %.2f  unpack %.2f  | device span %.2f  queue wall %.2f%s\n",
        split["prepare_ms"].get<double>(), split["allocate_ms"].get<double>(),
        split["upload_ms"].get<double>(), split["kernel_ms"].get<double>(),
        split["download_ms"].get<double>(), split["unpack_ms"].get<double>(),
        split["device_span_ms"].get<double>(), split["queue_wall_ms"].get<double>(),
        split["profiled"].get<bool>() ? "" : "  (queue not profiled: device parts 0)");
    if (const auto& f = cl["device_stages"]["deform_with_channels"]; f.is_object()) {
      std::printf(
          "deform with the detail channels, one lane (ms, median): %.2f (upload %.2f  kernel %.2f  "
          "download %.2f  unpack %.2f)\n",
          f["run_ms"].get<double>(), f["upload_ms"].get<double>(), f["kernel_ms"].get<double>(),
          f["download_ms"].get<double>(), f["unpack_ms"].get<double>());
    }
    std::printf("deform NDRange: %zu work items in groups of %zu, %d vertices each\n",
                split["global_size"].get<size_t>(), split["work_group_size"].get<size_t>(),
                split["lanes"].get<int>());
    auto& info = split["kernel_info"];
    std::printf(
        "deform kernel: max work-group %zu, preferred multiple %zu, private %llu B per item, "
        "local %llu B per group\n",
        info["max_work_group_size"].get<size_t>(),
        info["preferred_work_group_multiple"].get<size_t>(),
        static_cast<unsigned long long>(info["private_mem_bytes"].get<uint64_t>()),
        static_cast<unsigned long long>(info["local_mem_bytes"].get<uint64_t>()));
    auto& work = split["work_per_vertex"];
    std::printf(
        "per vertex (mean): %.2f portals, %.2f portal pairs, %.2f noise evaluations; %.0f %% of "
        "vertices in big rooms, %.0f %% on floors\n",
        work["portals"].get<double>(), work["portal_pairs"].get<double>(),
        work["noise_evaluations"].get<double>(), 100 * work["share_in_big_rooms"].get<double>(),
        100 * work["share_in_floored_rooms"].get<double>());
    std::printf("%-26s %10.1f\n", "100 single-room launches",
                cl["one_launch_per_room_ms"].get<double>());
    std::printf("%-26s %10.2f  (%zu vertices)\n", "smallest-room launch",
                cl["smallest_room_launch_ms"].get<double>(),
                cl["smallest_room_vertices"].get<size_t>());
    std::printf("%8s %10s %12s %12s %14s %14s\n", "rooms", "vertices", "opencl ms", "cpu ms",
                "opencl vert/s", "cpu vert/s");
    for (auto& s : cl["buffer_sizes"]) {
      std::printf("%8zu %10zu %12.2f %12.2f %14.3g %14.3g\n", s["rooms"].get<size_t>(),
                  s["vertices"].get<size_t>(), s["opencl_ms"].get<double>(),
                  s["cpu_ms"].get<double>(), s["opencl_vertices_per_s"].get<double>(),
                  s["cpu_vertices_per_s"].get<double>());
    }
  }
  std::ofstream(json_path) << report.dump(2) << "\n";
  return 0;
}
