// The deformation kernel against the CPU reference, on real PoCL: bit-identical, batched or not,
// and the room builder's fail-soft path.
#include "common/kernels/deform.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <latch>
#include <set>
#include <thread>

#include "common/kernels/room_builder.hpp"
#include "common/kernels/shared_deform.hpp"
#include "tests/kernels/test_support.hpp"

namespace grotto::kernels {
namespace {

class DeformKernelTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    world_ = new cave::World(cave::World::create(42, cave::LayoutParams{}).value());
    mesh_ = new mesh::MeshContext(mesh::MeshContext::create(*world_, mesh::MeshParams{}).value());
    region_ = new cave::Region(cave::generate_region(*world_, {0, 0, 0}, {0, 0, 0}));
    auto ctx = ComputeContext::create(DeviceConfig{.device = "auto"});
    ASSERT_TRUE(ctx.ok()) << ctx.error().message;
    device_ = new ComputeContext(std::move(ctx).value());
  }
  static void TearDownTestSuite() {
    delete device_;
    delete region_;
    delete mesh_;
    delete world_;
  }
  static std::vector<mesh::DeformInput> inputs(mesh::Lod lod, size_t step = 1) {
    std::vector<mesh::DeformInput> out;
    for (size_t i = 0; i < region_->rooms.size(); i += step) {
      out.push_back(mesh::prepare_room(*mesh_, region_->rooms[i], lod));
    }
    return out;
  }
  static void expect_matches_cpu(DeformKernel& kernel);
  static void expect_builders_sharing_a_device_get_their_own_rooms(ChannelsOn channels);
  static cave::World* world_;
  static mesh::MeshContext* mesh_;
  static cave::Region* region_;
  static ComputeContext* device_;
};
cave::World* DeformKernelTest::world_ = nullptr;
mesh::MeshContext* DeformKernelTest::mesh_ = nullptr;
cave::Region* DeformKernelTest::region_ = nullptr;
ComputeContext* DeformKernelTest::device_ = nullptr;

bool same_bits(float a, float b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

// A run's outputs copied out of the kernel's memory, whose views the next run overwrites.
struct OwnedOutput {
  std::vector<mesh::core::float3> positions;
  std::vector<float> clearance;
};
std::vector<OwnedOutput> owned(const std::vector<DeformOutput>& views) {
  std::vector<OwnedOutput> out;
  for (const DeformOutput& v : views)
    out.push_back(
        {{v.positions.begin(), v.positions.end()}, {v.clearance.begin(), v.clearance.end()}});
  return out;
}

// Both kernel shapes on this device: one vertex per work item (as on GPUs) and eight per work item
// in float8 lanes (the CPU-device default), each lane bit-identical to the scalar reference.
TEST_F(DeformKernelTest, kernel_matches_the_cpu_reference_bit_for_bit) {
  for (int lanes : {1, 8}) {
    SCOPED_TRACE("lanes=" + std::to_string(lanes));
    auto created = DeformKernel::create(*device_, *mesh_, lanes);
    ASSERT_TRUE(created.ok()) << created.error().message;
    DeformKernel kernel = std::move(created).value();
    EXPECT_EQ(kernel.lanes(), lanes);
    expect_matches_cpu(kernel);
  }
}

TEST_F(DeformKernelTest, lanes_default_to_eight_on_cpu_devices_and_reject_other_counts) {
  auto created = DeformKernel::create(*device_, *mesh_);
  ASSERT_TRUE(created.ok()) << created.error().message;
  EXPECT_EQ(created->lanes(), device_->info().device_type == "cpu" ? 8 : 1);
  // The driver's word on the kernel, for occupancy reports (mesh_bench): at least one group fits.
  EXPECT_GT(created->info().max_work_group_size, 0u);
  EXPECT_GT(created->info().preferred_multiple, 0u);
  auto bad = DeformKernel::create(*device_, *mesh_, 4);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("lanes"), std::string::npos) << bad.error().message;
}

void DeformKernelTest::expect_matches_cpu(DeformKernel& kernel) {
  for (mesh::Lod lod : {mesh::Lod::kPatch, mesh::Lod::kDetail}) {
    std::vector<mesh::DeformInput> batch = inputs(lod);
    std::vector<DeformOutput> out;
    LaunchStats stats;
    ASSERT_TRUE(kernel.run(batch, out, &stats).ok());
    EXPECT_LE(stats.launches, 2u) << "a sector's rooms fit in one or two launches";
    size_t vertices = 0, mismatches = 0;
    for (size_t r = 0; r < batch.size(); ++r) {
      size_t n = batch[r].donor->directions.size();
      std::vector<mesh::core::float3> pos(n);
      std::vector<float> clearance(n);
      mesh::deform_cpu(*mesh_, batch[r], pos, clearance);
      ASSERT_EQ(out[r].positions.size(), n);
      for (size_t v = 0; v < n; ++v, ++vertices) {
        bool same = same_bits(pos[v].x, out[r].positions[v].x) &&
                    same_bits(pos[v].y, out[r].positions[v].y) &&
                    same_bits(pos[v].z, out[r].positions[v].z) &&
                    same_bits(clearance[v], out[r].clearance[v]);
        if (!same && ++mismatches <= 5) {
          ADD_FAILURE() << mesh::lod_name(lod) << " room " << batch[r].room.id.to_string()
                        << " vertex " << v << ": cpu " << pos[v].x << "," << pos[v].y << ","
                        << pos[v].z << " device " << out[r].positions[v].x << ","
                        << out[r].positions[v].y << "," << out[r].positions[v].z;
        }
      }
    }
    EXPECT_EQ(mismatches, 0u);
    EXPECT_GT(vertices, 50000u);
    // Every path of the deformation is in the batch: small rooms (spline tubes), big rooms (the
    // sphere with collars) and halls resting on a floor.
    size_t big = 0, floored = 0;
    for (const mesh::DeformInput& in : batch) {
      big += in.record.big_amplitude != 0.0f;
      floored += in.record.has_floor != 0u;
    }
    EXPECT_GT(big, floored);
    EXPECT_GT(floored, 0u);
  }
}

