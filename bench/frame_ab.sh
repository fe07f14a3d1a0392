#!/usr/bin/env bash
# A look's frame cost on this machine: grotto-client of this checkout against the one of commit
# BEFORE, both on llvmpipe through EGL at 960x540 with the defaults, the two binaries alternating
# (before, after) for --rounds rounds over the rows, `--bench SECONDS` each run. Rows: seed 7's
# scripted path and two held halls of seed 95 (its hall's centre, hall-entrance-95) unless --row
# is given (repeatable: NAME:SEED:FLAGS, e.g. "wall:7:--hold --pose 64,54.44,50.4,120,0").
# Prints one Markdown table, a row per row: before and after as median / p99 per round, and the
# ratio of medians (after / before) as the median over the rounds with its range; with the CPU's
# model and vector flags and the load average at each run (machines are noisy: read the ratio,
# not the milliseconds). The runs' reports stay in --out.
#
#   bash bench/frame_ab.sh BEFORE [--rounds N] [--seconds S] [--row NAME:SEED:FLAGS]...
#                                 [--build-dir DIR] [--out DIR]
#
# BEFORE: a commit, whose grotto-client is built (Release) in a git worktree under build-ab/ the
# first time (minutes) and kept there (`git worktree remove build-ab/src-COMMIT` when done); or
# the path of a grotto-client binary already built. This checkout's is --build-dir's (default
# build: built here if missing). Defaults: 3 rounds, 8 s a run, reports in build-ab/runs. Exit: 0 when every
# run reported, 1 when one failed, 2 on a bad flag.
set -u
cd "$(dirname "$0")/.."

before="" rounds=3 seconds=8 build_dir=build out=build-ab/runs
rows=()
usage() { sed -n '2,/^set -u/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }
while (($#)); do
  case "$1" in
    --rounds) rounds=${2:-} && shift ;;
    --seconds) seconds=${2:-} && shift ;;
    --row) rows+=("${2:-}") && shift ;;
    --build-dir) build_dir=${2:-} && shift ;;
    --out) out=${2:-} && shift ;;
    -h | --help) usage && exit 0 ;;
    -*) echo "frame_ab: unknown flag $1 (--help)" >&2 && exit 2 ;;
    *) [[ -z $before ]] && before=$1 || { echo "frame_ab: one commit, not '$1'" >&2 && exit 2; } ;;
  esac
  shift
done
[[ -n $before ]] || { echo "frame_ab: which commit to compare with? (--help)" >&2 && exit 2; }
[[ $rounds =~ ^[1-9][0-9]*$ ]] || { echo "frame_ab: --rounds wants a count, not '$rounds'" >&2 && exit 2; }
[[ $seconds =~ ^[1-9][0-9]*$ ]] || { echo "frame_ab: --seconds wants whole seconds, not '$seconds'" >&2 && exit 2; }
if [[ -f $before && -x $before ]]; then
  before_client=$before commit=$before
else
  commit=$(git rev-parse --verify --quiet "$before^{commit}") ||
    { echo "frame_ab: '$before' is no commit here, nor a grotto-client binary" >&2 && exit 2; }
  before_client=build-ab/src-${commit:0:12}/build/bin/grotto-client
fi
((${#rows[@]})) || rows=("path:7:" "hall-95:95:--hold --pose 147.94,50.04,140.49,0,0"
  "hall-entrance-95:95:--hold --pose 163.91,46.33,123.21,-136.6,5.2")

# grotto-client (Release) from source dir $1 in build dir $2, its output in $2.log.
build_client() {
  mkdir -p "$2"
  { cmake -S "$1" -B "$2" -DCMAKE_BUILD_TYPE=Release &&
    cmake --build "$2" -j "$(nproc)" --target grotto-client; } >"$2.log" 2>&1 ||
    { echo "frame_ab: building grotto-client in $2 failed (see $2.log)" >&2 && exit 1; }
}
worktree=build-ab/src-${commit:0:12}
if [[ ! -x $before_client ]]; then
  echo "frame_ab: building grotto-client at ${commit:0:12} in $worktree (minutes)" >&2
  [[ -d $worktree ]] || git worktree add -q --detach "$worktree" "$commit" || exit 1
  # The in-process server bundles the browser viewer: the checkout's npm packages (deploy/setup.sh).
  [[ -e $worktree/web/node_modules || ! -d web/node_modules ]] ||
    ln -s "$PWD/web/node_modules" "$worktree/web/node_modules"
  build_client "$worktree" "$worktree/build"
fi
[[ -x $build_dir/bin/grotto-client ]] || build_client . "$build_dir"
mkdir -p "$out"
declare -A bin=([before]=$before_client [after]=$build_dir/bin/grotto-client)
failed=0
for ((r = 1; r <= rounds; r++)); do
  for row in "${rows[@]}"; do
    IFS=: read -r name seed flags <<<"$row"
    for side in before after; do
      report=$out/$name-$side-$r.json
      read -r -a extra <<<"$flags"
      if ! "${bin[$side]}" --gl egl --device none --seed "$seed" --width 960 --height 540 \
        --bench "$seconds" "${extra[@]}" --json "$report" >/dev/null 2>"$out/$name-$side-$r.err"; then
        echo "frame_ab: $name ($side, round $r) failed: $(head -1 "$out/$name-$side-$r.err")" >&2
        failed=1
        continue
      fi
      # The load average as the run ended, beside its report.
      cut -d' ' -f1 /proc/loadavg >"$out/$name-$side-$r.load"
    done
  done
done
label=$commit
[[ $before_client == "$before" ]] || label=${commit:0:12}
python3 - "$out" "$rounds" "$label" "${rows[@]}" <<'PY'
import json, os, re, statistics, sys
out, rounds, commit, rows = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4:]
cpu = open("/proc/cpuinfo").read()
model = re.search(r"model name\s*:\s*(.*)", cpu).group(1).strip()
flags = set(re.search(r"flags\s*:\s*(.*)", cpu).group(1).split())
vector = ", ".join(f for f in ("avx2", "avx512f") if f in flags) or "no avx2"
loads = []
print(f"grotto-client at 960x540, llvmpipe: {commit} (before) against this checkout (after); "
      f"{model}, {os.cpu_count()} cores, {vector}")
print()
print("| row | before: median / p99 ms | after: median / p99 ms | ratio of medians |")
print("| --- | ---: | ---: | ---: |")
for row in rows:
    name = row.split(":", 1)[0]
    cells = {"before": [], "after": []}
    ratios = []
    for r in range(1, rounds + 1):
        got = {}
        for side in cells:
            path = f"{out}/{name}-{side}-{r}.json"
            if not os.path.exists(path) or not os.path.exists(path[:-5] + ".load"):
                continue
            j = json.load(open(path))
            got[side] = j["median_ms"]
            cells[side].append(f"{j['median_ms']:.1f} / {j['p99_ms']:.1f}")
            loads.append(float(open(path[:-5] + ".load").read()))
        if len(got) == 2:
            ratios.append(got["after"] / got["before"])
    ratio = (f"**{statistics.median(ratios):.3f}** ({min(ratios):.3f}-{max(ratios):.3f})"
             if ratios else "-")
    print(f"| {name} | {', '.join(cells['before'])} | {', '.join(cells['after'])} | {ratio} |")
if loads:
    print()
    print(f"Load average {min(loads):.2f}-{max(loads):.2f} over the runs.")
PY
exit "$failed"
