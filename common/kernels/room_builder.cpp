#include "common/kernels/room_builder.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <condition_variable>
#include <mutex>
#include <numeric>
#include <thread>

#include "common/core/parallel.hpp"

namespace grotto::kernels {

RoomBuilder::RoomBuilder(const mesh::MeshContext& mesh_ctx) : mesh_ctx_(&mesh_ctx) {}
RoomBuilder::RoomBuilder(RoomBuilder&&) noexcept = default;
RoomBuilder& RoomBuilder::operator=(RoomBuilder&&) noexcept = default;
RoomBuilder::~RoomBuilder() = default;

RoomBuilder RoomBuilder::create(const mesh::MeshContext& mesh_ctx, const Options& options) {
  RoomBuilder b(mesh_ctx);
  b.threads_ = options.threads > 0
                   ? options.threads
                   : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (options.shared_device) {
    if (!options.shared_device->serves(mesh_ctx)) {
      b.path_ = "cpu: the shared device's kernel has other mesh parameters";
      spdlog::warn("event=compute_path path=cpu reason=\"{}\"", b.path_.substr(5));
      return b;
    }
    b.shared_ = options.shared_device;
    b.path_ = "opencl: " + b.shared_->device().describe() +
              " shared=true channels=" + (b.shared_->channels() ? "device" : "cpu");
    return b;
  }
  auto ctx = ComputeContext::create(options.device);
  if (!ctx) {
    b.path_ = "cpu: " + ctx.error().message;
    // Asked for (--device none) is not worth a warning, once per builder; a failure is.
    spdlog::log(options.device.device == "none" ? spdlog::level::info : spdlog::level::warn,
                "event=compute_path path=cpu reason=\"{}\"", ctx.error().message);
    return b;
  }
  b.device_ = std::make_unique<ComputeContext>(std::move(ctx).value());
  auto kernel = DeformKernel::create_for(*b.device_, mesh_ctx, options.channels);
  if (!kernel) {
    b.path_ = "cpu: deformation kernel failed to build: " + kernel.error().message;
    spdlog::warn(
        "event=compute_path path=cpu reason=kernel_build_failed device=\"{}\" error=\"{}\"",
        b.device_->info().device_name, kernel.error().message);
    b.device_.reset();
    return b;
  }
  b.kernel_.emplace(std::move(kernel).value());
  b.path_ = "opencl: " + b.device_->describe();
  spdlog::info("event=compute_path path=opencl {} program={} channels={}", b.device_->describe(),
               build_origin_name(b.kernel_->build_origin()),
               b.kernel_->channels() ? "device" : "cpu");
  return b;
}

bool RoomBuilder::channels_on_device() const {
  return shared_ ? shared_->channels() : kernel_ && kernel_->channels();
}

std::vector<Result<mesh::RoomMesh>> RoomBuilder::build(std::span<const cave::Room> rooms,
                                                       mesh::Lod lod) {
  std::vector<const mesh::MeshContext*> worlds(rooms.size(), mesh_ctx_);
  return build(worlds, rooms, lod);
}

RoomBuilder::BuiltRegion RoomBuilder::build_region(cave::SectorCoord lo, cave::SectorCoord hi,
                                                   mesh::Lod lod) {
  const cave::World& world = mesh_ctx_->world();
  if (threads_ <= 2) {
    // Two threads stay busy through the layout (seed 42's cave: seven sectors, 8 ms, the slowest
    // 3), so there is nothing for the pipeline to fill, and its second build cost 1-2 ms.
    BuiltRegion out{cave::generate_region(world, lo, hi, threads_), {}};
    out.meshes = build(out.region.rooms, lod);
    return out;
  }
  const cave::RegionPlan plan = cave::plan_region(world, lo, hi);
  std::vector<cave::SectorCoord> coords = plan.block;
  coords.insert(coords.end(), plan.outside.begin(), plan.outside.end());
  std::vector<cave::SectorLayout> layouts(coords.size());
  // Layout threads take the sectors in order, the block's first; the caller waits for the
  // block's, then builds its interior rooms while they lay out the rest (the build's threads and
  // the last layout threads share the cores for those few milliseconds).
  std::atomic<size_t> next{0};
  std::mutex mutex;
  std::condition_variable block_done;
  size_t block_left = plan.block.size();
  auto lay_out = [&] {
    for (size_t i = next++; i < coords.size(); i = next++) {
      layouts[i] = cave::generate_sector(world, coords[i]);
      if (i >= plan.block.size()) continue;
      std::lock_guard lock(mutex);
      if (--block_left == 0) block_done.notify_one();
    }
  };
  std::vector<std::jthread> pool;  // joined when cleared, or on the way out
  for (size_t t = 0; t < std::min(static_cast<size_t>(threads_), coords.size()); ++t)
    pool.emplace_back(lay_out);
  {
    std::unique_lock lock(mutex);
    block_done.wait(lock, [&] { return block_left == 0; });
  }
  std::vector<cave::Room> interior;
  for (size_t i = 0; i < plan.block.size(); ++i)
    interior.insert(interior.end(), layouts[i].rooms.begin(), layouts[i].rooms.end());
  std::vector<Result<mesh::RoomMesh>> interior_meshes = build(interior, lod);
  pool.clear();

  BuiltRegion out{cave::assemble_region(plan, std::move(layouts)), {}};
  std::vector<cave::Room> gates;
  for (const cave::Room& r : out.region.rooms) {
    if (r.id.is_gate()) gates.push_back(r);
  }
  std::vector<Result<mesh::RoomMesh>> gate_meshes = build(gates, lod);
  // The region's rooms are sorted by id, which orders by sector first: its interior rooms come
  // in `interior`'s order (the block's sectors x-major, each's rooms by index), its gates in the
  // order taken above.
  out.meshes.reserve(out.region.rooms.size());
  size_t next_gate = 0, next_interior = 0;
  for (const cave::Room& r : out.region.rooms) {
    if (r.id.is_gate()) {
      out.meshes.push_back(std::move(gate_meshes[next_gate++]));
    } else if (next_interior < interior.size() && interior[next_interior].id == r.id) {
      out.meshes.push_back(std::move(interior_meshes[next_interior++]));
    } else {  // the order above no longer holds: a defect, said rather than a wrong mesh
      out.meshes.push_back(Error{ErrorCode::kInternal, "room " + r.id.to_string() +
                                                           ": not in the block's interior order"});
    }
  }
  return out;
}

bool RoomBuilder::serves(const mesh::MeshContext& world) const {
  // The kernel holds the shapes of the builder's parameters (DeformKernel::create).
  return same_mesh_shapes(world, *mesh_ctx_);
}

std::vector<Result<mesh::RoomMesh>> RoomBuilder::build(
    std::span<const mesh::MeshContext* const> worlds, std::span<const cave::Room> rooms,
    mesh::Lod lod) {
  assert(worlds.size() == rooms.size());
  std::vector<Result<mesh::RoomMesh>> meshes(
      rooms.size(), invalid_argument("the world's mesh parameters differ from the builder's"));
  std::vector<mesh::DeformInput> inputs;
  std::vector<size_t> slots;  // inputs[k] is rooms[slots[k]]
  inputs.reserve(rooms.size());
  for (size_t i = 0; i < rooms.size(); ++i) {
    if (!serves(*worlds[i])) continue;
    inputs.push_back(mesh::prepare_room(*worlds[i], rooms[i], lod));
    slots.push_back(i);
  }
  if (inputs.empty()) return meshes;

  std::vector<DeformOutput> outputs;
  bool on_device = false;
  if (kernel_ || shared_) {
    Status s =
        shared_ ? shared_->run(inputs, shared_results_) : kernel_->run(inputs, outputs, &launches_);
    if (shared_ && s) outputs = shared_results_.outputs;
    on_device = s.ok();
    if (!s) {
      ++fallbacks_;
      spdlog::warn("event=deform_fallback rooms={} error=\"{}\"", inputs.size(), s.error().message);
    }
  }
  // The donor vertices' detail channels came with the deformation where the device computes
  // them (assembly adds the rim vertices'). Else, on several threads, the channels on the CPU run
  // after every room is assembled, in pieces any thread takes: inside assembly a big room's (a
  // hall's: ~40 % of its assembly) held its thread long after the others had finished.
  const bool channels_with_deformation = on_device && channels_on_device();
  const bool channels_in_pieces = !channels_with_deformation && threads_ > 1;
  const mesh::ChannelsBy channels =
      channels_in_pieces ? mesh::ChannelsBy::kCaller : mesh::ChannelsBy::kAssemble;
  // Rooms are independent: each index writes its own output and mesh slot. Largest first: with
  // whole rooms as the unit of work, a hall taken last would finish alone while the other
  // threads wait.
  std::vector<size_t> order(inputs.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return inputs[a].donor->directions.size() > inputs[b].donor->directions.size();
  });
  for_each_index(inputs.size(), threads_, [&](size_t i) {
    const size_t k = order[i];
    const mesh::MeshContext& world = *worlds[slots[k]];
    if (!on_device) {  // the room's deformation on this thread, for its assembly alone
      const size_t n = inputs[k].donor->directions.size();
      std::vector<mesh::core::float3> positions(n);
      std::vector<float> clearance(n);
      mesh::deform_cpu(world, inputs[k], positions, clearance);
      meshes[slots[k]] =
          mesh::assemble_room(world, inputs[k], positions, clearance, nullptr, channels);
      return;
    }
    meshes[slots[k]] =
        mesh::assemble_room(world, inputs[k], outputs[k].positions, outputs[k].clearance, nullptr,
                            channels, {outputs[k].roughness, outputs[k].mineral});
  });
  if (channels_in_pieces) fill_channels_on_threads(worlds, slots, meshes);
  return meshes;
}

