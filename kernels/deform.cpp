#include "kernels/deform.hpp"

#include <algorithm>

#include "embedded_cl/deform.hpp"
#include "embedded_cl/deform_core.hpp"
#include "embedded_cl/deform_prelude.hpp"

namespace grotto::kernels {

using mesh::core::GrottoPortal;
using mesh::core::GrottoRoom;
using mesh::core::GrottoShape;

std::string deform_source() {
  std::string s(source_deform_prelude());
  s += source_deform_core();
  s += source_deform();
  return s;
}

Result<DeformKernel> DeformKernel::create(ComputeContext& ctx, const mesh::MeshContext& mesh_ctx) {
  auto program = build_program(ctx, deform_source(), kDeterministicOptions);
  if (!program) return program.error();
  auto kernel = program->kernel("grotto_deform_rooms");
  if (!kernel) return kernel.error();
  auto perm = make_buffer(ctx, CL_MEM_READ_ONLY, mesh_ctx.perm(), 512);
  if (!perm) return perm.error();
  GrottoShape shapes[mesh::kLodCount] = {mesh_ctx.shape(mesh::Lod::kDetail),
                                         mesh_ctx.shape(mesh::Lod::kPatch)};
  auto shape_buffer = make_buffer(ctx, CL_MEM_READ_ONLY, shapes, mesh::kLodCount);
  if (!shape_buffer) return shape_buffer.error();
  cl_ulong max_constant = 0;
  GROTTO_CL_TRY(ctx.device().getInfo(CL_DEVICE_MAX_CONSTANT_BUFFER_SIZE, &max_constant));
  size_t max_group = 0;
  GROTTO_CL_TRY(kernel->getWorkGroupInfo(ctx.device(), CL_KERNEL_WORK_GROUP_SIZE, &max_group));
  DeformKernel k(ctx, std::move(kernel).value(), std::move(perm).value(),
                 std::move(shape_buffer).value(), static_cast<size_t>(max_constant),
                 program->origin());
  k.local_size_ = std::clamp<size_t>(max_group, 1, kPreferredGroupSize);
  return k;
}

DeformKernel::DeformKernel(ComputeContext& ctx, cl::Kernel kernel, cl::Buffer perm,
                           cl::Buffer shapes, size_t max_constant_bytes, BuildOrigin origin)
    : ctx_(&ctx),
      kernel_(std::move(kernel)),
      perm_(std::move(perm)),
      shapes_(std::move(shapes)),
      max_constant_bytes_(max_constant_bytes),
      origin_(origin) {}

Status DeformKernel::run(std::span<const mesh::DeformInput> batch,
                         std::vector<DeformOutput>& outputs, LaunchStats* stats) {
  outputs.assign(batch.size(), {});
  // Split where the room or portal table would outgrow the device's constant memory.
  size_t begin = 0;
  while (begin < batch.size()) {
    size_t end = begin, portals = 0;
    while (end < batch.size()) {
      size_t next_portals = portals + batch[end].portals.size();
      size_t rooms_bytes = (end - begin + 1) * sizeof(GrottoRoom);
      if (end > begin && (rooms_bytes > max_constant_bytes_ / 2 ||
                          next_portals * sizeof(GrottoPortal) > max_constant_bytes_ / 2)) {
        break;
      }
      portals = next_portals;
      ++end;
    }
    if (Status s = launch(batch.subspan(begin, end - begin),
                          std::span(outputs).subspan(begin, end - begin));
        !s) {
      return s;
    }
    if (stats) {
      ++stats->launches;
      stats->rooms += end - begin;
      for (size_t i = begin; i < end; ++i)
        stats->vertices += outputs[i].positions.size();
    }
    begin = end;
  }
  return {};
}

Status DeformKernel::launch(std::span<const mesh::DeformInput> rooms,
                            std::span<DeformOutput> outputs) {
  // Flatten the batch: every vertex carries its room's index (thesis §4.2.1's obstacle: "each
  // room must reference different portal data").
  std::vector<GrottoRoom> records;
  std::vector<GrottoPortal> portals;
  std::vector<uint32_t> vertex_room;
  std::vector<float> directions;
  for (size_t r = 0; r < rooms.size(); ++r) {
    GrottoRoom rec = rooms[r].record;
    rec.first_portal = static_cast<uint32_t>(portals.size());
    rec.first_vertex = static_cast<uint32_t>(vertex_room.size());
    records.push_back(rec);
    portals.insert(portals.end(), rooms[r].portals.begin(), rooms[r].portals.end());
    for (const auto& d : rooms[r].donor->directions) {
      vertex_room.push_back(static_cast<uint32_t>(r));
      directions.insert(directions.end(), {d.x, d.y, d.z});
    }
  }
  const size_t n = vertex_room.size();
  if (n == 0) return {};
  if (portals.empty()) portals.push_back({});  // no zero-size buffers; never read
  auto room_buf = make_buffer(*ctx_, CL_MEM_READ_ONLY, records.data(), records.size());
  auto portal_buf = make_buffer(*ctx_, CL_MEM_READ_ONLY, portals.data(), portals.size());
  auto index_buf = make_buffer(*ctx_, CL_MEM_READ_ONLY, vertex_room.data(), n);
  auto dir_buf = make_buffer(*ctx_, CL_MEM_READ_ONLY, directions.data(), directions.size());
  auto pos_buf = make_buffer<float>(*ctx_, CL_MEM_WRITE_ONLY, 3 * n);
  auto clear_buf = make_buffer<float>(*ctx_, CL_MEM_WRITE_ONLY, n);
  for (auto* b : {&room_buf, &portal_buf, &index_buf, &dir_buf, &pos_buf, &clear_buf}) {
    if (!*b) return b->error();
  }
  if (Status s = set_kernel_args(kernel_, perm_, shapes_, *room_buf, *portal_buf, *index_buf,
                                 *dir_buf, *pos_buf, *clear_buf, static_cast<cl_uint>(n));
      !s) {
    return s;
  }
  // Explicit work-groups of up to 128 items (the kernel ignores the padding): on PoCL's CPU device
  // the driver's own choice ran 1.5-1.7x the CPU reference and 128 ran 2.0x (docs/BENCHMARKS.md).
  size_t global = (n + local_size_ - 1) / local_size_ * local_size_;
  GROTTO_CL_TRY(ctx_->queue().enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(global),
                                                   cl::NDRange(local_size_)));
  std::vector<float> positions(3 * n), clearance(n);
  if (Status s = read_buffer(*ctx_, *pos_buf, positions.data(), positions.size()); !s) return s;
  if (Status s = read_buffer(*ctx_, *clear_buf, clearance.data(), n); !s) return s;
  for (size_t r = 0; r < rooms.size(); ++r) {
    size_t first = records[r].first_vertex, count = rooms[r].donor->directions.size();
    DeformOutput& out = outputs[r];
    out.positions.resize(count);
    out.clearance.assign(clearance.begin() + first, clearance.begin() + first + count);
    for (size_t v = 0; v < count; ++v) {
      out.positions[v] = {positions[3 * (first + v)], positions[3 * (first + v) + 1],
                          positions[3 * (first + v) + 2]};
    }
  }
  return {};
}

}  // namespace grotto::kernels
