#include "kernels/room_builder.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cstring>
#include <numeric>
#include <thread>

#include "core/parallel.hpp"

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
  auto ctx = ComputeContext::create(options.device);
  if (!ctx) {
    b.path_ = "cpu: " + ctx.error().message;
    // Asked for (--device none) is not worth a warning, once per builder; a failure is.
    spdlog::log(options.device.device == "none" ? spdlog::level::info : spdlog::level::warn,
                "event=compute_path path=cpu reason=\"{}\"", ctx.error().message);
    return b;
  }
  b.device_ = std::make_unique<ComputeContext>(std::move(ctx).value());
  auto kernel = DeformKernel::create(*b.device_, mesh_ctx);
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
  spdlog::info("event=compute_path path=opencl {} program={}", b.device_->describe(),
               build_origin_name(b.kernel_->build_origin()));
  return b;
}

std::vector<Result<mesh::RoomMesh>> RoomBuilder::build(std::span<const cave::Room> rooms,
                                                       mesh::Lod lod) {
  std::vector<const mesh::MeshContext*> worlds(rooms.size(), mesh_ctx_);
  return build(worlds, rooms, lod);
}

bool RoomBuilder::serves(const mesh::MeshContext& world) const {
  // The kernel holds the shapes of the builder's parameters (DeformKernel::create).
  for (int l = 0; l < mesh::kLodCount; ++l) {
    auto lod = static_cast<mesh::Lod>(l);
    if (std::memcmp(&world.shape(lod), &mesh_ctx_->shape(lod), sizeof(world.shape(lod))) != 0) {
      return false;
    }
  }
  return true;
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
  if (kernel_) {
    Status s = kernel_->run(inputs, outputs, &launches_);
    on_device = s.ok();
    if (!s) {
      ++fallbacks_;
      spdlog::warn("event=deform_fallback rooms={} error=\"{}\"", inputs.size(), s.error().message);
    }
  }
  // On the CPU, each room's deformation in its own vectors (the device's are views of its memory).
  std::vector<std::vector<mesh::core::float3>> cpu_positions(on_device ? 0 : inputs.size());
  std::vector<std::vector<float>> cpu_clearance(on_device ? 0 : inputs.size());
  // Rooms are independent: each index writes its own output and mesh slot. Largest first: with
  // whole rooms as the unit of work, a hall taken last would finish alone while the other
  // threads wait (issue 30: the whole cave on every core).
  std::vector<size_t> order(inputs.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return inputs[a].donor->directions.size() > inputs[b].donor->directions.size();
  });
  for_each_index(inputs.size(), threads_, [&](size_t i) {
    const size_t k = order[i];
    const mesh::MeshContext& world = *worlds[slots[k]];
    if (!on_device) {
      size_t n = inputs[k].donor->directions.size();
      cpu_positions[k].resize(n);
      cpu_clearance[k].resize(n);
      mesh::deform_cpu(world, inputs[k], cpu_positions[k], cpu_clearance[k]);
      meshes[slots[k]] = mesh::assemble_room(world, inputs[k], cpu_positions[k], cpu_clearance[k]);
      return;
    }
    meshes[slots[k]] =
        mesh::assemble_room(world, inputs[k], outputs[k].positions, outputs[k].clearance);
  });
  return meshes;
}

}  // namespace grotto::kernels
