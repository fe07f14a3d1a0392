#include "common/kernels/deform.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>

#include "common/mesh/context.hpp"
#include "embedded_cl/channels_core.hpp"
#include "embedded_cl/deform.hpp"
#include "embedded_cl/deform_core.hpp"
#include "embedded_cl/deform_prelude.hpp"

namespace grotto::kernels {

using mesh::core::GrottoPortal;
using mesh::core::GrottoRoom;
using mesh::core::GrottoShape;

namespace {

using Clock = std::chrono::steady_clock;

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// grotto_deform_rooms' arguments after its eight (deform.cl) when it computes the channels: the
// room table, roughness and mineral.
constexpr cl_uint kFirstChannelArg = 8;

}  // namespace

void accumulate(LaunchStats& stats, const LaunchStats& more) {
  stats.launches += more.launches;
  stats.rooms += more.rooms;
  stats.vertices += more.vertices;
  stats.prepare_ms += more.prepare_ms;
  stats.allocate_ms += more.allocate_ms;
  stats.upload_ms += more.upload_ms;
  stats.kernel_ms += more.kernel_ms;
  stats.download_ms += more.download_ms;
  stats.device_span_ms += more.device_span_ms;
  stats.queue_wall_ms += more.queue_wall_ms;
  stats.unpack_ms += more.unpack_ms;
  stats.upload_bytes += more.upload_bytes;
  stats.download_bytes += more.download_bytes;
  if (more.launches > 0) {
    stats.global_size = more.global_size;
    stats.local_size = more.local_size;
  }
}

void add_device_times(LaunchStats& stats, std::span<const cl::Event> writes,
                      const cl::Event& kernel, std::span<const cl::Event> reads) {
  for (const cl::Event& e : writes)
    stats.upload_ms += event_ms(e);
  stats.kernel_ms += event_ms(kernel);
  for (const cl::Event& e : reads)
    stats.download_ms += event_ms(e);
  stats.device_span_ms += event_span_ms(writes.front(), reads.back());
}

std::string deform_source(bool channels) {
  std::string s(source_deform_prelude());
  s += source_deform_core();
  if (channels) s += source_channels_core();
  s += source_deform();
  return s;
}

Result<DeformKernel> DeformKernel::create(ComputeContext& ctx, const mesh::MeshContext& mesh_ctx,
                                          int lanes, size_t max_constant_bytes, bool channels) {
  if (lanes == 0) lanes = ctx.info().device_type == "cpu" && !channels ? 8 : 1;
  if (lanes != 1 && lanes != 8) {
    return invalid_argument("deformation lanes must be 0 (auto), 1 or 8, not " +
                            std::to_string(lanes));
  }
  std::string options =
      std::string(kDeterministicOptions) + " -DGROTTO_LANES=" + std::to_string(lanes);
  if (channels) {
    if (lanes != 1)
      return invalid_argument("the detail channels need one lane, not " + std::to_string(lanes));
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
    options += std::string(" -DGROTTO_CHANNELS=1 -DGROTTO_NOISE_PERIOD=") + period;
  }
  auto program = build_program(ctx, deform_source(channels), options);
  if (!program) return program.error();
  auto kernel = program->kernel("grotto_deform_rooms");
  if (!kernel) return kernel.error();
  GrottoShape shapes[mesh::kLodCount] = {mesh_ctx.shape(mesh::Lod::kDetail),
                                         mesh_ctx.shape(mesh::Lod::kPatch)};
  auto shape_buffer = make_buffer(ctx, CL_MEM_READ_ONLY, shapes, mesh::kLodCount);
  if (!shape_buffer) return shape_buffer.error();
  cl_ulong max_constant = 0;
  GROTTO_CL_TRY(ctx.device().getInfo(CL_DEVICE_MAX_CONSTANT_BUFFER_SIZE, &max_constant));
  if (max_constant_bytes > 0) max_constant = std::min<cl_ulong>(max_constant, max_constant_bytes);
  size_t max_group = 0;
  GROTTO_CL_TRY(kernel->getWorkGroupInfo(ctx.device(), CL_KERNEL_WORK_GROUP_SIZE, &max_group));
  DeformKernel k(ctx, std::move(kernel).value(), std::move(shape_buffer).value(),
                 static_cast<size_t>(max_constant), program->origin(), lanes, channels);
  k.local_size_ = std::clamp<size_t>(max_group, 1, kPreferredGroupSize);
  // For reports only: a query the driver does not answer leaves its field 0.
  k.info_.max_work_group_size = max_group;
  const cl::Kernel& built = k.kernel_;
  built.getWorkGroupInfo(ctx.device(), CL_KERNEL_PREFERRED_WORK_GROUP_SIZE_MULTIPLE,
                         &k.info_.preferred_multiple);
  cl_ulong bytes = 0;
  if (built.getWorkGroupInfo(ctx.device(), CL_KERNEL_PRIVATE_MEM_SIZE, &bytes) == CL_SUCCESS) {
    k.info_.private_mem_bytes = bytes;
  }
  if (built.getWorkGroupInfo(ctx.device(), CL_KERNEL_LOCAL_MEM_SIZE, &bytes) == CL_SUCCESS) {
    k.info_.local_mem_bytes = bytes;
  }
  return k;
}

Result<DeformKernel> DeformKernel::create_for(ComputeContext& ctx,
                                              const mesh::MeshContext& mesh_ctx, ChannelsOn where) {
  const bool channels = where == ChannelsOn::kDevice ||
                        (where == ChannelsOn::kAuto && ctx.info().device_type != "cpu");
  if (!channels) return create(ctx, mesh_ctx);
  auto kernel = create(ctx, mesh_ctx, 0, 0, true);
  if (kernel) return kernel;
  // No double precision, or the channels' program failed to build: the deformation alone.
  spdlog::warn("event=channels_path path=cpu device=\"{}\" error=\"{}\"", ctx.info().device_name,
               kernel.error().message);
  return create(ctx, mesh_ctx);
}

DeformKernel::DeformKernel(ComputeContext& ctx, cl::Kernel kernel, cl::Buffer shapes,
                           size_t max_constant_bytes, BuildOrigin origin, int lanes, bool channels)
    : ctx_(&ctx),
      kernel_(std::move(kernel)),
      shapes_(std::move(shapes)),
      max_constant_bytes_(max_constant_bytes),
      origin_(origin),
      lanes_(lanes),
      channels_(channels) {}

Status DeformKernel::run(std::span<const mesh::DeformInput> batch,
                         std::vector<DeformOutput>& outputs, LaunchStats* stats) {
  std::vector<const mesh::DeformInput*> rooms(batch.size());
  for (size_t i = 0; i < batch.size(); ++i)
    rooms[i] = &batch[i];
  return run(std::span<const mesh::DeformInput* const>(rooms), outputs, stats);
}

Status DeformKernel::run(std::span<const mesh::DeformInput* const> batch,
                         std::vector<DeformOutput>& outputs, LaunchStats* stats) {
  outputs.assign(batch.size(), {});
  // The whole run's host memory first: every launch's views stay valid to the end of the run.
  const Clock::time_point t_allocate = Clock::now();
  const size_t lanes = static_cast<size_t>(lanes_);
  size_t slots = 0, vertices = 0;
  for (const mesh::DeformInput* room : batch) {
    const size_t n = room->donor->directions.size();
    slots += (n + lanes - 1) / lanes * lanes;
    vertices += n;
  }
  const size_t padded = std::max<size_t>(slots, 1);  // no zero-size buffers
  if (Status s = host_positions_.reserve(*ctx_, 3 * padded * sizeof(float)); !s) return s;
  if (Status s = host_clearance_.reserve(*ctx_, padded * sizeof(float)); !s) return s;
  if (channels_) {
    if (Status s = host_roughness_.reserve(*ctx_, padded * sizeof(float)); !s) return s;
    if (Status s = host_mineral_.reserve(*ctx_, padded * sizeof(float)); !s) return s;
  }
  if (lanes > 1 && unpacked_.size() < vertices) {
    unpacked_.resize(std::max(vertices, unpacked_.size() + unpacked_.size() / 2));
  }
  if (stats) stats->allocate_ms += ms_between(t_allocate, Clock::now());
  // Split where the room or portal table would outgrow the device's constant memory.
  size_t begin = 0, slot_base = 0, vertex_base = 0;
  while (begin < batch.size()) {
    size_t end = begin, portals = 0;
    while (end < batch.size()) {
      size_t next_portals = portals + batch[end]->portals.size();
      size_t rooms_bytes = (end - begin + 1) * sizeof(GrottoRoom);
      if (end > begin && (rooms_bytes > max_constant_bytes_ / 2 ||
                          next_portals * sizeof(GrottoPortal) > max_constant_bytes_ / 2)) {
        break;
      }
      portals = next_portals;
      ++end;
    }
    if (Status s =
            launch(batch.subspan(begin, end - begin),
                   std::span(outputs).subspan(begin, end - begin), slot_base, vertex_base, stats);
        !s) {
      return s;
    }
    for (size_t i = begin; i < end; ++i) {
      const size_t n = batch[i]->donor->directions.size();
      slot_base += (n + lanes - 1) / lanes * lanes;
      vertex_base += n;
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

Status DeformKernel::upload_donors(std::span<const mesh::DeformInput* const> rooms,
                                   std::vector<uint32_t>& first_groups, LaunchStats* stats) {
  const size_t lanes = static_cast<size_t>(lanes_);
  bool grown = false;
  first_groups.clear();
  for (const mesh::DeformInput* room : rooms) {
    const auto& dirs = room->donor->directions;
    const uint32_t next = static_cast<uint32_t>(donor_directions_.size() / (3 * lanes));
    const auto [it, fresh] =
        donor_first_group_.try_emplace({room->donor->frequency, dirs.size()}, next);
    first_groups.push_back(it->second);
    if (!fresh) continue;
    grown = true;
    // Groups of `lanes` directions, x[lanes] y[lanes] z[lanes]; the last padded with copies of the
    // donor's last direction.
    for (size_t first = 0; first < dirs.size(); first += lanes) {
      for (int axis = 0; axis < 3; ++axis) {
        for (size_t l = 0; l < lanes; ++l) {
          const auto& d = dirs[std::min(first + l, dirs.size() - 1)];
          donor_directions_.push_back(axis == 0 ? d.x : axis == 1 ? d.y : d.z);
        }
      }
    }
  }
  if (!grown) return {};
  auto buffer = make_buffer<float>(*ctx_, CL_MEM_READ_ONLY, donor_directions_.size());
  if (!buffer) return buffer.error();
  cl::Event write;
  if (Status s =
          enqueue_write(*ctx_, *buffer, donor_directions_.data(), donor_directions_.size(), &write);
      !s) {
    ctx_->queue().finish();
    return s;
  }
  // Waited for: the host copy grows in a later launch, and a launch that fails after this point
  // returns without draining the queue.
  GROTTO_CL_TRY(write.wait());
  donor_buffer_ = std::move(buffer).value();
  if (stats) {
    stats->upload_bytes += donor_directions_.size() * sizeof(float);
    stats->upload_ms += event_ms(write);
  }
  return {};
}

Status DeformKernel::launch(std::span<const mesh::DeformInput* const> rooms,
                            std::span<DeformOutput> outputs, size_t slot_base, size_t vertex_base,
                            LaunchStats* stats) {
  const Clock::time_point t_prepare = Clock::now();
  // The batch as groups of `lanes_` vertices of one room (a room's last group padded, as the
  // donor's groups are). The rooms' tables are all that goes up: a work item finds its room by its
  // first vertex (thesis §4.2.1's obstacle: "each room must reference different portal data") and
  // its directions from the room's place among the resident donor directions.
  const size_t lanes = static_cast<size_t>(lanes_);
  std::vector<uint32_t> first_dirs;  // per room: its donor's first group on the device
  if (Status s = upload_donors(rooms, first_dirs, stats); !s) return s;
  std::vector<GrottoRoom>& records = host_rooms_;
  std::vector<GrottoPortal>& portals = host_portals_;
  std::vector<double>& room_channels = host_room_channels_;
  records.clear();
  portals.clear();
  room_channels.clear();
  size_t groups = 0;
  for (size_t r = 0; r < rooms.size(); ++r) {
    GrottoRoom rec = rooms[r]->record;
    rec.first_portal = static_cast<uint32_t>(portals.size());
    rec.first_vertex = static_cast<uint32_t>(groups * lanes);
    rec.first_direction = first_dirs[r];
    records.push_back(rec);
    portals.insert(portals.end(), rooms[r]->portals.begin(), rooms[r]->portals.end());
    groups += (rooms[r]->donor->directions.size() + lanes - 1) / lanes;
    if (channels_) {
      const Vec3 o = rooms[r]->origin;
      const auto& f = rooms[r]->channel_frequencies;
      room_channels.insert(room_channels.end(), {o.x, o.y, o.z, f[0], f[1], f[2]});
    }
  }
  if (groups == 0) return {};
  const size_t slots = groups * lanes;
  if (portals.empty()) portals.push_back({});  // no zero-size buffers; never read

  // The inputs go up by explicit writes rather than CL_MEM_COPY_HOST_PTR, so the queue's events
  // time the copies apart from the kernel (to show where a launch's time goes).
  const Clock::time_point t_allocate = Clock::now();
  auto room_buf = rooms_.reserve(*ctx_, records.size() * sizeof(GrottoRoom));
  auto portal_buf = portals_.reserve(*ctx_, portals.size() * sizeof(GrottoPortal));
  auto pos_buf = positions_.reserve(*ctx_, 3 * slots * sizeof(float));
  auto clear_buf = clearance_.reserve(*ctx_, slots * sizeof(float));
  for (auto* b : {&room_buf, &portal_buf, &pos_buf, &clear_buf}) {
    if (!*b) return b->error();
  }
  if (Status s = set_kernel_args(kernel_, shapes_, **room_buf, static_cast<cl_uint>(records.size()),
                                 **portal_buf, *donor_buffer_, **pos_buf, **clear_buf,
                                 static_cast<cl_uint>(groups));
      !s) {
    return s;
  }
  const cl::Buffer* channel_bufs[3] = {};  // room table, roughness, mineral
  if (channels_) {
    auto table = room_channels_.reserve(*ctx_, room_channels.size() * sizeof(double));
    auto rough = roughness_.reserve(*ctx_, slots * sizeof(float));
    auto mineral = mineral_.reserve(*ctx_, slots * sizeof(float));
    for (auto* b : {&table, &rough, &mineral}) {
      if (!*b) return b->error();
    }
    channel_bufs[0] = *table;
    channel_bufs[1] = *rough;
    channel_bufs[2] = *mineral;
    for (cl_uint i = 0; i < 3; ++i)
      GROTTO_CL_TRY(kernel_.setArg(kFirstChannelArg + i, *channel_bufs[i]));
  }
  // This launch's place in the run's host memory (run() sized it for the whole run).
  float* const positions = static_cast<float*>(host_positions_.data()) + 3 * slot_base;
  float* const clearance = static_cast<float*>(host_clearance_.data()) + slot_base;
  float* const roughness =
      channels_ ? static_cast<float*>(host_roughness_.data()) + slot_base : nullptr;
  float* const mineral =
      channels_ ? static_cast<float*>(host_mineral_.data()) + slot_base : nullptr;
  const Clock::time_point t_queue = Clock::now();
  // Non-blocking writes and first read: the memory outlives the blocking last read, which the
  // in-order queue completes after everything before it. Explicit work-groups (the kernel ignores
  // the padding): on PoCL's CPU device the driver's own choice was slower than fixed groups
  // (docs/BENCHMARKS.md).
  const size_t global = (groups + local_size_ - 1) / local_size_ * local_size_;
  // In queue order (the span's first write and last read).
  const size_t write_count = channels_ ? 3 : 2, read_count = channels_ ? 4 : 2;
  cl::Event writes[3], run, reads[4];
  auto enqueue = [&]() -> Status {
    if (Status s = enqueue_write(*ctx_, **room_buf, records.data(), records.size(), &writes[0]);
        !s) {
      return s;
    }
    if (Status s = enqueue_write(*ctx_, **portal_buf, portals.data(), portals.size(), &writes[1]);
        !s) {
      return s;
    }
    if (channels_) {
      if (Status s = enqueue_write(*ctx_, *channel_bufs[0], room_channels.data(),
                                   room_channels.size(), &writes[2]);
          !s) {
        return s;
      }
    }
    GROTTO_CL_TRY(ctx_->queue().enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(global),
                                                     cl::NDRange(local_size_), nullptr, &run));
    if (Status s = read_buffer(*ctx_, **pos_buf, positions, 3 * slots, false, &reads[0]); !s) {
      return s;
    }
    if (channels_) {
      if (Status s = read_buffer(*ctx_, *channel_bufs[1], roughness, slots, false, &reads[1]); !s) {
        return s;
      }
      if (Status s = read_buffer(*ctx_, *channel_bufs[2], mineral, slots, false, &reads[2]); !s) {
        return s;
      }
    }
    // The last read blocks: the in-order queue has completed every command before it.
    return read_buffer(*ctx_, **clear_buf, clearance, slots, true, &reads[read_count - 1]);
  };
  if (Status s = enqueue(); !s) {
    // Commands already queued may still read or write the vectors above: let them end first.
    ctx_->queue().finish();
    return s;
  }
  const Clock::time_point t_unpack = Clock::now();
  mesh::core::float3* vertex = unpacked_.data() + vertex_base;
  for (size_t r = 0; r < rooms.size(); ++r) {
    const size_t first = records[r].first_vertex, count = rooms[r]->donor->directions.size();
    outputs[r].clearance = std::span<const float>(clearance + first, count);
    if (channels_) {
      outputs[r].roughness = std::span<const float>(roughness + first, count);
      outputs[r].mineral = std::span<const float>(mineral + first, count);
    }
    const float* group = positions + 3 * first;
    if (lanes == 1) {  // x y z x y z ...: the vertices as they are, read where they landed
      static_assert(sizeof(mesh::core::float3) == 3 * sizeof(float));
      outputs[r].positions = std::span(reinterpret_cast<const mesh::core::float3*>(group), count);
      continue;
    }
    // A room's vertices start a group (first_vertex is a multiple of lanes): group by group, each
    // x[lanes] y[lanes] z[lanes] into vertices.
    outputs[r].positions = std::span<const mesh::core::float3>(vertex, count);
    for (size_t v = 0; v < count; v += lanes, group += 3 * lanes) {
      const size_t n = std::min(lanes, count - v);
      for (size_t l = 0; l < n; ++l)
        *vertex++ = {group[l], group[lanes + l], group[2 * lanes + l]};
    }
  }
  if (stats) {
    stats->prepare_ms += ms_between(t_prepare, t_allocate);
    stats->allocate_ms += ms_between(t_allocate, t_queue);
    stats->queue_wall_ms += ms_between(t_queue, t_unpack);
    stats->unpack_ms += ms_between(t_unpack, Clock::now());
    add_device_times(*stats, std::span(writes, write_count), run, std::span(reads, read_count));
    stats->upload_bytes += records.size() * sizeof(GrottoRoom) +
                           portals.size() * sizeof(GrottoPortal) +
                           room_channels.size() * sizeof(double);
    stats->download_bytes += (channels_ ? 6 : 4) * slots * sizeof(float);
    stats->global_size = global;
    stats->local_size = local_size_;
  }
  return {};
}

}  // namespace grotto::kernels
