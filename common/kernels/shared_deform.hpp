// One OpenCL device's deformation shared by every RoomBuilder of a process.
// The server's workers each had a context, a queue and a kernel of their own: a GPU was
// time-sliced among 16 contexts and every worker's batch of up to 32 patch rooms paid its own
// round trip (on an H100 the server built slower with the GPU than without). Shared, there is one
// context, one queue and one kernel: a batch that arrives while a launch runs waits, and goes up
// with every batch that arrived meanwhile in the next launch, which the first waiting thread to
// find the device free starts (no thread of its own: the callers take turns). While one launch
// runs, the batches of the launch before it are being assembled and encoded on their workers.
// The results are copied into each caller's Results, so no launch waits for a caller to finish
// with the last one's. The bits are DeformKernel's, which are the CPU reference's.
#pragma once

#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <vector>

#include "common/kernels/deform.hpp"

namespace grotto::kernels {

class SharedDeform {
 public:
  // One batch's deformation, owned by its caller and reused from batch to batch.
  struct Results {
    std::vector<mesh::core::float3> positions;
    std::vector<float> clearance;
    std::vector<float> roughness, mineral;  // empty unless the kernel computes the channels
    std::vector<DeformOutput> outputs;      // a room's views of the vectors above
  };

  // Opens the device `config` names and builds the kernel for `mesh_ctx`'s mesh parameters (every
  // world whose parameters are the same is served: the world comes with each room). Errors as
  // ComputeContext::create's and DeformKernel::create's. The kernel computes the detail channels
  // where `channels` puts them (DeformKernel::create_for).
  // `observe`, if set, is called after each launch that succeeded, on the launching thread and
  // outside the device's lock: how many batches it carried and its wall time in seconds (the
  // host's flattening, the device's round trip and the copies out), for metrics.
  using LaunchObserver = std::function<void(size_t batches, double seconds)>;
  static Result<std::shared_ptr<SharedDeform>> open(const DeviceConfig& config,
                                                    const mesh::MeshContext& mesh_ctx,
                                                    LaunchObserver observe = {},
                                                    ChannelsOn channels = ChannelsOn::kAuto);

  SharedDeform(const SharedDeform&) = delete;
  SharedDeform& operator=(const SharedDeform&) = delete;

  // Deforms every room of `batch` into `results` (thread-safe; blocks until the launch that
  // carried the batch has ended). A failed launch fails every batch it carried, each with the
  // launch's error: their callers build them on the CPU.
  Status run(std::span<const mesh::DeformInput> batch, Results& results);

  // Whether `world`'s mesh parameters are the kernel's.
  bool serves(const mesh::MeshContext& world) const;
  const ComputeContext& device() const { return *device_; }
  BuildOrigin build_origin() const { return kernel_->build_origin(); }
  // Whether each room's results carry its donor vertices' detail channels.
  bool channels() const { return kernel_->channels(); }
  // Every launch so far (launches, rooms, the device's and the host's times), and the callers'
  // batches they carried: batches() / stats().launches is how many batches a launch merged.
  LaunchStats stats() const;
  size_t batches() const;

 private:
  SharedDeform(std::unique_ptr<ComputeContext> device, const mesh::MeshContext& mesh_ctx);

  struct Request {
    std::span<const mesh::DeformInput> batch;
    Results* results = nullptr;
    Status status{};
    bool done = false;
  };
  // Runs the requests' rooms in one launch (or as few as the device's constant memory allows)
  // and copies each request's results out. Only one thread at a time (launching_). Whether it
  // succeeded.
  bool launch(std::span<Request* const> requests);

  std::unique_ptr<ComputeContext> device_;
  std::optional<DeformKernel> kernel_;
  const mesh::MeshContext* mesh_ctx_;
  LaunchObserver observe_;
  mutable std::mutex mutex_;
  std::condition_variable done_cv_;
  std::vector<Request*> pending_;  // guarded by mutex_
  bool launching_ = false;         // guarded by mutex_
  LaunchStats stats_;              // guarded by mutex_
  size_t batches_ = 0;             // guarded by mutex_
  // The launching thread's alone: the rooms of a launch and their outputs.
  std::vector<const mesh::DeformInput*> rooms_;
  std::vector<DeformOutput> outputs_;
};

// Whether two worlds' mesh parameters give the same level-of-detail shapes, which a deformation
// kernel holds (one kernel serves both).
bool same_mesh_shapes(const mesh::MeshContext& a, const mesh::MeshContext& b);

}  // namespace grotto::kernels
