#!/usr/bin/env bash
# Renders docs/GALLERY.md's pictures: each pose with the relief on and off (--no-displacement; the
# last poses with and without the fine detail or the ambient occlusion instead),
# through EGL (no window system: Mesa's llvmpipe here, a GPU's driver where there is one), from an
# in-process server (CPU reference). About 4 s a picture at 1920x1080 on llvmpipe.
# Usage: bash docs/gallery/render.sh [build dir, default build]  (from the repository root)
# GALLERY_OUT (default docs/images/gallery2; docs/images/gallery holds the 480x270 renders of the
# world before it had halls) is where the pictures go, as JPEG when cjpeg is installed (Debian's
# libjpeg-turbo-progs; a 1080p PNG is ~2 MB, its JPEG a tenth), else PNG; GALLERY_SIZE (default
# 1920x1080) their size; GALLERY_FLAGS, more client flags for every picture (docs/gallery/
# protocol.sh passes --protocol 1 or 2); GALLERY_ONLY, a pose name to render alone.
set -euo pipefail
build=${1:-build}
out=${GALLERY_OUT:-docs/images/gallery2}
here=$(dirname "$0")
size=${GALLERY_SIZE:-1920x1080}
only=${GALLERY_ONLY:-}
read -r -a more <<< "${GALLERY_FLAGS:-}"
mkdir -p "$out"
client="$build/bin/grotto-client"
layout="$build/bin/grotto-layout"
# A pose in a room from the layout: pose seed room kind [args]
#   centre dy yaw pitch   the sphere centre raised by dy radii
#   floor yaw pitch       1.7 m above the room's floor below the centre
#   across yaw pitch      0.6 radii from the centre, on the side opposite the yaw
#   along                 the centre, looking from the first portal towards the second
#   entrance              1.5 m inside the lowest portal, looking into the room
pose() {
  "$layout" --seed "$1" --room "$2" 2>/dev/null | python3 -c "
import json, math, sys
r = json.load(sys.stdin)
c, R, kind, a = r['centre'], r['radius'], sys.argv[1], [float(x) for x in sys.argv[2:]]
def look(d):
    n = math.sqrt(sum(x * x for x in d))
    d = [x / n for x in d]
    return math.degrees(math.atan2(d[0], -d[2])), math.degrees(math.asin(d[1]))
if kind == 'centre':
    p, yaw, pitch = [c[0], c[1] + a[0] * R, c[2]], a[1], a[2]
elif kind == 'floor':
    p, yaw, pitch = [c[0], c[1] - 0.2 * R + 1.7, c[2]], a[0], a[1]
elif kind == 'across':
    y = math.radians(a[0])
    p, yaw, pitch = [c[0] - 0.6 * R * math.sin(y), c[1], c[2] + 0.6 * R * math.cos(y)], a[0], a[1]
elif kind == 'along':
    p0, p1 = r['portals'][0]['centre'], r['portals'][1]['centre']
    p = c
    yaw, pitch = look([p1[i] - p0[i] for i in range(3)])
elif kind == 'entrance':
    q = min(r['portals'], key=lambda q: q['centre'][1])
    n = q['normal']
    p = [q['centre'][i] - 1.5 * n[i] for i in range(3)]
    yaw, pitch = look([-x for x in n])
print('%.2f,%.2f,%.2f,%.1f,%.1f' % (p[0], p[1], p[2], yaw, pitch))" "${@:3}"
}
shoot() {  # name seed extra-args...; OFF=flag: what the -off picture leaves out (default: the relief)
  local name=$1 seed=$2 off=${OFF:---no-displacement}
  shift 2
  [[ -n $only && $only != "$name" ]] && return 0
  for relief in on off; do
    local flags=()
    [[ $relief == off ]] && flags=("$off")
    "$client" --gl egl --device none --seed "$seed" --width "${size%x*}" --height "${size#*x}" \
      --tess-max 8 --lod distance --frames 3 --wait 120 --no-motion-blur --mode fly \
      --screenshot "$out/$name-$relief.png" --json "$out/$name-$relief.json" \
      "${flags[@]}" "${more[@]}" "$@" >/dev/null
    if command -v cjpeg >/dev/null; then
      python3 "$here/png2ppm.py" "$out/$name-$relief.png" | cjpeg -quality 85 >"$out/$name-$relief.jpg"
      rm "$out/$name-$relief.png"
    fi
  done
  echo "gallery: $name"
}
shoot cavern-95 95 --pose "$(pose 95 0.0.0.r0 centre 0 200 10)"
shoot stalactites-95 95 --pose "$(pose 95 0.0.0.r0 centre 0 200 55)"
shoot floor-7 7 --pose "$(pose 7 0.0.0.r0 floor 20 -15)"
shoot tunnel-7 7 --pose "$(pose 7 0.0.0.r73 along)"
shoot tunnel-95 95 --pose "$(pose 95 0.0.0.r21 along)"
shoot shaft-up-7 7 --pose "$(pose 7 0.0.0.r14 centre 0 140 80)"
shoot shaft-up-95 95 --pose "$(pose 95 0.0.0.r16 centre 0 140 80)"
shoot cavern-3 3 --pose "$(pose 3 0.0.0.r64 centre 0 270 -10)"
shoot portal-3 3 --pose room:0.0.0.r86
shoot ceiling-3 3 --pose "$(pose 3 0.0.0.r0 centre 0.3 30 50)"
shoot flythrough-95 95 --flythrough 8
shoot flythrough-7 7 --flythrough 3
# Passages shaped by their rock (cave::passage_section), from the middle of a straight, level
# passage whose two portals have the same kind of section, looking along it: vadose canyons, a
# fissure along a joint, lenses along the bedding and a round tube.
shoot canyon-95 95 --pose "$(pose 95 1.0.0.r61 along)"
shoot canyon-7 7 --pose "$(pose 7 1.0.0.r39 along)"
shoot fissure-95 95 --pose "$(pose 95 1.0.0.r33 along)"
shoot lens-95 95 --pose "$(pose 95 0.0.0.r93 along)"
shoot lens-7 7 --pose "$(pose 7 1.0.1.r69 along)"
shoot tube-95 95 --pose "$(pose 95 0.0.1.r9 along)"
# Halls: from an entrance, across from one side, from the floor looking up at the ceiling.
shoot hall-entrance-95 95 --pose "$(pose 95 1.0.1.r0 entrance)"
shoot hall-across-7 7 --pose "$(pose 7 0.0.0.r0 across 270 5)"
shoot hall-across-95 95 --pose "$(pose 95 1.0.1.r0 across 0 5)"
shoot hall-up-7 7 --pose "$(pose 7 0.0.0.r0 floor 60 55)"
# Light in the dark: the headlamp off, one flare thrown into the hall (it falls, bounces and lies
# burning), and the world's lights.
shoot hall-flare-95 95 --pose "$(pose 95 1.0.1.r0 across 0 -5)" --no-headlamp --flares 1
# Breakdown: the first heap of blocks in seed 95's hall 0.0.0.r0 (room frame 13.0, 3.5: its
# middle), from 9 m towards the hall's middle, 2.5 m above the floor, looking down 14 degrees.
shoot breakdown-95 95 --pose 60.27,48.47,45.73,105.1,-14.0
# Columns: where a level floor and ceiling are 2.5-3.5 m apart a column cell's
# stalactite and stalagmite join. Halls never hold one (their ceilings are 10-30 m up and slope
# where they come down); seed 7's passage room 0.0.1.r59 (r = 3.8 m, floor at y 39.8, ceiling
# 2.4 m above) holds two, 0.9 m apart, found by scanning the column cells of sectors 0,0,0 to
# 1,0,1 in seeds 3, 7 and 95 (37 joined in all, every one in a room of radius 2.8-6 m).
shoot column-field-7 7 --pose 11.62,72.53,7.10,96.0,-6.0
# Fine detail (the -off picture without it, --no-fine-detail): the same room's wall 1.9 m away.
OFF=--no-fine-detail shoot detail-wall-7 7 --pose 64.00,54.44,50.40,120.0,0.0
# Ambient occlusion (the -off picture without it, --no-ao): stalagmites' feet on the floor of
# seed 7's hall, the fluted wall behind.
OFF=--no-ao shoot ao-stalagmites-7 7 --pose 52.00,54.44,31.00,60.0,-25.0
# Draperies: sheets hanging from seed 7's hall roof where it slopes down towards the
# wall, 3.5 m from the widest (2.5 m across, 1.5 m drop: its extras from /extras/), across it.
shoot draperies-7 7 --pose 53.49,65.97,17.84,117.9,1.7
# The biggest of them from its other side, the headlamp off: the hall's glow-worm colony 13 m
# behind it shows through the sheet, amber, its bands dark against it.
shoot draperies-back-7 7 --pose 59.67,65.30,21.13,298.1,8.0 --no-headlamp