TEST_F(DeformKernelTest, batched_and_single_room_launches_agree) {
  auto created = DeformKernel::create(*device_, *mesh_);
  ASSERT_TRUE(created.ok()) << created.error().message;
  DeformKernel kernel = std::move(created).value();
  std::vector<mesh::DeformInput> batch = inputs(mesh::Lod::kPatch, 5);
  std::vector<DeformOutput> views;
  LaunchStats stats;
  ASSERT_TRUE(kernel.run(batch, views, &stats).ok());
  EXPECT_EQ(stats.launches, 1u);
  const std::vector<OwnedOutput> together = owned(views);
  // Alone, and in another batch mix (reversed), every room gives the same bits.
  std::vector<mesh::DeformInput> reversed(batch.rbegin(), batch.rend());
  ASSERT_TRUE(kernel.run(reversed, views).ok());
  const std::vector<OwnedOutput> mixed = owned(views);
  for (size_t r = 0; r < batch.size(); ++r) {
    std::vector<DeformOutput> alone;
    ASSERT_TRUE(kernel.run(std::span(batch).subspan(r, 1), alone).ok());
    const OwnedOutput& m = mixed[batch.size() - 1 - r];
    ASSERT_EQ(alone[0].positions.size(), together[r].positions.size());
    for (size_t v = 0; v < alone[0].positions.size(); ++v) {
      ASSERT_TRUE(same_bits(alone[0].positions[v].y, together[r].positions[v].y));
      ASSERT_TRUE(same_bits(m.positions[v].x, together[r].positions[v].x));
      ASSERT_TRUE(same_bits(alone[0].clearance[v], together[r].clearance[v]));
    }
  }
}

// A batch split into several launches (as a GPU's 64 KiB of constant memory splits a few hundred
// rooms) gives every room the bits of one launch: each launch reads into its own part of the
// run's host memory, and the first launch's views survive the later ones.
TEST_F(DeformKernelTest, a_batch_split_into_many_launches_gives_the_one_launch_bits) {
  for (int lanes : {1, 8}) {
    SCOPED_TRACE("lanes=" + std::to_string(lanes));
    auto whole_created = DeformKernel::create(*device_, *mesh_, lanes);
    auto split_created = DeformKernel::create(*device_, *mesh_, lanes, 4096);
    ASSERT_TRUE(whole_created.ok() && split_created.ok());
    DeformKernel whole = std::move(whole_created).value();
    DeformKernel split = std::move(split_created).value();
    std::vector<mesh::DeformInput> batch = inputs(mesh::Lod::kPatch);
    std::vector<DeformOutput> one_views, many;
    LaunchStats one_stats, many_stats;
    ASSERT_TRUE(whole.run(batch, one_views, &one_stats).ok());
    ASSERT_TRUE(split.run(batch, many, &many_stats).ok());
    EXPECT_EQ(one_stats.launches, 1u);
    EXPECT_GE(many_stats.launches, 4u);
    ASSERT_EQ(many.size(), batch.size());
    const std::vector<OwnedOutput> one = owned(one_views);
    for (size_t r = 0; r < batch.size(); ++r) {
      ASSERT_EQ(many[r].positions.size(), one[r].positions.size());
      EXPECT_EQ(std::memcmp(many[r].positions.data(), one[r].positions.data(),
                            one[r].positions.size() * sizeof(mesh::core::float3)),
                0)
          << "room " << r;
      EXPECT_EQ(std::memcmp(many[r].clearance.data(), one[r].clearance.data(),
                            one[r].clearance.size() * sizeof(float)),
                0)
          << "room " << r;
    }
  }
}

