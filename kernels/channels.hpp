// The detail channels on an OpenCL device (issue 30, item 2: the per-vertex stages that are data
// parallel move to the device): kernels/channels.cl over the finished meshes of a whole batch of
// rooms, of any worlds, in one launch. Its results are bit-identical to mesh::detail_channels.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/result.hpp"
#include "kernels/cl_context.hpp"
#include "kernels/deform.hpp"
#include "mesh/params.hpp"
#include "mesh/room_mesh.hpp"

namespace grotto::kernels {

// The built kernel on one device. Not thread-safe: use one per thread (the ComputeContext may be
// shared).
class ChannelsKernel {
 public:
  // Builds (or loads from the caches) the program. Fails on a device without double precision
  // (cl_khr_fp64: the world position is wrapped into the noise period in doubles, as on the CPU).
  static Result<ChannelsKernel> create(ComputeContext& ctx);

  // Fills meshes[i]'s roughness and mineral, one value per vertex, from its positions and origin
  // with world seeds[i]'s noise and `params`' frequencies (one set for the batch: a RoomBuilder's).
  // Sizes agree; a mesh without vertices is skipped. On error the meshes' channels are unchanged
  // or empty, never partly filled with garbage: the caller computes them on the CPU instead.
  Status run(std::span<mesh::RoomMesh* const> meshes, std::span<const uint32_t> seeds,
             const mesh::MeshParams& params, LaunchStats* stats = nullptr);

  BuildOrigin build_origin() const { return origin_; }

 private:
  ChannelsKernel(ComputeContext& ctx, cl::Kernel kernel, BuildOrigin origin, size_t local_size);

  ComputeContext* ctx_;
  cl::Kernel kernel_;
  BuildOrigin origin_;
  size_t local_size_;
  // A launch's buffers and host memory, kept for the next one.
  GrowingBuffer origins_{CL_MEM_READ_ONLY}, firsts_{CL_MEM_READ_ONLY}, seeds_{CL_MEM_READ_ONLY};
  GrowingBuffer positions_{CL_MEM_READ_ONLY};
  GrowingBuffer roughness_{CL_MEM_WRITE_ONLY}, mineral_{CL_MEM_WRITE_ONLY};
  std::vector<double> host_origins_;
  std::vector<uint32_t> host_firsts_, host_seeds_;
  // The positions gathered for the upload and the two channels read back, in pinned memory.
  PinnedHost host_positions_, host_roughness_, host_mineral_;
};

// The source the kernel is built from: prelude + shared core + kernel.
std::string channels_source();

}  // namespace grotto::kernels
