// Determinism is a feature: the same seed gives the same rooms in any order, in any process.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "common/cave/layout.hpp"
#include "common/core/random.hpp"

namespace grotto::cave {
namespace {

World test_world(uint64_t seed = 42) {
  return World::create(seed, LayoutParams{}).value();
}

std::vector<SectorCoord> block(int lo, int hi) {
  std::vector<SectorCoord> out;
  for (int x = lo; x <= hi; ++x)
    for (int y = lo; y <= hi; ++y)
      for (int z = lo; z <= hi; ++z)
        out.push_back({x, y, z});
  return out;
}

// Digest of every sector of the block, generated in the given order but hashed in x-major
// order, so only the content can change the result.
uint64_t block_digest(const World& world, std::vector<SectorCoord> order) {
  std::vector<std::pair<SectorCoord, uint64_t>> parts;
  for (SectorCoord s : order) {
    SectorLayout layout = generate_sector(world, s);
    std::vector<Room> rooms = layout.rooms;
    rooms.insert(rooms.end(), layout.gates.begin(), layout.gates.end());
    parts.push_back({s, digest(rooms)});
  }
  std::sort(parts.begin(), parts.end());
  uint64_t h = 0;
  for (auto& [s, d] : parts)
    h = hash_combine(h, d);
  return h;
}

void shuffle(std::vector<SectorCoord>& v, uint64_t seed) {
  Rng rng(seed);
  for (size_t i = v.size(); i > 1; --i)
    std::swap(v[i - 1], v[rng.below(static_cast<uint32_t>(i))]);
}

// Also the child half of two_processes_agree: it prints the digest, and the parent passes the
// shuffle seed in GROTTO_ORDER_SEED so the child generates in an order of the parent's choosing.
TEST(LayoutDeterminism, sectors_are_identical_in_any_generation_order) {
  World world = test_world();
  std::vector<SectorCoord> order = block(-1, 1);
  uint64_t forward = block_digest(world, order);
  std::reverse(order.begin(), order.end());
  EXPECT_EQ(block_digest(world, order), forward);
  const char* order_seed = std::getenv("GROTTO_ORDER_SEED");
  shuffle(order, order_seed ? std::strtoull(order_seed, nullptr, 10) : 7);
  uint64_t shuffled = block_digest(world, order);
  EXPECT_EQ(shuffled, forward);
  std::printf("digest=%llu\n", static_cast<unsigned long long>(shuffled));
}

TEST(LayoutDeterminism, rooms_are_identical_however_they_are_reached) {
  World world = test_world();
  Region region = generate_region(world, {0, 0, 0}, {1, 1, 1});
  std::vector<Room> sample;
  for (size_t i = 0; i < region.rooms.size(); i += 17)
    sample.push_back(region.rooms[i]);
  std::reverse(sample.begin(), sample.end());
  for (const Room& expected : sample) {
    auto r = room(world, expected.id);
    ASSERT_TRUE(r.ok()) << r.error().message;
    std::vector<unsigned char> a, b;
    append_bytes(expected, a);
    append_bytes(*r, b);
    EXPECT_EQ(a, b) << expected.id.to_string();
  }
}

TEST(LayoutDeterminism, different_seeds_give_different_caves) {
  EXPECT_NE(block_digest(test_world(1), block(0, 0)), block_digest(test_world(2), block(0, 0)));
}

TEST(LayoutDeterminism, two_processes_agree) {
  std::string self = std::filesystem::read_symlink("/proc/self/exe");
  std::string cmd =
      "GROTTO_ORDER_SEED=12345 '" + self +
      "' --gtest_filter=LayoutDeterminism.sectors_are_identical_in_any_generation_order";
  FILE* child = popen(cmd.c_str(), "r");
  ASSERT_NE(child, nullptr);
  char line[512];
  unsigned long long child_digest = 0;
  bool found = false;
  while (std::fgets(line, sizeof line, child)) {
    if (std::sscanf(line, "digest=%llu", &child_digest) == 1) found = true;
  }
  ASSERT_EQ(pclose(child), 0);
  ASSERT_TRUE(found) << "the child printed no digest";
  EXPECT_EQ(child_digest, block_digest(test_world(), block(-1, 1)));
}

// A checked-in digest: any change to the layout algorithm, its parameters' defaults or the
// PRNG shows up here. When a change is intended, update the constant and say so in the commit.
TEST(LayoutDeterminism, golden_digest_for_seed_42) {
  World world = test_world(42);
  Region region = generate_region(world, {0, 0, 0}, {1, 1, 1});
  // Changed by halls (a sector's hub, from a stream of its own) and floors (no portal
  // of a room with a floor opens below it); then ceilings (no portal above a hall's spring) and
  // halls up to 34 m radius, and the spawn at a hall's entrance instead of in the hall.
  EXPECT_EQ(digest(region.rooms), 0x5b46bd8d588a985bull)
      << std::hex << "0x" << digest(region.rooms);
  EXPECT_EQ(spawn_room(world).to_string(), "0.0.0.r25");
}

// Laid out on several threads, a region is the same bytes as on one: its sectors and the sectors
// beyond its faces, in any order.
TEST(LayoutDeterminism, a_region_laid_out_on_threads_is_the_same) {
  World world = test_world(42);
  const Region one = generate_region(world, {0, 0, 0}, {1, 1, 1});
  for (int threads : {2, 5}) {
    const Region many = generate_region(world, {0, 0, 0}, {1, 1, 1}, threads);
    EXPECT_EQ(digest(many.rooms), digest(one.rooms)) << threads << " threads";
    ASSERT_EQ(many.sectors.size(), one.sectors.size());
    for (size_t i = 0; i < one.sectors.size(); ++i)
      EXPECT_EQ(digest(many.sectors[i].rooms), digest(one.sectors[i].rooms));
  }
}

}  // namespace
}  // namespace grotto::cave
