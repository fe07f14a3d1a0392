// Layout generation rate: sectors/s and rooms/s.
// Command and results: docs/BENCHMARKS.md.
#include <benchmark/benchmark.h>

#include "common/cave/layout.hpp"

namespace grotto::cave {
namespace {

World bench_world() {
  return World::create(42, LayoutParams{}).value();
}

// One sector with its gates: the unit of work a server does for a cold room.
void BM_GenerateSector(benchmark::State& state) {
  World world = bench_world();
  int32_t i = 0;
  size_t rooms = 0;
  for (auto _ : state) {
    SectorLayout layout = generate_sector(world, {i % 16, (i / 16) % 16, i / 256});
    rooms += layout.rooms.size() + layout.gates.size();
    benchmark::DoNotOptimize(layout);
    ++i;
  }
  state.counters["sectors_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["rooms_per_s"] =
      benchmark::Counter(static_cast<double>(rooms), benchmark::Counter::kIsRate);
  state.counters["rooms_per_sector"] =
      static_cast<double>(rooms) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_GenerateSector)->Unit(benchmark::kMicrosecond);

// A single room by id with no cache: an interior room costs one sector, a gate two.
void BM_RoomById(benchmark::State& state) {
  World world = bench_world();
  RoomId id = state.range(0) ? RoomId::gate({0, 0, 0}, 0, 0) : RoomId::interior({0, 0, 0}, 5);
  for (auto _ : state)
    benchmark::DoNotOptimize(room(world, id));
  state.SetLabel(id.is_gate() ? "gate" : "interior");
}
BENCHMARK(BM_RoomById)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// A 4x4x4 block with all gates merged: what the connectivity test and the tool do.
void BM_Region4x4x4(benchmark::State& state) {
  World world = bench_world();
  size_t rooms = 0;
  for (auto _ : state) {
    Region region = generate_region(world, {0, 0, 0}, {3, 3, 3});
    rooms += region.rooms.size();
    benchmark::DoNotOptimize(region);
  }
  state.counters["rooms_per_s"] =
      benchmark::Counter(static_cast<double>(rooms), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_Region4x4x4)->Unit(benchmark::kMillisecond);

void BM_Locate(benchmark::State& state) {
  World world = bench_world();
  Vec3 p = room(world, spawn_room(world)).value().sphere.centre;
  for (auto _ : state)
    benchmark::DoNotOptimize(locate(world, p));
}
BENCHMARK(BM_Locate)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace grotto::cave

// Google Benchmark's main, but an unknown flag exits 2 as in every Grotto binary (its --help: 0).
int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 2;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