// A launch's time split by the queue's events. With profiling (the default) the device's
// upload, kernel and download are timed and fit in the device's span; without it they read 0, and
// either way the results are the same bits.
TEST_F(DeformKernelTest, a_profiled_queue_splits_the_launch_into_upload_kernel_and_download) {
  ASSERT_TRUE(device_->profiling()) << "PoCL accepts CL_QUEUE_PROFILING_ENABLE";
  auto plain_ctx = ComputeContext::create(DeviceConfig{.device = "auto", .profiling = false});
  ASSERT_TRUE(plain_ctx.ok()) << plain_ctx.error().message;
  EXPECT_FALSE(plain_ctx->profiling());
  std::vector<mesh::DeformInput> batch = inputs(mesh::Lod::kPatch, 3);
  std::vector<OwnedOutput> outs[2], again;
  LaunchStats stats[2], second;
  ComputeContext* contexts[2] = {device_, &plain_ctx.value()};
  for (int k = 0; k < 2; ++k) {
    auto created = DeformKernel::create(*contexts[k], *mesh_);
    ASSERT_TRUE(created.ok()) << created.error().message;
    DeformKernel kernel = std::move(created).value();
    std::vector<DeformOutput> views;
    ASSERT_TRUE(kernel.run(batch, views, &stats[k]).ok());
    outs[k] = owned(views);
    // The donors' directions stay on the device: the same batch again uploads its tables
    // alone, and gives the same bits.
    if (k == 0) {
      ASSERT_TRUE(kernel.run(batch, views, &second).ok());
      again = owned(views);
    }
  }
  const LaunchStats& s = stats[0];
  EXPECT_GT(s.upload_ms, 0.0);
  EXPECT_GT(s.kernel_ms, 0.0);
  EXPECT_GT(s.download_ms, 0.0);
  EXPECT_GE(s.device_span_ms, s.kernel_ms);
  EXPECT_GE(s.queue_wall_ms, s.kernel_ms);
  EXPECT_GT(s.prepare_ms + s.allocate_ms + s.unpack_ms, 0.0);
  EXPECT_EQ(s.launches, 1u);
  ASSERT_GT(s.local_size, 0u);
  EXPECT_EQ(s.global_size % s.local_size, 0u);
  const size_t lanes = device_->info().device_type == "cpu" ? 8 : 1;
  EXPECT_GE(s.global_size * lanes, s.vertices);
  // Positions and clearance of every padded slot come back: 16 bytes each.
  EXPECT_GE(s.download_bytes, 16 * s.vertices);
  size_t donor_vertices = 0;  // each distinct donor's directions go up once
  std::set<const mesh::DonorSphere*> donors;
  for (const mesh::DeformInput& in : batch)
    if (donors.insert(in.donor.get()).second) donor_vertices += in.donor->directions.size();
  EXPECT_GE(s.upload_bytes, 12 * donor_vertices);
  // The second launch uploads no directions and nothing per vertex: its room and portal tables
  // (80 bytes a room, 96 a portal).
  EXPECT_LE(second.upload_bytes + 12 * donor_vertices, s.upload_bytes);
  size_t portal_count = 0;
  for (const mesh::DeformInput& in : batch)
    portal_count += in.portals.size();
  EXPECT_EQ(second.upload_bytes,
            sizeof(mesh::core::GrottoRoom) * batch.size() +
                sizeof(mesh::core::GrottoPortal) * std::max<size_t>(portal_count, 1))
      << "the tables alone";
  ASSERT_EQ(again.size(), outs[0].size());
  for (size_t r = 0; r < again.size(); ++r) {
    EXPECT_EQ(again[r].positions.size(), outs[0][r].positions.size());
    EXPECT_EQ(std::memcmp(again[r].positions.data(), outs[0][r].positions.data(),
                          again[r].positions.size() * sizeof(mesh::core::float3)),
              0);
  }
  EXPECT_EQ(stats[1].upload_ms + stats[1].kernel_ms + stats[1].download_ms, 0.0);
  EXPECT_EQ(stats[1].upload_bytes, s.upload_bytes);
  ASSERT_EQ(outs[0].size(), outs[1].size());
  for (size_t r = 0; r < outs[0].size(); ++r) {
    ASSERT_EQ(outs[0][r].positions.size(), outs[1][r].positions.size());
    EXPECT_EQ(std::memcmp(outs[0][r].positions.data(), outs[1][r].positions.data(),
                          outs[0][r].positions.size() * sizeof(mesh::core::float3)),
              0);
    EXPECT_EQ(outs[0][r].clearance, outs[1][r].clearance);
  }
}

