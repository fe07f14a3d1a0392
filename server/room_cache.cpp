#include "server/room_cache.hpp"

#include <cassert>

namespace grotto::server {

RoomPtr RoomCache::find(const RoomKey& key) {
  auto it = index_.find(key);
  if (it == index_.end()) return nullptr;
  lru_.splice(lru_.begin(), lru_, it->second);
  return *it->second;
}

void RoomCache::insert(RoomPtr room) {
  assert(room);
  size_t size = room->frame.size();
  if (size > max_bytes_) return;
  if (auto it = index_.find(room->key); it != index_.end()) erase(it->second);
  lru_.push_front(room);
  index_[room->key] = lru_.begin();
  bytes_ += size;
  while (bytes_ > max_bytes_) {
    erase(std::prev(lru_.end()));
    ++evictions_;
  }
}

void RoomCache::erase(std::list<RoomPtr>::iterator it) {
  bytes_ -= (*it)->frame.size();
  index_.erase((*it)->key);
  lru_.erase(it);
}

}  // namespace grotto::server
