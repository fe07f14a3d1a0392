#include "client/stream/room_store.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <tuple>

namespace grotto::stream {
namespace {

template <typename T>
size_t capacity_bytes(const std::vector<T>& v) {
  return v.capacity() * sizeof(T);
}

}  // namespace

size_t ReadyRoom::memory_bytes() const {
  // Capacity, not size: what the allocator holds is what the budget is for.
  return sizeof(ReadyRoom) + capacity_bytes(room.portals) + capacity_bytes(mesh.positions) +
         capacity_bytes(mesh.normals) + capacity_bytes(mesh.roughness) +
         capacity_bytes(mesh.mineral) + capacity_bytes(mesh.rim_portal) +
         capacity_bytes(mesh.rim_index) + capacity_bytes(mesh.indices);
}

void RoomStore::insert(std::shared_ptr<const ReadyRoom> room) {
  assert(room);
  erase(room->room.id);
  bytes_ += room->memory_bytes();
  const cave::RoomId id = room->room.id;
  rooms_.emplace(id, std::move(room));
}

std::shared_ptr<const ReadyRoom> RoomStore::find(cave::RoomId id) const {
  auto it = rooms_.find(id);
  return it == rooms_.end() ? nullptr : it->second;
}

void RoomStore::erase(cave::RoomId id) {
  auto it = rooms_.find(id);
  if (it == rooms_.end()) return;
  // ReadyRoom is immutable once stored, so this is the figure insert() added.
  bytes_ -= it->second->memory_bytes();
  rooms_.erase(it);
}

void RoomStore::clear() {
  rooms_.clear();
  bytes_ = 0;
}

std::vector<cave::RoomId> RoomStore::evict(Vec3 position, const std::set<cave::RoomId>& keep) {
  std::vector<cave::RoomId> evicted;
  if (bytes_ <= max_bytes_) return evicted;
  // Candidates farthest first (distance to the sphere's surface, negative inside it), ties by id.
  std::vector<std::pair<double, cave::RoomId>> candidates;
  for (const auto& [id, room] : rooms_) {
    if (keep.count(id)) continue;
    const cave::Sphere& s = room->room.sphere;
    double d = distance(position, s.centre) - s.radius;
    candidates.push_back({std::isnan(d) ? 0.0 : d, id});  // NaN would break the sort's order
  }
  std::sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) {
    return std::tie(b.first, a.second) < std::tie(a.first, b.second);
  });
  for (const auto& [d, id] : candidates) {
    if (bytes_ <= max_bytes_) break;
    erase(id);
    evicted.push_back(id);
  }
  return evicted;
}

std::vector<cave::RoomId> RoomStore::ids() const {
  std::vector<cave::RoomId> out;
  out.reserve(rooms_.size());
  for (const auto& [id, room] : rooms_)
    out.push_back(id);
  return out;
}

}  // namespace grotto::stream