// One kernel serves every world with its mesh parameters: rooms of two worlds, interleaved in one
// run, each match the CPU reference of their own world, in a single launch.
TEST_F(DeformKernelTest, a_batch_mixing_two_worlds_matches_each_worlds_cpu_reference) {
  auto created = DeformKernel::create(*device_, *mesh_);
  ASSERT_TRUE(created.ok()) << created.error().message;
  DeformKernel kernel = std::move(created).value();
  cave::World other_world = cave::World::create(43, cave::LayoutParams{}).value();
  auto other = mesh::MeshContext::create(other_world, mesh::MeshParams{}).value();
  ASSERT_NE(other.noise_seed(), mesh_->noise_seed());
  cave::Region other_region = cave::generate_region(other_world, {0, 0, 0}, {0, 0, 0});
  std::vector<mesh::DeformInput> batch;
  std::vector<const mesh::MeshContext*> world_of;
  for (size_t i = 0; i < 4; ++i) {
    batch.push_back(mesh::prepare_room(*mesh_, region_->rooms[i], mesh::Lod::kPatch));
    world_of.push_back(mesh_);
    batch.push_back(mesh::prepare_room(other, other_region.rooms[i], mesh::Lod::kPatch));
    world_of.push_back(&other);
  }
  // The same room of the same place in another world differs: the seed reached the kernel.
  batch.push_back(mesh::prepare_room(other, region_->rooms[0], mesh::Lod::kPatch));
  world_of.push_back(&other);
  std::vector<DeformOutput> out;
  LaunchStats stats;
  ASSERT_TRUE(kernel.run(batch, out, &stats).ok());
  EXPECT_EQ(stats.launches, 1u) << "one launch whatever the worlds";
  for (size_t r = 0; r < batch.size(); ++r) {
    size_t n = batch[r].donor->directions.size();
    std::vector<mesh::core::float3> pos(n);
    std::vector<float> clearance(n);
    mesh::deform_cpu(*world_of[r], batch[r], pos, clearance);
    ASSERT_EQ(out[r].positions.size(), n);
    for (size_t v = 0; v < n; ++v) {
      ASSERT_TRUE(same_bits(pos[v].x, out[r].positions[v].x) &&
                  same_bits(pos[v].y, out[r].positions[v].y) &&
                  same_bits(pos[v].z, out[r].positions[v].z) &&
                  same_bits(clearance[v], out[r].clearance[v]))
          << "room " << r << " vertex " << v;
    }
  }
  size_t differing = 0;
  for (size_t v = 0; v < out[0].positions.size(); ++v)
    differing += !same_bits(out[0].positions[v].x, out.back().positions[v].x);
  EXPECT_GT(differing, out[0].positions.size() / 2);
}

// Whether two meshes' vertices (positions and the detail channels) are the same bits.
bool same_vertices(const mesh::RoomMesh& a, const mesh::RoomMesh& b) {
  if (a.vertex_count() != b.vertex_count() || a.roughness.size() != a.vertex_count() ||
      b.roughness.size() != b.vertex_count() || a.mineral.size() != b.mineral.size()) {
    return false;
  }
  return std::memcmp(a.positions.data(), b.positions.data(),
                     a.vertex_count() * sizeof(mesh::core::float3)) == 0 &&
         std::memcmp(a.roughness.data(), b.roughness.data(), a.vertex_count() * sizeof(float)) ==
             0 &&
         std::memcmp(a.mineral.data(), b.mineral.data(), a.vertex_count() * sizeof(float)) == 0;
}

// Each of `meshes` built, with the indices and vertex bits of rooms[i]'s CPU reference (patch).
void expect_cpu_meshes(const std::vector<Result<mesh::RoomMesh>>& meshes,
                       const std::vector<cave::Room>& rooms, const mesh::MeshContext& world) {
  ASSERT_EQ(meshes.size(), rooms.size());
  for (size_t i = 0; i < rooms.size(); ++i) {
    ASSERT_TRUE(meshes[i].ok()) << meshes[i].error().message;
    mesh::RoomMesh cpu = mesh::build_room_mesh(world, rooms[i], mesh::Lod::kPatch).value();
    EXPECT_EQ(meshes[i]->indices, cpu.indices) << rooms[i].id.to_string();
    EXPECT_TRUE(same_vertices(*meshes[i], cpu)) << rooms[i].id.to_string();
  }
}

// With the detail channels where the CPU device puts them (its SIMD lanes, after assembly) and
// forced onto the device (as on a GPU: computed with the deformation, in its launch, the rim
// vertices' at assembly), on one thread and on several, the meshes are the CPU's bits.
TEST_F(DeformKernelTest, room_builder_on_the_device_gives_the_cpu_meshes) {
  using Channels = RoomBuilder::Options::Channels;
  for (Channels channels : {Channels::kAuto, Channels::kDevice}) {
    for (int threads : {1, 2}) {
      SCOPED_TRACE(
          std::string(channels == Channels::kAuto ? "channels auto" : "channels on the device") +
          ", " + std::to_string(threads) + " threads");
      RoomBuilder builder =
          RoomBuilder::create(*mesh_, {DeviceConfig{.device = "auto"}, threads, channels});
      ASSERT_TRUE(builder.uses_opencl()) << builder.path();
      EXPECT_EQ(builder.path().rfind("opencl: ", 0), 0u) << builder.path();
      // Auto keeps the channels on a CPU device's lanes (PoCL) and puts them on any other device.
      EXPECT_EQ(builder.channels_on_device(),
                channels == Channels::kDevice || device_->info().device_type != "cpu");
      std::vector<cave::Room> rooms(region_->rooms.begin(), region_->rooms.begin() + 20);
      auto meshes = builder.build(rooms, mesh::Lod::kPatch);
      ASSERT_EQ(meshes.size(), rooms.size());
      expect_cpu_meshes(meshes, rooms, *mesh_);
      EXPECT_EQ(builder.fallbacks(), 0u);
      EXPECT_EQ(builder.launch_stats().launches, 1u);
    }
  }
}

// Builders sharing one device (the server's workers): four threads' batches, released at once
// and merged into fewer launches than batches, give every room its CPU reference's bits, each
// thread its own rooms in its own order; the device's stats count every room once.
TEST_F(DeformKernelTest, builders_sharing_a_device_get_their_own_rooms_with_the_cpu_bits) {
  for (ChannelsOn channels : {ChannelsOn::kAuto, ChannelsOn::kDevice}) {
    SCOPED_TRACE(channels == ChannelsOn::kAuto ? "channels auto" : "channels on the device");
    expect_builders_sharing_a_device_get_their_own_rooms(channels);
  }
}

