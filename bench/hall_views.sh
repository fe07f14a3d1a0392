#!/usr/bin/env bash
# A check of space in halls: for each seed, in the largest room of sectors 0,0,0..1,0,1, four
# pictures from its centre (--mode fly, pitch 0, yaws 0, 90, 180 and 270) and four across it
# (from 0.6 radii behind the centre, looking the same ways: docs/gallery/render.sh's "across"),
# with their reports' view depth (depth_m: median over the pixels that show rock) and lights (the
# light sources that light the frame). Prints one Markdown table, a row per picture, and per seed
# how many yaws from the centre see a median depth of at least 12 m, the largest median and the
# most lights (the targets: 3 of 4 yaws >= 12 m and a shot with >= 3 lights in seed 95; a hall of
# median >= 15 m in two of seeds 3, 7 and 95).
#
#   bash bench/hall_views.sh [--build-dir DIR] [--seeds "3 7 95"] [--size WxH] [--out DIR] [--check]
#
# --check: also exit 3 unless every seed given passes the first two targets (3 of 4 yaws from
# the centre at >= 12 m, a shot with >= 3 lights): ctest world.hall_views runs it for seed 95.
# Defaults: build, seeds 3 7 95, 480x270 (depth and lights do not depend on the size; the
# pictures are for looking at), pictures and reports in DIR (default build/hall-views). The
# client runs through EGL (llvmpipe where there is no GPU) with its in-process server on the CPU
# reference. Exit: 0 when every picture was taken, 1 when one failed, 2 on a bad flag, 3 when
# --check failed.
set -u
cd "$(dirname "$0")/.."

build_dir=build seeds="3 7 95" size=480x270 out="" check=0
usage() { sed -n '2,/^set -u/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }
while (($#)); do
  case "$1" in
    --build-dir) build_dir=${2:-} && shift ;;
    --seeds) seeds=${2:-} && shift ;;
    --size) size=${2:-} && shift ;;
    --out) out=${2:-} && shift ;;
    --check) check=1 ;;
    -h | --help) usage && exit 0 ;;
    *) echo "hall_views.sh: unknown flag '$1' (--help lists them)" >&2 && exit 2 ;;
  esac
  shift
done
[[ "$size" =~ ^[0-9]+x[0-9]+$ ]] || { echo "hall_views.sh: --size must be WxH, e.g. 480x270" >&2; exit 2; }
[[ "$seeds" =~ ^[0-9\ ]+$ ]] || { echo "hall_views.sh: --seeds must be whole numbers" >&2; exit 2; }
out=${out:-$build_dir/hall-views}
mkdir -p "$out" || { echo "hall_views.sh: cannot create $out" >&2; exit 1; }
for b in grotto-client grotto-layout; do
  [[ -x "$build_dir/bin/$b" ]] || { echo "hall_views.sh: $build_dir/bin/$b is missing (build it)" >&2; exit 1; }
done

failed=0
for seed in $seeds; do
  "$build_dir/bin/grotto-layout" --seed "$seed" --from 0,0,0 --to 1,0,1 --json "$out/layout-$seed.json" \
    2>/dev/null || { echo "hall_views.sh: grotto-layout failed for seed $seed" >&2; exit 1; }
  centre=$(python3 -c "
import json, sys
r = max(json.load(open(sys.argv[1]))['rooms'], key=lambda r: r['radius'])
print('%s %.3f %.4f %.4f %.4f' % (r['id'], r['radius'], *r['centre']))" "$out/layout-$seed.json")
  read -r room radius x y z <<<"$centre"
  echo "$room $radius" >"$out/room-$seed.txt"
  for place in centre across; do
    for yaw in 0 90 180 270; do
      pose=$(python3 -c "
import math, sys
x, y, z, r, yaw, back = (float(v) for v in sys.argv[1:])
a = math.radians(yaw)
print('%.2f,%.2f,%.2f,%g,0' % (x - back * r * math.sin(a), y, z + back * r * math.cos(a), yaw))" \
        "$x" "$y" "$z" "$radius" "$yaw" "$([[ $place == across ]] && echo 0.6 || echo 0)")
      shot=$out/seed$seed-$place-yaw$yaw
      "$build_dir/bin/grotto-client" --gl egl --device none --seed "$seed" --mode fly \
        --pose "$pose" --width "${size%x*}" --height "${size#*x}" \
        --screenshot "$shot.png" --json "$shot.json" >"$shot.log" 2>&1 ||
        { failed=1; echo "hall_views.sh: seed $seed $place yaw $yaw failed: $(tail -n 1 "$shot.log")" >&2; }
    done
  done
done

python3 - "$out" "$check" $seeds <<'EOF'
import json, os, sys
out, check, seeds = sys.argv[1], sys.argv[2] == "1", sys.argv[3:]
passed = True
print("| seed | room (radius) | from | yaw | depth median (p10-p90) m | lights |")
print("| ---: | --- | --- | ---: | --- | ---: |")
summary = []
for seed in seeds:
    room, radius = open(os.path.join(out, f"room-{seed}.txt")).read().split()
    deep, best, most = 0, 0.0, 0
    for place in ("centre", "across"):
        for yaw in (0, 90, 180, 270):
            where = f"| {seed} | {room} ({float(radius):.1f} m) | {place} | {yaw} |"
            try:
                r = json.load(open(os.path.join(out, f"seed{seed}-{place}-yaw{yaw}.json")))
            except (OSError, ValueError):
                print(f"{where} failed | - |")
                continue
            d = r["depth_m"]
            lights = len(r["lights"])
            deep += place == "centre" and d["median"] >= 12
            best = max(best, d["median"])
            most = max(most, lights)
            print(f"{where} {d['median']:.1f} ({d['p10']:.1f}-{d['p90']:.1f}) | {lights} |")
    summary.append(f"seed {seed}: {deep} of 4 yaws from the centre >= 12 m, largest median "
                   f"{best:.1f} m, most lights in a shot {most}")
    passed = passed and deep >= 3 and most >= 3
print()
for line in summary:
    print("- " + line)
sys.exit(3 if check and not passed else 0)
EOF
rc=$?
((failed)) && exit 1
exit $rc
