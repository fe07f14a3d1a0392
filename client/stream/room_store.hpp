// The rooms a client holds decoded and ready to draw, bounded in memory: when over its budget it
// evicts the rooms farthest from the player that the current plan does not want. Not thread-safe
// (Stream guards its store with a mutex); ReadyRoom is immutable once stored and shared, so a
// renderer may keep using a room after it was evicted.
#pragma once
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/codec/room_codec.hpp"
#include "common/core/vec3.hpp"

namespace grotto::stream {

// One decoded room: its descriptor from the frame and its mesh. World position of vertex i is
// origin + mesh.positions[i], computed in double (PROTOCOL.md "World coordinates").
struct ReadyRoom {
  cave::Room room;
  uint8_t lod = 0;  // wire lod
  Vec3 origin;
  codec::DecodedRoom mesh;
  size_t payload_bytes = 0;  // Draco bytes received
  double decode_ms = 0;      // time decode_room took on a worker
  // What the room holds in memory (mesh arrays and descriptor), the unit of the store's budget.
  size_t memory_bytes() const;
};

class RoomStore {
 public:
  explicit RoomStore(size_t max_bytes) : max_bytes_(max_bytes) {}
  // Adds or replaces the room with the same id.
  void insert(std::shared_ptr<const ReadyRoom> room);
  std::shared_ptr<const ReadyRoom> find(cave::RoomId id) const;  // nullptr when absent
  bool contains(cave::RoomId id) const { return rooms_.count(id) != 0; }
  void erase(cave::RoomId id);
  void clear();
  // While over max_bytes, evicts the room whose sphere is farthest from `position` (distance to
  // the sphere's surface, ties by id), never one in `keep`. Returns the evicted ids, farthest
  // first. The store may stay over budget when `keep` alone exceeds it.
  std::vector<cave::RoomId> evict(Vec3 position, const std::set<cave::RoomId>& keep);
  size_t bytes() const { return bytes_; }
  size_t size() const { return rooms_.size(); }
  size_t max_bytes() const { return max_bytes_; }
  std::vector<cave::RoomId> ids() const;

 private:
  size_t max_bytes_;
  size_t bytes_ = 0;
  std::map<cave::RoomId, std::shared_ptr<const ReadyRoom>> rooms_;
};

}  // namespace grotto::stream