void DeformKernelTest::expect_builders_sharing_a_device_get_their_own_rooms(ChannelsOn channels) {
  auto opened = SharedDeform::open(DeviceConfig{.device = "auto"}, *mesh_, {}, channels);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  std::shared_ptr<SharedDeform> shared = std::move(opened).value();
  EXPECT_EQ(shared->channels(),
            channels == ChannelsOn::kDevice || device_->info().device_type != "cpu");
  constexpr size_t kThreads = 4, kRounds = 6, kRooms = 5;
  std::vector<std::vector<cave::Room>> rooms(kThreads);
  for (size_t t = 0; t < kThreads; ++t) {
    for (size_t i = 0; i < kRooms; ++i)
      rooms[t].push_back(region_->rooms[(t * kRooms + i) % region_->rooms.size()]);
  }
  std::vector<std::vector<Result<mesh::RoomMesh>>> built(kThreads * kRounds);
  std::vector<std::string> paths(kThreads);
  std::vector<size_t> fallbacks(kThreads);
  std::latch go(1);
  std::vector<std::thread> threads;
  for (size_t t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      RoomBuilder::Options options;
      options.device.device = "none";  // not opened: the shared device is used
      options.shared_device = shared;
      RoomBuilder builder = RoomBuilder::create(*mesh_, options);
      EXPECT_EQ(builder.channels_on_device(), shared->channels());
      paths[t] = builder.path();
      go.wait();
      for (size_t r = 0; r < kRounds; ++r)
        built[t * kRounds + r] = builder.build(rooms[t], mesh::Lod::kPatch);
      fallbacks[t] = builder.fallbacks();
    });
  }
  go.count_down();
  for (std::thread& t : threads)
    t.join();
  for (size_t t = 0; t < kThreads; ++t) {
    SCOPED_TRACE("thread " + std::to_string(t));
    EXPECT_EQ(paths[t].rfind("opencl: ", 0), 0u) << paths[t];
    EXPECT_NE(paths[t].find("shared=true"), std::string::npos) << paths[t];
    EXPECT_EQ(fallbacks[t], 0u);
    for (size_t r = 0; r < kRounds; ++r)
      expect_cpu_meshes(built[t * kRounds + r], rooms[t], *mesh_);
  }
  const LaunchStats stats = shared->stats();
  EXPECT_EQ(shared->batches(), kThreads * kRounds);
  EXPECT_EQ(stats.rooms, kThreads * kRounds * kRooms);
  EXPECT_LT(stats.launches, shared->batches()) << "batches that waited went up together";
  EXPECT_GE(stats.launches, 1u);
}

// A shared device built for other mesh parameters is not used: the builder says so and builds on
// the CPU.
TEST_F(DeformKernelTest, a_shared_device_of_other_mesh_parameters_is_not_used) {
  auto opened = SharedDeform::open(DeviceConfig{.device = "auto"}, *mesh_);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  mesh::MeshParams rougher;
  rougher.octave_amplitude[0] = 0.5;
  auto differs = mesh::MeshContext::create(*world_, rougher).value();
  RoomBuilder::Options options;
  options.shared_device = std::move(opened).value();
  RoomBuilder builder = RoomBuilder::create(differs, options);
  EXPECT_FALSE(builder.uses_opencl());
  EXPECT_NE(builder.path().find("other mesh parameters"), std::string::npos) << builder.path();
  std::vector<cave::Room> rooms(region_->rooms.begin(), region_->rooms.begin() + 3);
  auto meshes = builder.build(std::vector(rooms.size(), &differs), rooms, mesh::Lod::kPatch);
  for (size_t i = 0; i < rooms.size(); ++i) {
    ASSERT_TRUE(meshes[i].ok()) << meshes[i].error().message;
    EXPECT_TRUE(same_vertices(*meshes[i],
                              mesh::build_room_mesh(differs, rooms[i], mesh::Lod::kPatch).value()));
  }
}

// Run by the kernels.launch_fault.* tests (tests/kernels/CMakeLists.txt), under an interposer that
// fails every launch of the kernel GROTTO_TEST_FAIL_KERNEL names: the machine's OpenCL failing
// after a good start. The builder logs and counts each failed launch and builds that stage on the
// CPU, with the same bits, and tries the device again at the next batch.
class LaunchFault : public DeformKernelTest {};

TEST_F(LaunchFault, a_failed_launch_is_built_on_the_cpu_with_the_same_bits) {
  const char* failing = std::getenv("GROTTO_TEST_FAIL_KERNEL");
  if (failing == nullptr) GTEST_SKIP() << "run by kernels.launch_fault.* under the interposer";
  ASSERT_EQ(std::string(failing), "grotto_deform_rooms");
  using Channels = RoomBuilder::Options::Channels;
  for (Channels channels : {Channels::kAuto, Channels::kDevice}) {
    RoomBuilder builder =
        RoomBuilder::create(*mesh_, {DeviceConfig{.device = "auto"}, /*threads=*/2, channels});
    ASSERT_TRUE(builder.uses_opencl()) << builder.path();
    std::vector<cave::Room> rooms(region_->rooms.begin(), region_->rooms.begin() + 12);
    for (size_t round = 1; round <= 2; ++round) {
      auto meshes = builder.build(rooms, mesh::Lod::kPatch);
      ASSERT_EQ(meshes.size(), rooms.size());
      expect_cpu_meshes(meshes, rooms, *mesh_);
      EXPECT_EQ(builder.fallbacks(), round) << "one failed launch a batch, counted";
      EXPECT_EQ(builder.launch_stats().launches, 0u) << "a failed launch is not counted";
    }
  }
}

