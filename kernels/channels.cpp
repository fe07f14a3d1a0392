#include "kernels/channels.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>

#include "embedded_cl/channels.hpp"
#include "embedded_cl/deform_core.hpp"
#include "embedded_cl/deform_prelude.hpp"
#include "mesh/context.hpp"

namespace grotto::kernels {
namespace {

using Clock = std::chrono::steady_clock;

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

constexpr size_t kPreferredGroupSize = 128;

}  // namespace

std::string channels_source() {
  std::string s(source_deform_prelude());
  s += source_deform_core();
  s += source_channels();
  return s;
}

Result<ChannelsKernel> ChannelsKernel::create(ComputeContext& ctx) {
  std::string extensions;
  GROTTO_CL_TRY(ctx.device().getInfo(CL_DEVICE_EXTENSIONS, &extensions));
  if (extensions.find("cl_khr_fp64") == std::string::npos) {
    return Error{ErrorCode::kUnavailable,
                 "the device has no double precision (cl_khr_fp64), which the detail channels' "
                 "world positions need"};
  }
  // The period as the C++ code has it, to the last bit (a power of two: exact in decimal).
  char period[64];
  std::snprintf(period, sizeof period, "%.1f", mesh::kNoisePeriod);
  auto program = build_program(
      ctx, channels_source(),
      std::string(kDeterministicOptions) + " -DGROTTO_LANES=1 -DGROTTO_NOISE_PERIOD=" + period);
  if (!program) return program.error();
  auto kernel = program->kernel("grotto_detail_channels");
  if (!kernel) return kernel.error();
  size_t max_group = 0;
  GROTTO_CL_TRY(kernel->getWorkGroupInfo(ctx.device(), CL_KERNEL_WORK_GROUP_SIZE, &max_group));
  return ChannelsKernel(ctx, std::move(kernel).value(), program->origin(),
                        std::clamp<size_t>(max_group, 1, kPreferredGroupSize));
}

ChannelsKernel::ChannelsKernel(ComputeContext& ctx, cl::Kernel kernel, BuildOrigin origin,
                               size_t local_size)
    : ctx_(&ctx), kernel_(std::move(kernel)), origin_(origin), local_size_(local_size) {}

Status ChannelsKernel::run(std::span<mesh::RoomMesh* const> meshes, std::span<const uint32_t> seeds,
                           const mesh::MeshParams& params, LaunchStats* stats) {
  if (meshes.size() != seeds.size()) return invalid_argument("channels: one seed per mesh");
  const Clock::time_point t_prepare = Clock::now();
  // The room table: each room's origin, first vertex and world; empty rooms left out.
  host_origins_.clear();
  host_firsts_.clear();
  host_seeds_.clear();
  size_t vertices = 0;
  for (size_t i = 0; i < meshes.size(); ++i) {
    const mesh::RoomMesh& m = *meshes[i];
    if (m.positions.empty()) continue;
    host_origins_.insert(host_origins_.end(), {m.origin.x, m.origin.y, m.origin.z});
    host_firsts_.push_back(static_cast<uint32_t>(vertices));
    host_seeds_.push_back(seeds[i]);
    vertices += m.positions.size();
  }
  if (vertices == 0) return {};
  if (vertices > UINT32_MAX) return invalid_argument("channels: over 2^32 vertices in one run");

  const Clock::time_point t_allocate = Clock::now();
  if (Status s = host_positions_.reserve(*ctx_, 3 * vertices * sizeof(float)); !s) return s;
  if (Status s = host_roughness_.reserve(*ctx_, vertices * sizeof(float)); !s) return s;
  if (Status s = host_mineral_.reserve(*ctx_, vertices * sizeof(float)); !s) return s;
  const size_t rooms = host_seeds_.size();
  auto origin_buf = origins_.reserve(*ctx_, host_origins_.size() * sizeof(double));
  auto first_buf = firsts_.reserve(*ctx_, rooms * sizeof(uint32_t));
  auto seed_buf = seeds_.reserve(*ctx_, rooms * sizeof(uint32_t));
  auto pos_buf = positions_.reserve(*ctx_, 3 * vertices * sizeof(float));
  auto rough_buf = roughness_.reserve(*ctx_, vertices * sizeof(float));
  auto mineral_buf = mineral_.reserve(*ctx_, vertices * sizeof(float));
  for (auto* b : {&origin_buf, &first_buf, &seed_buf, &pos_buf, &rough_buf, &mineral_buf}) {
    if (!*b) return b->error();
  }
  // The positions gathered into pinned memory, the upload's source.
  const Clock::time_point t_gather = Clock::now();
  auto* positions = static_cast<float*>(host_positions_.data());
  for (mesh::RoomMesh* m : meshes) {
    static_assert(sizeof(mesh::core::float3) == 3 * sizeof(float));
    std::memcpy(positions, m->positions.data(), m->positions.size() * sizeof(mesh::core::float3));
    positions += 3 * m->positions.size();
  }
  if (Status s = set_kernel_args(kernel_, **origin_buf, **first_buf, **seed_buf,
                                 static_cast<cl_uint>(rooms), **pos_buf, **rough_buf, **mineral_buf,
                                 static_cast<cl_uint>(vertices),
                                 static_cast<float>(params.roughness_frequency),
                                 static_cast<float>(3 * params.roughness_frequency),
                                 static_cast<float>(params.mineral_frequency));
      !s) {
    return s;
  }
  auto* roughness = static_cast<float*>(host_roughness_.data());
  auto* mineral = static_cast<float*>(host_mineral_.data());
  const Clock::time_point t_queue = Clock::now();
  const size_t global = (vertices + local_size_ - 1) / local_size_ * local_size_;
  cl::Event writes[4], run, reads[2];
  auto enqueue = [&]() -> Status {
    if (Status s = enqueue_write(*ctx_, **origin_buf, host_origins_.data(), host_origins_.size(),
                                 &writes[0]);
        !s) {
      return s;
    }
    if (Status s = enqueue_write(*ctx_, **first_buf, host_firsts_.data(), rooms, &writes[1]); !s) {
      return s;
    }
    if (Status s = enqueue_write(*ctx_, **seed_buf, host_seeds_.data(), rooms, &writes[2]); !s) {
      return s;
    }
    if (Status s =
            enqueue_write(*ctx_, **pos_buf, static_cast<const float*>(host_positions_.data()),
                          3 * vertices, &writes[3]);
        !s) {
      return s;
    }
    GROTTO_CL_TRY(ctx_->queue().enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(global),
                                                     cl::NDRange(local_size_), nullptr, &run));
    if (Status s = read_buffer(*ctx_, **rough_buf, roughness, vertices, false, &reads[0]); !s) {
      return s;
    }
    return read_buffer(*ctx_, **mineral_buf, mineral, vertices, true, &reads[1]);
  };
  if (Status s = enqueue(); !s) {
    // Commands already queued may still read or write the memory above: let them end first.
    ctx_->queue().finish();
    return s;
  }
  const Clock::time_point t_unpack = Clock::now();
  for (mesh::RoomMesh* m : meshes) {
    const size_t n = m->positions.size();
    m->roughness.assign(roughness, roughness + n);
    m->mineral.assign(mineral, mineral + n);
    roughness += n;
    mineral += n;
  }
  if (stats) {
    ++stats->launches;
    stats->rooms += rooms;
    stats->vertices += vertices;
    // The gather into pinned memory is the host's flattening, as the deformation's tables are.
    stats->prepare_ms += ms_between(t_prepare, t_allocate) + ms_between(t_gather, t_queue);
    stats->allocate_ms += ms_between(t_allocate, t_gather);
    stats->queue_wall_ms += ms_between(t_queue, t_unpack);
    stats->unpack_ms += ms_between(t_unpack, Clock::now());
    add_device_times(*stats, writes, run, reads);
    stats->upload_bytes += host_origins_.size() * sizeof(double) + 2 * rooms * sizeof(uint32_t) +
                           3 * vertices * sizeof(float);
    stats->download_bytes += 2 * vertices * sizeof(float);
    stats->global_size = global;
    stats->local_size = local_size_;
  }
  return {};
}

}  // namespace grotto::kernels
