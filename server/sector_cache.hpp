// Sector layouts kept in a bounded LRU, so that the rooms, locate and spawn of the generation
// service cost one generate_sector per sector instead of one per room (cave::room regenerates
// the sector, ~0.5-1 ms, on every call). Answers are those of cave::room / cave::locate /
// cave::spawn_room, computed from the cached layouts (tests pin the equality).
//
// Thread safety: every member may be called from any thread. Layouts are generated outside the
// lock; two threads missing the same sector at once both generate it (same bytes), one is kept.
#pragma once

#include <cstddef>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <optional>

#include "cave/layout.hpp"
#include "core/result.hpp"
#include "proto/messages.hpp"

namespace grotto::server {

class SectorCache {
 public:
  // capacity: layouts kept; 0 keeps none (every call generates).
  SectorCache(const cave::World& world, size_t capacity);

  // cave::room(world, id). Errors: kNotFound for a well-formed id that names no room (also a
  // gate on the world's edge); kInternal for a sector that could not link its gates.
  Result<cave::Room> room(cave::RoomId id);
  // cave::locate(world, point).
  std::optional<cave::RoomId> locate(Vec3 point);
  // cave::spawn_room(world) and a position inside that room's space (its sphere's centre, moved
  // back behind any portal plane it lies beyond).
  proto::SpawnPoint spawn();

  // The layout of an in-range sector, from the cache or generated now.
  std::shared_ptr<const cave::SectorLayout> sector(cave::SectorCoord s);

  size_t hits() const;
  size_t misses() const;
  size_t size() const;

 private:
  using Entry = std::pair<cave::SectorCoord, std::shared_ptr<const cave::SectorLayout>>;
  cave::World world_;
  size_t capacity_;
  mutable std::mutex mutex_;
  std::list<Entry> lru_;  // most recent first
  std::map<cave::SectorCoord, std::list<Entry>::iterator> index_;
  size_t hits_ = 0;
  size_t misses_ = 0;
};

}  // namespace grotto::server
