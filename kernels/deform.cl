/* The room deformation of thesis §4.2, batched (§4.2.1: the fixed cost of a launch made small
 * rooms expensive, so one launch deforms many rooms). One work item per group of GROTTO_LANES
 * donor vertices of one room (the host pads each room to whole groups); each group knows its
 * room and its group of the donor's directions, which stay on the device from launch to launch
 * (one copy per donor sphere, whatever the rooms using it). Room, portal and shape tables live in
 * __constant memory, as in the thesis. Directions and results are stored per group as x[LANES]
 * y[LANES] z[LANES]. Each room record carries its
 * world's noise seed, so one launch serves rooms of many worlds. Built after deform_prelude.cl
 * and deform_core.h. */
__kernel void grotto_deform_rooms(__constant const GrottoShape* shapes,
                                  __constant const GrottoRoom* rooms,
                                  __constant const GrottoPortal* portals,
                                  __global const uint* group_room, __global const uint* group_dir,
                                  __global const float* directions, __global float* positions,
                                  __global float* clearance, uint group_count) {
  uint g = get_global_id(0);
  if (g >= group_count) return;
  __constant const GrottoRoom* room = rooms + group_room[g];
  __global const float* d = directions + 3 * GROTTO_LANES * group_dir[g];
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
}