// The same fault with the device shared by two builders: a failed deformation fails every batch
// of the launch, and each builder builds its own on the CPU with the same bits.
TEST_F(LaunchFault, a_failed_shared_launch_is_built_on_the_cpu_by_every_builder) {
  const char* failing = std::getenv("GROTTO_TEST_FAIL_KERNEL");
  if (failing == nullptr) GTEST_SKIP() << "run by kernels.launch_fault.* under the interposer";
  auto opened = SharedDeform::open(DeviceConfig{.device = "auto"}, *mesh_, {}, ChannelsOn::kDevice);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  RoomBuilder::Options options;
  options.shared_device = std::move(opened).value();
  std::vector<cave::Room> rooms(region_->rooms.begin(), region_->rooms.begin() + 6);
  std::vector<size_t> fallbacks(2);
  std::vector<std::vector<Result<mesh::RoomMesh>>> built(2);
  std::vector<std::thread> threads;
  for (size_t t = 0; t < 2; ++t) {
    threads.emplace_back([&, t] {
      RoomBuilder builder = RoomBuilder::create(*mesh_, options);
      built[t] = builder.build(rooms, mesh::Lod::kPatch);
      fallbacks[t] = builder.fallbacks();
    });
  }
  for (std::thread& t : threads)
    t.join();
  for (size_t t = 0; t < 2; ++t) {
    expect_cpu_meshes(built[t], rooms, *mesh_);
    EXPECT_EQ(fallbacks[t], 1u) << "builder " << t;
  }
  EXPECT_EQ(options.shared_device->stats().launches, 0u) << "a failed launch is not counted";
}

// The deformation computing the detail channels: every donor vertex of rooms of three worlds in
// one launch (two noise seeds, one world with other channel frequencies but the same shapes,
// origins far from 0 and on both sides of it, both levels) gets mesh::detail_channels' bits at the
// position the launch returns, which is deform_cpu's; the kernel without channels returns none.
TEST_F(DeformKernelTest, the_deformation_computes_the_channels_of_rooms_of_three_worlds) {
  auto created = DeformKernel::create(*device_, *mesh_, 0, 0, /*channels=*/true);
  ASSERT_TRUE(created.ok()) << created.error().message;
  DeformKernel kernel = std::move(created).value();
  EXPECT_TRUE(kernel.channels());
  EXPECT_EQ(kernel.lanes(), 1);
  cave::World other_world = cave::World::create(43, cave::LayoutParams{}).value();
  auto other = mesh::MeshContext::create(other_world, mesh::MeshParams{}).value();
  mesh::MeshParams finer;
  finer.roughness_frequency = 9 / 64.0;
  finer.mineral_frequency = 3 / 64.0;
  auto other_channels = mesh::MeshContext::create(*world_, finer).value();
  ASSERT_TRUE(same_mesh_shapes(other_channels, *mesh_));
  cave::Region far_region = cave::generate_region(other_world, {-40, 3, 977}, {-40, 3, 977});
  std::vector<mesh::DeformInput> batch;
  std::vector<const mesh::MeshContext*> worlds;
  for (size_t i = 0; i < 5; ++i) {
    batch.push_back(mesh::prepare_room(*mesh_, region_->rooms[i], mesh::Lod::kPatch));
    worlds.push_back(mesh_);
    batch.push_back(mesh::prepare_room(other, far_region.rooms[i], mesh::Lod::kDetail));
    worlds.push_back(&other);
    batch.push_back(mesh::prepare_room(other_channels, region_->rooms[i + 5], mesh::Lod::kPatch));
    worlds.push_back(&other_channels);
  }
  std::vector<DeformOutput> out;
  LaunchStats stats;
  ASSERT_TRUE(kernel.run(batch, out, &stats).ok());
  EXPECT_EQ(stats.launches, 1u);
  ASSERT_EQ(out.size(), batch.size());
  for (size_t i = 0; i < batch.size(); ++i) {
    const size_t n = batch[i].donor->directions.size();
    std::vector<mesh::core::float3> positions(n);
    std::vector<float> clearance(n), roughness(n), mineral(n);
    mesh::deform_cpu(*worlds[i], batch[i], positions, clearance);
    mesh::detail_channels_reference(*worlds[i], batch[i].origin, positions, roughness, mineral);
    ASSERT_EQ(out[i].roughness.size(), n) << "room " << i;
    ASSERT_EQ(out[i].mineral.size(), n) << "room " << i;
    EXPECT_EQ(std::memcmp(out[i].positions.data(), positions.data(), n * sizeof(positions[0])), 0)
        << "room " << i;
    EXPECT_EQ(std::memcmp(out[i].roughness.data(), roughness.data(), n * sizeof(float)), 0)
        << "room " << i;
    EXPECT_EQ(std::memcmp(out[i].mineral.data(), mineral.data(), n * sizeof(float)), 0)
        << "room " << i;
  }
  // The third world's own frequencies were used: world 42's give other channels at its positions.
  {
    const size_t n = out[2].positions.size();
    std::vector<float> roughness(n), mineral(n);
    mesh::detail_channels_reference(*mesh_, batch[2].origin, out[2].positions, roughness, mineral);
    EXPECT_NE(std::memcmp(out[2].roughness.data(), roughness.data(), n * sizeof(float)), 0);
    EXPECT_NE(std::memcmp(out[2].mineral.data(), mineral.data(), n * sizeof(float)), 0);
  }
  auto plain_created = DeformKernel::create(*device_, *mesh_);
  ASSERT_TRUE(plain_created.ok()) << plain_created.error().message;
  DeformKernel plain = std::move(plain_created).value();
  EXPECT_FALSE(plain.channels());
  ASSERT_TRUE(plain.run(std::span(batch).first(2), out).ok());
  EXPECT_TRUE(out[0].roughness.empty() && out[1].mineral.empty());
  // Eight lanes cannot carry the channels: refused, not built wrong.
  EXPECT_FALSE(DeformKernel::create(*device_, *mesh_, 8, 0, true).ok());
}

