// The room deformation on an OpenCL device (thesis §4.2): kernels/deform.cl compiled with the
// shared core common/mesh/deform_core.h, many rooms per launch (§4.2.1). Its results are
// bit-identical to mesh::deform_cpu.
#pragma once

#include <span>
#include <vector>

#include "core/result.hpp"
#include "kernels/cl_context.hpp"
#include "mesh/room_mesh.hpp"

namespace grotto::kernels {

// One room's deformation output: a position and a clearance per donor vertex.
struct DeformOutput {
  std::vector<mesh::core::float3> positions;
  std::vector<float> clearance;
};

// What one run() did, for benchmarks and metrics.
struct LaunchStats {
  size_t launches = 0;
  size_t rooms = 0;
  size_t vertices = 0;
};

// The built kernel plus the level-of-detail shapes (mesh parameters) on one device. The world
// comes with each room (its record's noise_seed), so one kernel, and one launch, serves every
// world whose mesh parameters it was built with. Not thread-safe: use one per thread (the
// ComputeContext may be shared).
class DeformKernel {
 public:
  // Builds (or loads from the caches) the program. Errors carry the build log. `lanes` is how many
  // vertices one work item deforms, 1 or 8; 0 picks by device: 8 on CPU devices (PoCL does not
  // vectorize the kernel across work items, so it runs in float8 registers), 1 elsewhere.
  static Result<DeformKernel> create(ComputeContext& ctx, const mesh::MeshContext& mesh_ctx,
                                     int lanes = 0);

  // Deforms every room of `batch`; outputs[i] receives room i's result. Rooms go to the device in
  // as few launches as its constant memory allows (usually one), whatever their worlds.
  Status run(std::span<const mesh::DeformInput> batch, std::vector<DeformOutput>& outputs,
             LaunchStats* stats = nullptr);

  BuildOrigin build_origin() const { return origin_; }
  int lanes() const { return lanes_; }

 private:
  DeformKernel(ComputeContext& ctx, cl::Kernel kernel, cl::Buffer shapes, size_t max_constant_bytes,
               BuildOrigin origin, int lanes);
  Status launch(std::span<const mesh::DeformInput> rooms, std::span<DeformOutput> outputs);

  static constexpr size_t kPreferredGroupSize = 128;

  ComputeContext* ctx_;
  cl::Kernel kernel_;
  size_t local_size_ = 1;
  cl::Buffer shapes_;
  size_t max_constant_bytes_;
  BuildOrigin origin_;
  int lanes_;
};

// The source the kernel is built from: prelude + shared core + kernel (GROTTO_LANES comes with the
// build options).
std::string deform_source();

}  // namespace grotto::kernels
