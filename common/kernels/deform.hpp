// The room deformation on an OpenCL device (thesis §4.2): common/kernels/deform.cl compiled with
// the shared core common/mesh/deform_core.h, many rooms per launch (§4.2.1). Its results are
// bit-identical to mesh::deform_cpu.
#pragma once

#include <map>
#include <optional>
#include <span>
#include <vector>

#include "common/core/result.hpp"
#include "common/kernels/cl_context.hpp"
#include "common/mesh/room_mesh.hpp"

namespace grotto::kernels {

// One room's deformation output, a position and a clearance per donor vertex, and with a kernel
// that computes them (DeformKernel::channels()) each donor vertex's detail channels: views of the
// kernel's host memory, where the device's results land (nothing is copied per room on a GPU),
// valid until the kernel's next run() or its end. Copy what must outlive that.
struct DeformOutput {
  std::span<const mesh::core::float3> positions;
  std::span<const float> clearance;
  std::span<const float> roughness, mineral;  // empty without channels
};

// What run() did, for benchmarks and metrics; every field adds up over the runs given the same
// stats (except the last launch's NDRange shape). Times are milliseconds. The device's three are
// the queue's event profiles (CL_PROFILING_COMMAND_START to _END of each command): how long the
// device spent on the commands, without the host's enqueue or wait; they stay 0 when the queue
// does not profile (ComputeContext::profiling()). The host's parts are the calling thread's
// steady clock.
struct LaunchStats {
  size_t launches = 0;
  size_t rooms = 0;
  size_t vertices = 0;
  // Host: flattening the batch into the kernel's layout (room and portal tables, each group's
  // room and donor group; a donor's directions de-interleaved into lanes the first time it comes).
  double prepare_ms = 0;
  // Host: growing the launch's buffers and the (pinned) host memory the outputs are read into,
  // where this batch needs more than an earlier one (they are kept from launch to launch).
  double allocate_ms = 0;
  // Device: the input writes (two, three with channels, and a new donor's directions), the
  // kernel, the output reads (two, four with channels; sums of their durations).
  double upload_ms = 0;
  double kernel_ms = 0;
  double download_ms = 0;
  // Device: from the first write's start to the last read's end; minus the three above, the
  // device's idle gaps between the commands.
  double device_span_ms = 0;
  // Host: from enqueueing the first write to the last read's return; minus device_span_ms, the
  // driver's cost of enqueueing, staging host memory and signalling completion.
  double queue_wall_ms = 0;
  // Host: the positions copied out of lanes into vertices (lanes of 8, the CPU device's layout)
  // and each room's views set; with one lane the views point at the downloaded memory as it is.
  double unpack_ms = 0;
  size_t upload_bytes = 0;
  size_t download_bytes = 0;
  // The last launch's NDRange: work items (whole work-groups, the padding idle) and group size;
  // each work item deforms lanes() vertices of one room.
  size_t global_size = 0;
  size_t local_size = 0;
};

// Adds `more` to `stats` field by field (the NDRange shape: `more`'s, the later launch's).
void accumulate(LaunchStats& stats, const LaunchStats& more);

// Adds one launch's device times to `stats` (0 without profiling): its input writes' and output
// reads' durations, the kernel's, and the span from the first write to the last read. The host's
// parts and the byte counts stay the caller's.
void add_device_times(LaunchStats& stats, std::span<const cl::Event> writes,
                      const cl::Event& kernel, std::span<const cl::Event> reads);

// What the driver says about the built kernel on its device (clGetKernelWorkGroupInfo), for
// reasoning about occupancy: the largest work-group it can run (on GPUs lower than the device's
// limit when each work item needs many registers), the work-group multiple it prefers (the SIMD
// width: 32 on NVIDIA), and its memory per work item (private: registers spilled and arrays the
// compiler could not keep in registers; NVIDIA's "local memory") and per group (__local).
struct KernelInfo {
  size_t max_work_group_size = 0;
  size_t preferred_multiple = 0;
  uint64_t private_mem_bytes = 0;
  uint64_t local_mem_bytes = 0;
};

// Where the detail channels of rooms deformed on a device are computed: with the deformation, in
// its launch (one vertex a work item), or on the CPU's SIMD lanes after assembly. kAuto: with the
// deformation on devices that are not CPUs (PoCL runs the deformation in lanes of 8, and its
// one-vertex-per-item channels were no faster than the CPU's lanes: docs/BENCHMARKS.md).
enum class ChannelsOn { kAuto, kDevice, kHost };

// The built kernel plus the level-of-detail shapes (mesh parameters) on one device. The world
// comes with each room (its record's noise_seed), so one kernel, and one launch, serves every
// world whose mesh parameters it was built with. Not thread-safe: use one per thread (the
// ComputeContext may be shared).
class DeformKernel {
 public:
  // Builds (or loads from the caches) the program. Errors carry the build log. `lanes` is how many
  // vertices one work item deforms, 1 or 8; 0 picks by device: 8 on CPU devices (PoCL does not
  // vectorize the kernel across work items, so it runs in float8 registers), 1 elsewhere.
  // `max_constant_bytes` caps the constant memory a launch's tables may use (0: the device's
  // limit); a smaller cap splits batches into more launches (tests: every launch's results in
  // their own part of the host memory). With `channels` every work item also computes its
  // vertex's detail channels (the per-vertex stages on the device, in the same launch);
  // that needs one lane (0 picks it) and double precision (cl_khr_fp64: the world position is
  // wrapped into the noise period in doubles, as on the CPU), else the kernel is not built.
  static Result<DeformKernel> create(ComputeContext& ctx, const mesh::MeshContext& mesh_ctx,
                                     int lanes = 0, size_t max_constant_bytes = 0,
                                     bool channels = false);