// A builder made for world 42 builds world 43's rooms as world 43's own CPU reference does (one
// builder per worker serves every world of a server), and refuses a world whose mesh parameters
// differ from its own (its kernel holds their shapes).
TEST_F(DeformKernelTest, room_builder_serves_another_world_with_its_mesh_parameters_only) {
  RoomBuilder builder = RoomBuilder::create(*mesh_, {DeviceConfig{.device = "auto"}});
  ASSERT_TRUE(builder.uses_opencl()) << builder.path();
  cave::World other_world = cave::World::create(43, cave::LayoutParams{}).value();
  auto other = mesh::MeshContext::create(other_world, mesh::MeshParams{}).value();
  cave::Region region = cave::generate_region(other_world, {0, 0, 0}, {0, 0, 0});
  std::vector<cave::Room> rooms(region.rooms.begin(), region.rooms.begin() + 6);
  auto meshes = builder.build(std::vector(rooms.size(), &other), rooms, mesh::Lod::kPatch);
  ASSERT_EQ(meshes.size(), rooms.size());
  for (size_t i = 0; i < rooms.size(); ++i) {
    ASSERT_TRUE(meshes[i].ok()) << meshes[i].error().message;
    mesh::RoomMesh cpu = mesh::build_room_mesh(other, rooms[i], mesh::Lod::kPatch).value();
    EXPECT_EQ(meshes[i]->indices, cpu.indices) << rooms[i].id.to_string();
    ASSERT_EQ(meshes[i]->vertex_count(), cpu.vertex_count());
    for (size_t v = 0; v < cpu.vertex_count(); ++v) {
      ASSERT_TRUE(same_bits(meshes[i]->positions[v].x, cpu.positions[v].x) &&
                  same_bits(meshes[i]->positions[v].y, cpu.positions[v].y) &&
                  same_bits(meshes[i]->positions[v].z, cpu.positions[v].z))
          << rooms[i].id.to_string() << " vertex " << v;
    }
  }
  EXPECT_EQ(builder.fallbacks(), 0u);

  mesh::MeshParams rougher;
  rougher.octave_amplitude[0] = 0.5;
  auto differs = mesh::MeshContext::create(other_world, rougher).value();
  auto refused = builder.build(std::vector(rooms.size(), &differs), rooms, mesh::Lod::kPatch);
  ASSERT_EQ(refused.size(), rooms.size());
  for (const auto& m : refused) {
    ASSERT_FALSE(m.ok());
    EXPECT_NE(m.error().message.find("mesh parameters"), std::string::npos) << m.error().message;
  }
}

TEST_F(DeformKernelTest, room_builder_falls_back_to_the_cpu_when_told_to) {
  RoomBuilder builder = RoomBuilder::create(*mesh_, {DeviceConfig{.device = "none"}});
  EXPECT_FALSE(builder.uses_opencl());
  EXPECT_NE(builder.path().find("cpu: "), std::string::npos);
  EXPECT_NE(builder.path().find("disabled by configuration"), std::string::npos) << builder.path();
  auto meshes = builder.build(std::span(region_->rooms).subspan(0, 3), mesh::Lod::kPatch);
  for (auto& m : meshes)
    EXPECT_TRUE(m.ok());
}

