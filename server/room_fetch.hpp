// One room for a caller that is not a player's WebSocket session: an HTTP GET of the room's URL
// (PROTOCOL.md, "Rooms over HTTP"), and a replica's owner fetch answered by that GET. The room goes
// through the generator like any want: its queue at `priority` (urgent or not by the same
// deadline rule), single flight with every player waiting for it, and the cache. No sockets here.
#pragma once

#include <cstdint>
#include <functional>

#include "common/core/result.hpp"
#include "server/generator.hpp"
#include "server/rooms.hpp"

namespace grotto::server {

// Runs a closure later, on a thread that is neither a generator worker nor inside a delivery
// callback (an Asio strand's post). It may drop the closure once the server is stopping.
using PostFn = std::function<void(std::function<void()>)>;
// The outcome: the room's frame (EncodedRoom::frame, the bytes a WebSocket room frame carries),
// or the generator's error: world_mismatch (a seed this server does not serve), overloaded (no
// world free, or the job waited past its deadline), not_found, internal, service_restart,
// invalid_argument (a lod above kMaxServedLod).
using RoomDoneFn = std::function<void(Result<RoomPtr>)>;

// Asks `generator` for the room `key` (world, lod, protocol version) as a want of `priority`
// (milliseconds until it is needed, as in a request), from wherever `build` allows: an HTTP GET
// of a room URL is Build::kHere, since in a cluster it is the room tier asking this replica as
// the room's owner (asking the tier again would come back here). `done` runs exactly once through
// `post` (never inside fetch_room, never on a generator worker), unless `post` drops it at
// shutdown. The caller checks the key against what the server serves (version spoken, params
// digest, max_lod) first. Thread-safe; `generator` must outlive the posted closure.
void fetch_room(Generator& generator, const RoomKey& key, uint32_t priority, Build build,
                PostFn post, RoomDoneFn done);

}  // namespace grotto::server
