#include "server/sector_cache.hpp"

#include <algorithm>
#include <cassert>

namespace grotto::server {
namespace {

using cave::Room;
using cave::RoomId;
using cave::SectorLayout;

const Room* find_room(const std::vector<Room>& rooms, RoomId id) {
  auto it = std::lower_bound(rooms.begin(), rooms.end(), id,
                             [](const Room& r, RoomId key) { return r.id < key; });
  return it != rooms.end() && it->id == id ? &*it : nullptr;
}

// As cave/layout.cpp's merge_gate: a gate's portals on both sides of its face.
Room merge_gate(const Room& lower_side, const Room& upper_side) {
  Room out = lower_side;
  out.portals.insert(out.portals.end(), upper_side.portals.begin(), upper_side.portals.end());
  std::sort(out.portals.begin(), out.portals.end(),
            [](const cave::Portal& p, const cave::Portal& q) { return p.neighbour < q.neighbour; });
  return out;
}

Error disconnected(cave::SectorCoord s) {
  return Error{ErrorCode::kInternal, "sector " + cave::to_string(s) +
                                         " could not link its gates; its rooms are unavailable"};
}

}  // namespace

SectorCache::SectorCache(const cave::World& world, size_t capacity)
    : SectorCache(world, std::make_shared<SectorStore>(capacity)) {}

SectorCache::SectorCache(const cave::World& world, std::shared_ptr<SectorStore> store)
    : world_(world), store_(std::move(store)) {}

std::shared_ptr<const SectorLayout> SectorCache::sector(cave::SectorCoord s) {
  assert(cave::in_range(s));
  SectorStore& st = *store_;
  const SectorStore::Key key{world_.seed(), s};
  {
    std::lock_guard lock(st.mutex_);
    auto it = st.index_.find(key);
    if (it != st.index_.end()) {
      ++st.hits_;
      st.lru_.splice(st.lru_.begin(), st.lru_, it->second);
      return it->second->second;
    }
    ++st.misses_;
  }
  auto layout = std::make_shared<const SectorLayout>(cave::generate_sector(world_, s));
  if (st.capacity_ == 0) return layout;
  std::lock_guard lock(st.mutex_);
  if (auto it = st.index_.find(key); it != st.index_.end()) return it->second->second;
  st.lru_.emplace_front(key, layout);
  st.index_[key] = st.lru_.begin();
  while (st.lru_.size() > st.capacity_) {
    st.index_.erase(st.lru_.back().first);
    st.lru_.pop_back();
  }
  return layout;
}

Result<Room> SectorCache::room(RoomId id) {
  cave::SectorCoord s = id.sector();
  if (!id.is_gate()) {
    auto layout = sector(s);
    if (!layout->connected) return disconnected(s);
    if (id.index() >= static_cast<int>(layout->rooms.size())) {
      return not_found("room " + id.to_string() + " does not exist: sector " + cave::to_string(s) +
                       " has " + std::to_string(layout->rooms.size()) + " interior rooms");
    }
    return layout->rooms[id.index()];
  }
  cave::SectorCoord upper_coord = cave::neighbour(s, id.gate_axis(), 1);
  if (!cave::in_range(upper_coord)) {
    return not_found("room " + id.to_string() + " does not exist: the world's edge has no gates");
  }
  auto lower = sector(s);
  // The lower sector's gate list holds every gate of this face: absent there, absent everywhere.
  const Room* a = find_room(lower->gates, id);
  if (!a) return not_found("room " + id.to_string() + " does not exist: no such gate on its face");
  auto upper = sector(upper_coord);
  if (!lower->connected) return disconnected(lower->sector);
  if (!upper->connected) return disconnected(upper->sector);
  const Room* b = find_room(upper->gates, id);
  assert(b);
  if (!b) return Error{ErrorCode::kInternal, "gate " + id.to_string() + " missing upstairs"};
  return merge_gate(*a, *b);
}

std::optional<RoomId> SectorCache::locate(Vec3 point) {
  if (!is_finite(point)) return std::nullopt;
  cave::SectorCoord s = cave::sector_of(world_, point);
  if (!cave::in_range(s)) return std::nullopt;
  auto layout = sector(s);
  // Only this sector's side of a gate matters: portals on the other side lie in the other sector.
  std::optional<RoomId> best;
  auto consider = [&](const Room& r) {
    if (cave::in_space(r, point) && (!best || r.id < *best)) best = r.id;
  };
  for (const Room& r : layout->rooms)
    consider(r);
  for (const Room& r : layout->gates)
    consider(r);
  return best;
}

proto::SpawnPoint SectorCache::spawn() {
  auto layout = sector({0, 0, 0});
  double half = 0.5 * world_.params().sector_size;
  Vec3 centre{half, half, half};
  const Room* best = nullptr;
  for (const Room& r : layout->rooms) {
    if (!best ||
        length_squared(r.sphere.centre - centre) < length_squared(best->sphere.centre - centre)) {
      best = &r;
    }
  }
  assert(best);  // a sector always links its gates with at least one interior room
  if (!best) best = &layout->gates.front();
  proto::SpawnPoint out;
  out.room = best->id;
  out.position = cave::interior_point(*best);
  return out;
}

size_t SectorStore::hits() const {
  std::lock_guard lock(mutex_);
  return hits_;
}
size_t SectorStore::misses() const {
  std::lock_guard lock(mutex_);
  return misses_;
}
size_t SectorStore::size() const {
  std::lock_guard lock(mutex_);
  return lru_.size();
}

}  // namespace grotto::server