// Every room's mesh the same bits in `a` and `b` (both built, in the rooms' order).
void expect_same_meshes(const std::vector<Result<mesh::RoomMesh>>& a,
                        const std::vector<Result<mesh::RoomMesh>>& b,
                        std::span<const cave::Room> rooms, const std::string& what) {
  ASSERT_EQ(a.size(), rooms.size()) << what;
  ASSERT_EQ(b.size(), rooms.size()) << what;
  for (size_t i = 0; i < rooms.size(); ++i) {
    const std::string room = what + " " + rooms[i].id.to_string();
    ASSERT_TRUE(a[i].ok() && b[i].ok()) << room;
    EXPECT_EQ(b[i]->id, rooms[i].id) << room;
    EXPECT_EQ(a[i]->indices, b[i]->indices) << room;
    ASSERT_EQ(a[i]->vertex_count(), b[i]->vertex_count()) << room;
    for (size_t v = 0; v < a[i]->vertex_count(); ++v) {
      ASSERT_TRUE(same_bits(a[i]->positions[v].x, b[i]->positions[v].x) &&
                  same_bits(a[i]->normals[v].y, b[i]->normals[v].y) &&
                  same_bits(a[i]->roughness[v], b[i]->roughness[v]) &&
                  same_bits(a[i]->mineral[v], b[i]->mineral[v]))
          << room << " vertex " << v;
    }
  }
}

// Several threads per build (a whole cave at once) give every room the mesh one thread gives, on
// both paths and at both levels (detail rooms' channels come in several pieces), and keep the
// rooms in order.
TEST_F(DeformKernelTest, room_builder_threads_give_the_single_thread_meshes) {
  std::vector<cave::Room> rooms(region_->rooms.begin(), region_->rooms.begin() + 24);
  for (auto [device, lod] : {std::pair{"auto", mesh::Lod::kPatch},
                             {"none", mesh::Lod::kPatch},
                             {"auto", mesh::Lod::kDetail},
                             {"none", mesh::Lod::kDetail}}) {
    RoomBuilder one = RoomBuilder::create(*mesh_, {DeviceConfig{.device = device}, 1});
    RoomBuilder three = RoomBuilder::create(*mesh_, {DeviceConfig{.device = device}, 3});
    expect_same_meshes(one.build(rooms, lod), three.build(rooms, lod), rooms, device);
  }
}

// A region built as a pipeline (interior rooms while the sectors beyond the block are laid out,
// then the gates; from three threads) is generate_region's region with build()'s meshes, room for
// room, as is one laid out then built (one thread), on both paths: a block of two sectors, so
// gates inside it and on its faces.
TEST_F(DeformKernelTest, build_region_gives_the_region_and_its_rooms_meshes) {
  const cave::Region expected = cave::generate_region(*world_, {0, 0, 0}, {1, 0, 0});
  size_t gates = 0;
  for (const cave::Room& r : expected.rooms)
    gates += r.id.is_gate();
  ASSERT_GT(gates, 0u);
  ASSERT_LT(gates, expected.rooms.size());
  for (const char* device : {"auto", "none"}) {
    RoomBuilder reference = RoomBuilder::create(*mesh_, {DeviceConfig{.device = device}, 1});
    const auto meshes = reference.build(expected.rooms, mesh::Lod::kPatch);
    for (int threads : {1, 3, 5}) {
      RoomBuilder builder = RoomBuilder::create(*mesh_, {DeviceConfig{.device = device}, threads});
      RoomBuilder::BuiltRegion built =
          builder.build_region({0, 0, 0}, {1, 0, 0}, mesh::Lod::kPatch);
      const std::string what = std::string(device) + " " + std::to_string(threads) + " threads";
      EXPECT_EQ(cave::digest(built.region.rooms), cave::digest(expected.rooms)) << what;
      ASSERT_EQ(built.region.sectors.size(), 2u) << what;
      EXPECT_EQ(cave::digest(built.region.sectors[1].rooms),
                cave::digest(expected.sectors[1].rooms))
          << what;
      expect_same_meshes(meshes, built.meshes, expected.rooms, what);
    }
  }
}

// The child half of builds_rooms_on_the_cpu_without_any_opencl_platform (and meaningful on its
// own): whatever OpenCL offers, the builder builds every room and says which path it took.
TEST(RoomBuilderPath, builds_rooms_and_reports_its_path) {
  cave::World world = cave::World::create(42, cave::LayoutParams{}).value();
  mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
  cave::Region region = cave::generate_region(world, {0, 0, 0}, {0, 0, 0});
  RoomBuilder builder = RoomBuilder::create(ctx, {});
  auto meshes = builder.build(std::span(region.rooms).subspan(0, 3), mesh::Lod::kPatch);
  size_t built = 0;
  for (auto& m : meshes)
    built += m.ok();
  std::printf("builder_path=%s\nbuilder_built=%zu\n", builder.path().c_str(), built);
  EXPECT_EQ(built, 3u);
  EXPECT_TRUE(builder.path().rfind("opencl: ", 0) == 0 || builder.path().rfind("cpu: ", 0) == 0);
}

TEST(RoomBuilderFallback, builds_rooms_on_the_cpu_without_any_opencl_platform) {
  testing::ChildRun child = testing::run_self_without_opencl("RoomBuilderPath.*");
  const std::string& output = child.output;
  ASSERT_TRUE(child.exited) << output;
  EXPECT_EQ(child.exit_code, 0) << output;
  EXPECT_NE(output.find("builder_path=cpu: no OpenCL platform"), std::string::npos) << output;
  EXPECT_NE(output.find("builder_built=3"), std::string::npos) << output;
}

}  // namespace
}  // namespace grotto::kernels