  // Deforms every room of `batch`; outputs[i] receives room i's result (views, valid until the
  // next run). Rooms go to the device in as few launches as its constant memory allows (usually
  // one), whatever their worlds.
  Status run(std::span<const mesh::DeformInput> batch, std::vector<DeformOutput>& outputs,
             LaunchStats* stats = nullptr);
  // The same for rooms gathered from several batches (SharedDeform's launches).
  Status run(std::span<const mesh::DeformInput* const> batch, std::vector<DeformOutput>& outputs,
             LaunchStats* stats = nullptr);

  // create() with the detail channels where `where` puts them on this device. A device that
  // cannot compute them (no double precision, or their program fails to build) gets the kernel
  // without them, with a logged warning (event=channels_path path=cpu).
  static Result<DeformKernel> create_for(ComputeContext& ctx, const mesh::MeshContext& mesh_ctx,
                                         ChannelsOn where);

  BuildOrigin build_origin() const { return origin_; }
  int lanes() const { return lanes_; }
  bool channels() const { return channels_; }
  const KernelInfo& info() const { return info_; }

 private:
  DeformKernel(ComputeContext& ctx, cl::Kernel kernel, cl::Buffer shapes, size_t max_constant_bytes,
               BuildOrigin origin, int lanes, bool channels);
  // Deforms `rooms` into the host memory from slot `slot_base` (and, with lanes of 8, the
  // unpacked vertices from `vertex_base`) on: the run's earlier launches keep theirs.
  Status launch(std::span<const mesh::DeformInput* const> rooms, std::span<DeformOutput> outputs,
                size_t slot_base, size_t vertex_base, LaunchStats* stats);

  static constexpr size_t kPreferredGroupSize = 128;

  // Resident donor directions (a launch uploads a batch's compact inputs, not what the device
  // already holds): every donor sphere a launch has used, by (frequency, vertex count), as groups
  // of lanes_ directions in donor_directions_ (the host's copy) and donor_buffer_ (the device's,
  // rewritten whole when a new donor joins: a few times in a process's life). first_groups[i]
  // receives rooms[i]'s donor's first group there.
  Status upload_donors(std::span<const mesh::DeformInput* const> rooms,
                       std::vector<uint32_t>& first_groups, LaunchStats* stats);

  ComputeContext* ctx_;
  cl::Kernel kernel_;
  std::map<std::pair<int, size_t>, uint32_t> donor_first_group_;
  std::vector<float> donor_directions_;
  std::optional<cl::Buffer> donor_buffer_;
  // A launch's buffers, kept for the next one.
  GrowingBuffer rooms_{CL_MEM_READ_ONLY}, portals_{CL_MEM_READ_ONLY};
  GrowingBuffer positions_{CL_MEM_WRITE_ONLY}, clearance_{CL_MEM_WRITE_ONLY};
  // With channels: six doubles a room (mesh origin, channel frequencies) up, two floats a vertex
  // down.
  GrowingBuffer room_channels_{CL_MEM_READ_ONLY};
  GrowingBuffer roughness_{CL_MEM_WRITE_ONLY}, mineral_{CL_MEM_WRITE_ONLY};
  std::vector<mesh::core::GrottoRoom> host_rooms_;
  std::vector<mesh::core::GrottoPortal> host_portals_;
  std::vector<double> host_room_channels_;
  // What the device's results are read into (positions x y z per slot, a clearance per slot, and
  // the channels); with lanes of 8 the positions are then unpacked into unpacked_. The rooms'
  // views point into these.
  PinnedHost host_positions_, host_clearance_, host_roughness_, host_mineral_;
  std::vector<mesh::core::float3> unpacked_;
  size_t local_size_ = 1;
  cl::Buffer shapes_;
  size_t max_constant_bytes_;
  BuildOrigin origin_;
  int lanes_;
  bool channels_;
  KernelInfo info_;
};

// The source the kernel is built from: prelude + shared core (+ the channels' core) + kernel
// (GROTTO_LANES, GROTTO_CHANNELS and GROTTO_NOISE_PERIOD come with the build options).
std::string deform_source(bool channels = false);

}  // namespace grotto::kernels
