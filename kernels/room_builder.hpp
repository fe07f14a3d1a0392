// Builds room meshes with the deformation (and, on a GPU, the detail channels) batched on an
// OpenCL device when one is usable, and on the CPU reference otherwise. Fail soft, never silently
// (DESIGN decision 6): no platform, no device, a failed build or a failed launch is a logged
// warning and the CPU path, and path() says which path is in use.
#pragma once

#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cave/layout.hpp"
#include "kernels/channels.hpp"
#include "kernels/deform.hpp"
#include "kernels/shared_deform.hpp"

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
    // Where the detail channels run when the deformation runs on a device: on the device (one
    // launch for the batch's finished meshes) for batches of at least channels_min_vertices
    // donor vertices, else on the CPU's SIMD lanes. kAuto: the device when it is not a CPU
    // (PoCL's one-vertex-per-item kernel does not beat the lanes); kDevice: whatever the device.
    // Meshes do not depend on it.
    enum class Channels { kAuto, kDevice, kHost };
    Channels channels = Channels::kAuto;
    // A launch's round trip is a fixed cost: on an H100 a server's batches of up to 32 patch
    // rooms built slower with a second launch for their channels (server_bench: 0.46 against
    // 0.26 ms a room), the whole detail cave (317,000 vertices) faster (docs/BENCHMARKS.md).
    size_t channels_min_vertices = 65'536;
    // A device shared with other builders (SharedDeform: one context and queue, every builder's
    // batches merged into its launches; the server's workers). When set, `device` is not opened:
    // this builder deforms there, and its detail channels run on the CPU's lanes. A device
    // whose mesh parameters are not the builder's is not used (the CPU path, with a warning).
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
  // the gates (issue 30: the whole cave on every core).
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
  // Whether the detail channels can run on the device (a big enough batch's do, where
  // Options::channels allows), and its launches for them.
  bool channels_on_device() const { return channels_kernel_.has_value(); }
  const LaunchStats& channel_stats() const { return channel_launches_; }

 private:
  explicit RoomBuilder(const mesh::MeshContext& mesh_ctx);
  // The detail channels of meshes[slots[k]] (those built) on the device, in one launch; on the
  // CPU (fill_channels_on_threads) when that fails (counted in fallbacks(), logged).
  void fill_channels(std::span<const mesh::MeshContext* const> worlds,
                     std::span<const size_t> slots, std::vector<Result<mesh::RoomMesh>>& meshes);
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
  std::optional<ChannelsKernel> channels_kernel_;
  std::string path_;
  int threads_ = 1;
  size_t channels_min_vertices_ = 0;
  size_t fallbacks_ = 0;
  LaunchStats launches_;
  LaunchStats channel_launches_;
};

}  // namespace grotto::kernels
