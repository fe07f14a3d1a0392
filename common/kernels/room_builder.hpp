// Builds room meshes with the deformation (and, on a GPU, the detail channels) batched on an
// OpenCL device when one is usable, and on the CPU reference otherwise. Fail soft, never silently:
// no platform, no device, a failed build or a failed launch is a logged warning and the CPU path,
// and path() says which path is in use.
#pragma once

#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/kernels/deform.hpp"
#include "common/kernels/shared_deform.hpp"

namespace grotto::kernels {

class RoomBuilder {
 public:
  struct Options {
    DeviceConfig device{};  // device "none" forces the CPU reference
    // Threads that deform (on the CPU path) and assemble the rooms of one build() call, the
    // caller's included: 1 keeps it all on the caller's thread (the server, which already runs
    // one build per worker thread, must not oversubscribe its cores); a whole cave built at once
    // sets more; 0 means one per hardware thread. Meshes do not depend on it.
    int threads = 1;
    // Where the detail channels run when the deformation runs on a device: in its launch (each
    // donor vertex's with its deformation; the rim vertices' on the CPU at assembly), or on the
    // CPU's SIMD lanes. kAuto: in the launch on devices that are not CPUs. Meshes do not depend
    // on it.
    using Channels = ChannelsOn;
    Channels channels = Channels::kAuto;
    // A device shared with other builders (SharedDeform: one context and queue, every builder's
    // batches merged into its launches; the server's workers). When set, `device` and `channels`
    // are not used: this builder deforms there, with the channels where the shared kernel puts
    // them. A device whose mesh parameters are not the builder's is not used (the CPU path, with a
    // warning).
    std::shared_ptr<SharedDeform> shared_device{};
  };

  // Never fails: without a usable device the builder runs on the CPU.
  static RoomBuilder create(const mesh::MeshContext& mesh_ctx, const Options& options);

  RoomBuilder(RoomBuilder&&) noexcept;
  RoomBuilder& operator=(RoomBuilder&&) noexcept;
  ~RoomBuilder();

  // One mesh per room, in order; all rooms share one kernel launch where the device allows.
  std::vector<Result<mesh::RoomMesh>> build(std::span<const cave::Room> rooms, mesh::Lod lod);
  // Rooms of any worlds whose mesh parameters are the builder's (one builder serves every world
  // of a server), in one launch: worlds[i] is rooms[i]'s world (same sizes). A room whose world
  // has other mesh parameters fails; the others are built.
  std::vector<Result<mesh::RoomMesh>> build(std::span<const mesh::MeshContext* const> worlds,
                                            std::span<const cave::Room> rooms, mesh::Lod lod);
  // A block of sectors [lo, hi] of the builder's world and every room's mesh: the region is
  // cave::generate_region's, meshes[i] is region.rooms[i]'s as build() gives it. A pipeline on
  // the builder's threads: the block's own sectors are laid out first, and its interior rooms
  // built while the sectors beyond its faces (which only its gate rooms need) are laid out; then
  // the gates, so that every core has work. With one or two threads, which the layout
  // keeps busy, the region is laid out, then built.
  struct BuiltRegion {
    cave::Region region;
    std::vector<Result<mesh::RoomMesh>> meshes;
  };
  BuiltRegion build_region(cave::SectorCoord lo, cave::SectorCoord hi, mesh::Lod lod);
  // Whether `world`'s mesh parameters are the builder's (its kernel holds their shapes).
  bool serves(const mesh::MeshContext& world) const;

  bool uses_opencl() const { return kernel_.has_value() || shared_ != nullptr; }
  // "opencl: <device description>" or "cpu: <why not OpenCL>".
  const std::string& path() const { return path_; }
  // Launches that failed and were redone on the CPU (each also logged).
  size_t fallbacks() const { return fallbacks_; }
  // This builder's own launches (a shared device's are SharedDeform::stats()).
  const LaunchStats& launch_stats() const { return launches_; }
  // Whether the device computes the donor vertices' detail channels with their deformation.
  bool channels_on_device() const;

 private:
  explicit RoomBuilder(const mesh::MeshContext& mesh_ctx);
  // The detail channels of meshes[slots[k]] (those built) on the CPU's lanes, in pieces of a few
  // thousand vertices on threads_ threads.
  void fill_channels_on_threads(std::span<const mesh::MeshContext* const> worlds,
                                std::span<const size_t> slots,
                                std::vector<Result<mesh::RoomMesh>>& meshes);

  const mesh::MeshContext* mesh_ctx_;
  std::unique_ptr<ComputeContext> device_;
  std::optional<DeformKernel> kernel_;
  std::shared_ptr<SharedDeform> shared_;  // instead of device_ and kernel_
  SharedDeform::Results shared_results_;
  std::string path_;
  int threads_ = 1;
  size_t fallbacks_ = 0;
  LaunchStats launches_;
};

}  // namespace grotto::kernels
