#!/usr/bin/env bash
# Renders docs/GALLERY.md's pictures: each pose with the relief on and off (--no-displacement),
# under Xvfb with Mesa's llvmpipe, from an in-process server (CPU reference). ~8 s a picture.
# Usage: bash docs/gallery/render.sh [build dir, default build]  (from the repository root)
# GALLERY_OUT (default docs/images/gallery) is where the pictures go; GALLERY_FLAGS, more client
# flags for every picture (docs/gallery/protocol.sh passes --protocol 1 or 2).
set -euo pipefail
build=${1:-build}
out=${GALLERY_OUT:-docs/images/gallery}
read -r -a more <<< "${GALLERY_FLAGS:-}"
mkdir -p "$out"
client="$build/bin/grotto-client"
layout="$build/bin/grotto-layout"
# A room's sphere centre, plus an offset in units of its radius: x,y,z.
centre() {  # seed room dy
  "$layout" --seed "$1" --room "$2" 2>/dev/null | python3 -c "
import json, sys
r = json.load(sys.stdin)
c = r['centre']
print('%.2f,%.2f,%.2f' % (c[0], c[1] + float(sys.argv[1]) * r['radius'], c[2]))" "$3"
}
shoot() {  # name seed extra-args...
  local name=$1 seed=$2
  shift 2
  for relief in on off; do
    local flags=()
    [[ $relief == off ]] && flags=(--no-displacement)
    xvfb-run -a -s "-screen 0 1280x1024x24" "$client" --device none --seed "$seed" \
      --width 480 --height 270 --tess-max 8 --lod distance --frames 3 --wait 120 --no-motion-blur \
      --screenshot "$out/$name-$relief.png" "${flags[@]}" "${more[@]}" "$@" >/dev/null
  done
  echo "gallery: $name"
}
shoot cavern-95 95 --pose "$(centre 95 0.0.0.r67 0),200,10"
shoot stalactites-95 95 --pose "$(centre 95 0.0.0.r67 0),200,55"
shoot floor-7 7 --pose "$(centre 7 0.0.0.r0 0),20,-15"
shoot tunnel-7 7 --pose "$(centre 7 0.0.0.r89 0),80,0"
shoot tunnel-95 95 --pose "$(centre 95 0.0.0.r84 0),80,0"
shoot shaft-up-7 7 --pose "$(centre 7 0.0.0.r37 0),140,80"
shoot shaft-up-95 95 --pose "$(centre 95 0.0.0.r7 0),140,80"
shoot cavern-3 3 --pose "$(centre 3 0.0.0.r64 0),90,-10"
shoot portal-3 3 --pose room:0.0.0.r86
shoot ceiling-3 3 --pose "$(centre 3 0.0.0.r0 0.3),30,50"
shoot flythrough-95 95 --flythrough 8
shoot flythrough-7 7 --flythrough 3
