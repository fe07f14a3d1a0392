/* The room deformation of thesis §4.2, batched (§4.2.1: the fixed cost of a launch made small
 * rooms expensive, so one launch deforms many rooms). One work item per group of GROTTO_LANES
 * donor vertices of one room (the host pads each room to whole groups). A work item finds its
 * room in the room table (binary search over the rooms' first vertices: the host uploads no
 * per-vertex index) and its directions among the donors', which stay on the device from launch to
 * launch (one copy per donor sphere, whatever the rooms using it). Room, portal and shape tables
 * live in __constant memory, as in the thesis. Directions and results are stored per group as
 * x[LANES] y[LANES] z[LANES]. Each room record carries its world's noise seed, so one launch
 * serves rooms of many worlds. Built after deform_prelude.cl and deform_core.h.
 *
 * With GROTTO_CHANNELS (one lane; after channels_core.cl) a work item also computes its vertex's
 * detail channels from the position it deformed, which is the position the finished mesh keeps
 * (the per-vertex stages stay on the device, with no second launch). `room_channels` holds six
 * doubles a room: the mesh origin and its world's channel frequencies. */
#if defined(GROTTO_CHANNELS) && GROTTO_LANES != 1
#error "GROTTO_CHANNELS needs GROTTO_LANES 1"
#endif
__kernel void grotto_deform_rooms(__constant const GrottoShape* shapes,
                                  __constant const GrottoRoom* rooms, uint room_count,
                                  __constant const GrottoPortal* portals,
                                  __global const float* directions, __global float* positions,
                                  __global float* clearance, uint group_count
#ifdef GROTTO_CHANNELS
                                  ,
                                  __global const double* room_channels, __global float* roughness,
                                  __global float* mineral
#endif
) {
  uint g = get_global_id(0);
  if (g >= group_count) return;
  /* The last room whose first vertex is at or before this group's. Rooms are in batch order; an
   * empty room shares its first vertex with the next one and is never picked. */
  const uint v = g * GROTTO_LANES;
  uint lo = 0, hi = room_count - 1;
  while (lo < hi) {
    const uint mid = (lo + hi + 1) / 2;
    if (rooms[mid].first_vertex <= v) {
      lo = mid;
    } else {
      hi = mid - 1;
    }
  }
  __constant const GrottoRoom* room = rooms + lo;
  __global const float* d =
      directions +
      3 * GROTTO_LANES * (room->first_direction + (v - room->first_vertex) / GROTTO_LANES);
  gfloat3 dir;
  dir.x = GROTTO_LOAD(d);
  dir.y = GROTTO_LOAD(d + GROTTO_LANES);
  dir.z = GROTTO_LOAD(d + 2 * GROTTO_LANES);
  gfloat least;
  gfloat3 p = grotto_deform_vertex(room->noise_seed, shapes + room->lod, room,
                                   portals + room->first_portal, dir, &least);
  __global float* out = positions + 3 * GROTTO_LANES * g;
  GROTTO_STORE(p.x, out);
  GROTTO_STORE(p.y, out + GROTTO_LANES);
  GROTTO_STORE(p.z, out + 2 * GROTTO_LANES);
  GROTTO_STORE(least, clearance + GROTTO_LANES * g);
#ifdef GROTTO_CHANNELS
  grotto_detail_channels_at(room_channels + 6 * lo, room->noise_seed, p, roughness + g,
                            mineral + g);
#endif
}