void RoomBuilder::fill_channels_on_threads(std::span<const mesh::MeshContext* const> worlds,
                                           std::span<const size_t> slots,
                                           std::vector<Result<mesh::RoomMesh>>& meshes) {
  // Pieces of a few thousand vertices: small beside a hall's 40,000, big beside a thread's start.
  constexpr size_t kPiece = 4096;
  struct Piece {
    const mesh::MeshContext* world;
    mesh::RoomMesh* mesh;
    size_t first, count;
  };
  std::vector<Piece> pieces;
  for (size_t slot : slots) {
    if (!meshes[slot].ok()) continue;
    mesh::RoomMesh& m = meshes[slot].value();
    const size_t n = m.positions.size();
    m.roughness.resize(n);
    m.mineral.resize(n);
    for (size_t first = 0; first < n; first += kPiece)
      pieces.push_back({worlds[slot], &m, first, std::min(kPiece, n - first)});
  }
  // Each vertex's channels are its own (lanes give every vertex the scalar reference's bits), so
  // the pieces give the whole room's.
  for_each_index(pieces.size(), threads_, [&](size_t i) {
    const Piece& p = pieces[i];
    mesh::detail_channels(*p.world, p.mesh->origin,
                          std::span(p.mesh->positions).subspan(p.first, p.count),
                          std::span(p.mesh->roughness).subspan(p.first, p.count),
                          std::span(p.mesh->mineral).subspan(p.first, p.count));
  });
}

}  // namespace grotto::kernels
