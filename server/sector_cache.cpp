#include "server/sector_cache.hpp"

#include <cassert>

namespace grotto::server {

using cave::RoomId;
using cave::SectorLayout;

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

cave::SectorSource SectorCache::source() {
  return [this](cave::SectorCoord s) { return sector(s); };
}

Result<cave::Room> SectorCache::room(RoomId id) {
  return cave::room(world_, id, source());
}

std::optional<RoomId> SectorCache::locate(Vec3 point) {
  return cave::locate(world_, point, source());
}

cave::Spawn SectorCache::spawn() {
  return cave::spawn(world_, source());
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
