// Encoded room frames kept in an LRU bounded in bytes (the generator's cache; hits are served
// without the worker pool). Not thread-safe: the generator calls it under its lock.
#pragma once

#include <cstddef>
#include <list>
#include <map>

#include "server/rooms.hpp"

namespace grotto::server {

struct RoomKeyLess {
  bool operator()(const RoomKey& a, const RoomKey& b) const {
    if (a.id != b.id) return a.id < b.id;  // a room's keys are adjacent (cancel relies on it)
    if (a.lod != b.lod) return a.lod < b.lod;
    return a.seed != b.seed ? a.seed < b.seed : a.version < b.version;
  }
};

class RoomCache {
 public:
  // max_bytes: frame bytes kept; 0 keeps nothing.
  explicit RoomCache(size_t max_bytes) : max_bytes_(max_bytes) {}

  // The room, made the most recently used; null when not cached.
  RoomPtr find(const RoomKey& key);
  // Keeps the room (replacing one with its key), then evicts the least recently used rooms
  // until the total is within max_bytes. A room larger than max_bytes is not kept.
  void insert(RoomPtr room);

  size_t bytes() const { return bytes_; }
  size_t entries() const { return lru_.size(); }
  size_t max_bytes() const { return max_bytes_; }
  size_t evictions() const { return evictions_; }

 private:
  void erase(std::list<RoomPtr>::iterator it);

  size_t max_bytes_;
  size_t bytes_ = 0;
  size_t evictions_ = 0;
  std::list<RoomPtr> lru_;  // most recent first
  std::map<RoomKey, std::list<RoomPtr>::iterator, RoomKeyLess> index_;
};

}  // namespace grotto::server
