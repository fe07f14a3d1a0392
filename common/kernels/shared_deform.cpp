#include "common/kernels/shared_deform.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>

namespace grotto::kernels {

bool same_mesh_shapes(const mesh::MeshContext& a, const mesh::MeshContext& b) {
  for (int l = 0; l < mesh::kLodCount; ++l) {
    auto lod = static_cast<mesh::Lod>(l);
    if (std::memcmp(&a.shape(lod), &b.shape(lod), sizeof(a.shape(lod))) != 0) return false;
  }
  return true;
}

SharedDeform::SharedDeform(std::unique_ptr<ComputeContext> device,
                           const mesh::MeshContext& mesh_ctx)
    : device_(std::move(device)), mesh_ctx_(&mesh_ctx) {}

Result<std::shared_ptr<SharedDeform>> SharedDeform::open(const DeviceConfig& config,
                                                         const mesh::MeshContext& mesh_ctx,
                                                         LaunchObserver observe,
                                                         ChannelsOn channels) {
  auto ctx = ComputeContext::create(config);
  if (!ctx) return ctx.error();
  std::shared_ptr<SharedDeform> shared(
      new SharedDeform(std::make_unique<ComputeContext>(std::move(ctx).value()), mesh_ctx));
  auto kernel = DeformKernel::create_for(*shared->device_, mesh_ctx, channels);
  if (!kernel) {
    return Error{kernel.error().code,
                 "deformation kernel failed to build: " + kernel.error().message};
  }
  shared->kernel_.emplace(std::move(kernel).value());
  shared->observe_ = std::move(observe);
  return shared;
}

bool SharedDeform::serves(const mesh::MeshContext& world) const {
  return same_mesh_shapes(world, *mesh_ctx_);
}

Status SharedDeform::run(std::span<const mesh::DeformInput> batch, Results& results) {
  Request request{batch, &results};
  std::unique_lock lock(mutex_);
  pending_.push_back(&request);
  while (!request.done) {
    if (launching_) {
      done_cv_.wait(lock);
      continue;
    }
    // The device is free: this thread launches every batch waiting, its own among them.
    launching_ = true;
    std::vector<Request*> taken;
    taken.swap(pending_);
    lock.unlock();
    const auto t0 = std::chrono::steady_clock::now();
    if (launch(taken) && observe_) {
      observe_(taken.size(),
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    lock.lock();
    launching_ = false;
    batches_ += taken.size();
    for (Request* r : taken)
      r->done = true;
    done_cv_.notify_all();
  }
  return request.status;
}

bool SharedDeform::launch(std::span<Request* const> requests) {
  rooms_.clear();
  for (const Request* r : requests) {
    for (const mesh::DeformInput& room : r->batch)
      rooms_.push_back(&room);
  }
  LaunchStats stats;
  Status s = kernel_->run(std::span<const mesh::DeformInput* const>(rooms_), outputs_, &stats);
  // Out of the kernel's memory, which the next launch overwrites, into each caller's: counted
  // with the unpacking (the host's work after the download).
  const auto t_copy = std::chrono::steady_clock::now();
  size_t next = 0;
  for (Request* r : requests) {
    Results& out = *r->results;
    r->status = s;
    if (!s) continue;
    size_t vertices = 0;
    for (size_t i = 0; i < r->batch.size(); ++i)
      vertices += outputs_[next + i].positions.size();
    const bool channels = kernel_->channels();
    out.positions.resize(vertices);
    out.clearance.resize(vertices);
    out.roughness.resize(channels ? vertices : 0);
    out.mineral.resize(channels ? vertices : 0);
    out.outputs.resize(r->batch.size());
    size_t at = 0;
    for (size_t i = 0; i < r->batch.size(); ++i, ++next) {
      const DeformOutput& from = outputs_[next];
      const size_t n = from.positions.size();
      std::copy(from.positions.begin(), from.positions.end(), out.positions.begin() + at);
      std::copy(from.clearance.begin(), from.clearance.end(), out.clearance.begin() + at);
      DeformOutput& to = out.outputs[i];
      to = {std::span(out.positions).subspan(at, n),
            std::span<const float>(out.clearance).subspan(at, n),
            {},
            {}};
      if (channels) {
        std::copy(from.roughness.begin(), from.roughness.end(), out.roughness.begin() + at);
        std::copy(from.mineral.begin(), from.mineral.end(), out.mineral.begin() + at);
        to.roughness = std::span<const float>(out.roughness).subspan(at, n);
        to.mineral = std::span<const float>(out.mineral).subspan(at, n);
      }
      at += n;
    }
  }
  stats.unpack_ms +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_copy).count();
  std::lock_guard lock(mutex_);
  accumulate(stats_, stats);
  return s.ok();
}

LaunchStats SharedDeform::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

size_t SharedDeform::batches() const {
  std::lock_guard lock(mutex_);
  return batches_;
}

}  // namespace grotto::kernels
