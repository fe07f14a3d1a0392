// Sector layouts kept in a bounded LRU, so that the rooms, locate and spawn of the generation
// service cost one generate_sector per sector instead of one per room (cave::room regenerates
// the sector, ~0.5-1 ms, on every call). The cache only keeps sectors: its answers are the
// cave's own functions (cave::room / cave::locate / cave::spawn) run over the cached layouts
// through a cave::SectorSource (tests pin the equality with the uncached forms).
//
// The layouts live in a SectorStore, which several worlds' caches may share: one LRU bounded in
// layouts, keyed by world and sector, so a busy world takes more of it than an idle one.
//
// Thread safety: every member may be called from any thread. Layouts are generated outside the
// lock; two threads missing the same sector at once both generate it (same bytes), one is kept.
#pragma once

#include <cstddef>
#include <cstdint>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>

#include "common/cave/layout.hpp"
#include "common/core/result.hpp"
#include "proto/messages.hpp"

namespace grotto::server {

class SectorStore {
 public:
  // capacity: layouts kept, all worlds together; 0 keeps none (every call generates).
  explicit SectorStore(size_t capacity) : capacity_(capacity) {}

  size_t hits() const;
  size_t misses() const;
  size_t size() const;

 private:
  friend class SectorCache;
  using Key = std::pair<uint64_t, cave::SectorCoord>;  // (world seed, sector)
  using Entry = std::pair<Key, std::shared_ptr<const cave::SectorLayout>>;
  size_t capacity_;
  mutable std::mutex mutex_;
  std::list<Entry> lru_;  // most recent first
  std::map<Key, std::list<Entry>::iterator> index_;
  size_t hits_ = 0;
  size_t misses_ = 0;
};

class SectorCache {
 public:
  // A cache of its own: capacity layouts; 0 keeps none (every call generates).
  SectorCache(const cave::World& world, size_t capacity);
  // A cache whose layouts live in `store`, beside other worlds'. Worlds sharing a store must
  // differ in seed and share layout parameters.
  SectorCache(const cave::World& world, std::shared_ptr<SectorStore> store);

  // cave::room(world, id). Errors: kNotFound for a well-formed id that names no room (also a
  // gate on the world's edge); kInternal for a sector that could not link its gates.
  Result<cave::Room> room(cave::RoomId id);
  // cave::locate(world, point).
  std::optional<cave::RoomId> locate(Vec3 point);
  // cave::spawn(world): spawn_room's room and a position inside its space (interior_point).
  cave::Spawn spawn();

  // The layout of an in-range sector, from the cache or generated now.
  std::shared_ptr<const cave::SectorLayout> sector(cave::SectorCoord s);
  // sector() as a source for the cave's functions; valid while this cache lives.
  cave::SectorSource source();

  // The store's counts (all worlds sharing it).
  size_t hits() const { return store_->hits(); }
  size_t misses() const { return store_->misses(); }
  size_t size() const { return store_->size(); }
  const std::shared_ptr<SectorStore>& store() const { return store_; }

 private:
  cave::World world_;
  std::shared_ptr<SectorStore> store_;
};

}  // namespace grotto::server
