/* The room deformation of thesis §4.2, batched (§4.2.1: the fixed cost of a launch made small
 * rooms expensive, so one launch deforms many rooms). One work item per donor vertex; each
 * vertex knows its room. Room, portal and shape tables and Perlin's permutation live in
 * __constant memory, as in the thesis. Built after deform_prelude.cl and deform_core.h. */
__kernel void grotto_deform_rooms(__constant const unsigned char* perm,
                                  __constant const GrottoShape* shapes,
                                  __constant const GrottoRoom* rooms,
                                  __constant const GrottoPortal* portals,
                                  __global const uint* vertex_room,
                                  __global const float* directions, __global float* positions,
                                  __global float* clearance, uint vertex_count) {
  uint i = get_global_id(0);
  if (i >= vertex_count) return;
  __constant const GrottoRoom* room = rooms + vertex_room[i];
  float3 dir = vload3(i, directions);
  float least;
  float3 p = grotto_deform_vertex(perm, shapes + room->lod, room, portals + room->first_portal, dir,
                                  &least);
  vstore3(p, i, positions);
  clearance[i] = least;
}
