#!/usr/bin/env bash
# Protocol version 1 (normals sent by the server) against version 2 (normals derived by the
# client, codec::derive_normals): renders every gallery pose with --protocol 1 and with
# --protocol 2 (render.sh, relief on and off), and two poses looking across a portal's rim, then
# prints for each the share of pixels differing by more than 8/255 and the largest difference
# (pixdiff.py). Writes docs/GALLERY.md's comparison pictures to docs/images/gallery/protocol/
# (through pngquant, to 256 colours, where it is installed). ~2 minutes on 2 cores.
# Usage: bash docs/gallery/protocol.sh [build dir, default build] [work dir, default
#        /tmp/grotto-protocol]  (from the repository root)
set -euo pipefail
build=${1:-build}
work=${2:-/tmp/grotto-protocol}
pictures=docs/images/gallery/protocol
mkdir -p "$work/v1" "$work/v2" "$pictures"
for v in 1 2; do
  GALLERY_OUT=$work/v$v GALLERY_FLAGS="--protocol $v" bash docs/gallery/render.sh "$build" >/dev/null
done
# Across a rim: the eye at the centre of a portal's disc, looking along the portal's plane, so
# the rim is a straight line through the middle of the picture. dir h: level in the plane (normal
# x up), v: the plane's other way (normal x h); -h, -v the opposite ways.
across() {  # seed room to dir
  "$build/bin/grotto-layout" --seed "$1" --room "$2" 2>/dev/null | python3 -c "
import json, math, sys
to, way = sys.argv[1:3]
p = next(p for p in json.load(sys.stdin)['portals'] if p['to'] == to)
c, n = p['centre'], p['normal']
def unit(a):
    l = math.sqrt(sum(x * x for x in a))
    return [x / l for x in a]
h = unit([-n[2], 0.0, n[0]])  # level, in the portal's plane
u = h if way.endswith('h') else unit([n[1] * h[2] - n[2] * h[1], n[2] * h[0] - n[0] * h[2], n[0] * h[1] - n[1] * h[0]])
if way.startswith('-'):
    u = [-x for x in u]
yaw = math.degrees(math.atan2(u[0], -u[2]))
pitch = max(-85.0, min(85.0, math.degrees(math.asin(max(-1.0, min(1.0, u[1]))))))
print('%.3f,%.3f,%.3f,%.2f,%.2f' % (c[0], c[1], c[2], yaw, pitch))" "$3" "$4"
}
shoot_across() {  # name seed room to dir
  local name=$1 seed=$2 pose
  pose=$(across "$2" "$3" "$4" "$5")
  for v in 1 2; do
    for relief in on off; do
      local flags=()
      [[ $relief == off ]] && flags=(--no-displacement)
      xvfb-run -a -s "-screen 0 1280x1024x24" "$build/bin/grotto-client" --device none \
        --seed "$seed" --protocol $v --width 480 --height 270 --tess-max 8 --lod distance \
        --frames 3 --wait 120 --no-motion-blur --pose "$pose" \
        --screenshot "$work/v$v/$name-$relief.png" "${flags[@]}" >/dev/null
    done
  done
}
shoot_across rim-7 7 0.0.0.r0 0.0.0.r102 -v   # seed 7, from r0 into r102, looking up the plane
shoot_across rim-3 3 0.0.0.r86 0.0.0.r87 h    # seed 3, portal-3's widest portal, level
# Each cell: the share of pixels over 8/255 and the largest difference. --flythrough 3 of seed 7
# lands in one of two views from run to run (GALLERY.md), whatever the version: over 90 % there
# means the two runs saw different views, not different normals; run it again.
printf '%-16s %-22s %s\n' pose "relief off" "relief on"
for f in "$work"/v1/*-off.png; do
  name=$(basename "$f" -off.png)
  printf '%-16s %-22s %s\n' "$name" \
    "$(python3 docs/gallery/pixdiff.py "$work/v1/$name-off.png" "$work/v2/$name-off.png")" \
    "$(python3 docs/gallery/pixdiff.py "$work/v1/$name-on.png" "$work/v2/$name-on.png")"
done
# GALLERY.md's table: version 1, version 2 and the differing pixels in red.
for shot in portal-3-off tunnel-7-off rim-7-off rim-7-on; do
  python3 docs/gallery/pixdiff.py "$work/v1/$shot.png" "$work/v2/$shot.png" \
    --overlay "$work/$shot-diff.png" >/dev/null
  for pair in "v1/$shot.png:$shot-v1.png" "v2/$shot.png:$shot-v2.png" "$shot-diff.png:$shot-diff.png"; do
    if command -v pngquant >/dev/null; then
      pngquant --force --speed 1 --output "$pictures/${pair#*:}" 256 "$work/${pair%%:*}"
    else
      cp "$work/${pair%%:*}" "$pictures/${pair#*:}"
    fi
  done
done
