#!/usr/bin/env bash
# Every capacity figure of docs/BENCHMARKS.md ("Capacity"), from one command: builds
# grotto-server and grotto-load (Release, in build-capacity/ unless --build-dir says otherwise),
# runs each row of the capacity table RUNS times (spread players, each in a sector of its own, so
# every room is really built; a fresh server for each run; grotto-load on the same machine), and
# prints one Markdown table: the median of the runs and their spread (min-max) for stalls,
# request->room p99 (all rooms, and the rooms requested due within a second: the next room a
# player walks into), time to first room p99, rooms/s and, for a separate server, its CPU time
# per room served, and the cores grotto-server and grotto-load kept busy (on a machine that runs
# both, a server that stops growing may be sharing its cores with its players); with the
# machine's 1-minute load average before each run and the CPU that other processes took during
# it (the machine's busy time from /proc/stat less what grotto-server and grotto-load used). A
# row with a run where others took more than --busy cores (0.25 by default) is marked "busy":
# its figures are not the machine's.
#
#   bash bench/capacity.sh [--runs N] [--duration S] [--rows LIST] [--build-dir DIR]
#                          [--out DIR] [--busy CORES] [--no-build] [--load-flags "FLAGS"]
#
# --load-flags adds FLAGS to every grotto-load run (an experiment against the defaults, such as
# "--min-horizon 1.0"); the table then says so in its first line.
#
# Rows (--rows takes their names, comma-separated; default: all of them, in this order):
#   embedded-300-once       300 players at once, embedded server, defaults (the target's check)
#   embedded-300-once-fixed the same with the fixed 4 s horizon (--min-horizon 0)
#   server-300-ramp2        300 players joining over 2 s, separate grotto-server, defaults
#   server-300-ramp2-fixed  the same with the fixed horizon
#   server-300-once         300 players at once, separate server
#   server-32-once-30       32 players at once at 30 m/s
#   server-128-once         128 players at once
#   server-256-once         256 players at once
#   server-256-once-fixed   the same with the fixed horizon
#   server-1000-ramp30      1,000 players joining over 30 s
#   server-300-ramp10-w1    300 players joining over 10 s, grotto-server --workers 1
#   server-300-ramp10-w2    the same with --workers 2: the server's CPU per room against one worker
#   past-1000-ramp30-20     past capacity: 1,000 players of seed 95 joining over 30 s at 20 m/s,
#                           grotto-server --workers 2 with admission (the default)
#   past-1000-ramp30-20-off the same with admission off (--admission-late-ms 0)
# Only with --rows, for a machine of 16 cores (the scaling set-up, CPU reference path):
#   cores16-w2              1,000 players over 10 s; grotto-server --opencl-device none --workers 2
#   cores16-w10             4,000 players over 20 s; --workers 10 --io-threads 4
# Every row is 10 m/s unless its name ends in -30 or -20. Exit: 0 when every run ran (whatever its
# figures), 1 when a build or a run failed, 2 on a bad flag.
set -u
cd "$(dirname "$0")/.."

runs=3 duration=60 rows="" build_dir=build-capacity out="" busy=0.25 build=1 load_flags=""
usage() { sed -n '2,/^set -u/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }
while (($#)); do
  case "$1" in
    --runs) runs=${2:-} && shift ;;
    --duration) duration=${2:-} && shift ;;
    --rows) rows=${2:-} && shift ;;
    --build-dir) build_dir=${2:-} && shift ;;
    --out) out=${2:-} && shift ;;
    --busy) busy=${2:-} && shift ;;
    --no-build) build=0 ;;
    --load-flags) load_flags=${2:-} && shift ;;
    -h | --help) usage && exit 0 ;;
    *) echo "capacity.sh: unknown flag '$1' (--help lists them)" >&2 && exit 2 ;;
  esac
  shift
done
[[ "$runs" =~ ^[1-9][0-9]*$ ]] || { echo "capacity.sh: --runs must be a whole number >= 1" >&2; exit 2; }
[[ "$duration" =~ ^[1-9][0-9]*$ ]] || { echo "capacity.sh: --duration must be whole seconds >= 1" >&2; exit 2; }
[[ "$busy" =~ ^[0-9]+([.][0-9]+)?$ ]] || { echo "capacity.sh: --busy must be a number of cores" >&2; exit 2; }

# name | server (embedded or server) | players | ramp s | speed m/s | grotto-load flags | server flags
all_rows=(
  "embedded-300-once|embedded|300|0|10|"
  "embedded-300-once-fixed|embedded|300|0|10|--min-horizon 0"
  "server-300-ramp2|server|300|2|10|"
  "server-300-ramp2-fixed|server|300|2|10|--min-horizon 0"
  "server-300-once|server|300|0|10|"
  "server-32-once-30|server|32|0|30|"
  "server-128-once|server|128|0|10|"
  "server-256-once|server|256|0|10|"
  "server-256-once-fixed|server|256|0|10|--min-horizon 0"
  "server-1000-ramp30|server|1000|30|10|"
  "server-300-ramp10-w1|server|300|10|10||--workers 1"
  "server-300-ramp10-w2|server|300|10|10||--workers 2"
  "past-1000-ramp30-20|server|1000|30|20|--seed 95|--workers 2"
  "past-1000-ramp30-20-off|server|1000|30|20|--seed 95|--workers 2 --admission-late-ms 0"
)
big_rows=(
  "cores16-w2|server|1000|10|10|--io-threads 2|--opencl-device none --workers 2 --max-connections 6000"
  "cores16-w10|server|4000|20|10|--io-threads 2|--opencl-device none --workers 10 --io-threads 4 --max-connections 6000"
)
selected=()
if [[ -z "$rows" ]]; then
  selected=("${all_rows[@]}")
else
  IFS=, read -ra wanted <<<"$rows"
  for w in "${wanted[@]}"; do
    found=""
    for r in "${all_rows[@]}" "${big_rows[@]}"; do [[ "${r%%|*}" == "$w" ]] && found=$r; done
    [[ -n "$found" ]] || { echo "capacity.sh: no row '$w' (--help lists them)" >&2; exit 2; }
    selected+=("$found")
  done
fi

command -v python3 >/dev/null || { echo "capacity.sh: python3 is needed for the table" >&2; exit 1; }
if ((build)); then
  echo "capacity.sh: building grotto-server and grotto-load (Release) in $build_dir" >&2
  { cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release >/dev/null &&
    cmake --build "$build_dir" -j "$(nproc)" --target grotto-server grotto-load >/dev/null; } ||
    { echo "capacity.sh: the build failed" >&2; exit 1; }
fi
server_bin=$build_dir/bin/grotto-server load_bin=$build_dir/bin/grotto-load
[[ -x "$server_bin" && -x "$load_bin" ]] || { echo "capacity.sh: no $server_bin or $load_bin (drop --no-build)" >&2; exit 1; }
[[ -n "$out" ]] || out=$(mktemp -d /tmp/grotto-capacity.XXXXXX)
mkdir -p "$out"

server_pid="" server_cpu=""
stop_server() {
  [[ -n "$server_pid" ]] || return 0
  # Its CPU seconds (user + system) before it goes: the server's cost per room served.
  server_cpu=$(awk -v t="$(getconf CLK_TCK)" '{ printf "%.3f", ($14 + $15) / t }' "/proc/$server_pid/stat" 2>/dev/null)
  kill "$server_pid" 2>/dev/null
  for _ in $(seq 1 100); do kill -0 "$server_pid" 2>/dev/null || break; sleep 0.1; done
  kill -9 "$server_pid" 2>/dev/null
  wait "$server_pid" 2>/dev/null
  server_pid=""
}
trap stop_server EXIT

# A free loopback port: the kernel's choice, read back from the server's first line.
start_server() {
  local log=$1
  # shellcheck disable=SC2086
  "$server_bin" --port 0 --log-level warn $server_flags >"$log" 2>&1 &
  server_pid=$!
  for _ in $(seq 1 300); do
    port=$(grep -o 'ws://127.0.0.1:[0-9]*' "$log" 2>/dev/null | head -n1 | sed 's/.*://')
    [[ -n "$port" ]] && return 0
    kill -0 "$server_pid" 2>/dev/null || break
    sleep 0.1
  done
  echo "capacity.sh: grotto-server did not start: $(tail -n 3 "$log")" >&2
  return 1
}

# The machine's busy CPU seconds so far (user, nice, system, irq, softirq, steal), and the CPU
# seconds of this script's finished children (grotto-server and grotto-load, once waited for).
tick=$(getconf CLK_TCK)
machine_cpu() { awk -v t="$tick" '/^cpu /{ printf "%.3f", ($2 + $3 + $4 + $7 + $8 + $9) / t }' /proc/stat; }
# (`times` reports the children of the shell it runs in: it must run here, not in a $(...)).
children_cpu_to() {
  times >"$1.times"
  tail -n 1 "$1.times" | awk '{ s = 0; for (i = 1; i <= 2; ++i) { split($i, a, "m"); sub("s", "", a[2]); s += a[1] * 60 + a[2] } printf "%.3f", s }' >"$1"
}

failed=0
echo "capacity.sh: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //')," \
  "AVX-512 $(grep -q avx512f /proc/cpuinfo && echo yes || echo no); $runs run(s) of ${duration} s a row;" \
  "results in $out" >&2
for row in "${selected[@]}"; do
  IFS='|' read -r name where players ramp speed extra server_flags <<<"$row"
  for ((i = 1; i <= runs; i++)); do
    json=$out/$name.$i.json
    load=$(cut -d' ' -f1 /proc/loadavg)
    args=(--players "$players" --spread --speed "$speed" --duration "$duration" --quiet --json "$json")
    ((ramp > 0)) && args+=(--ramp "$ramp")
    # shellcheck disable=SC2206
    [[ -n "$extra" ]] && args+=($extra)
    # shellcheck disable=SC2206
    [[ -n "$load_flags" ]] && args+=($load_flags)
    server_cpu=""
    if [[ "$where" == server ]]; then
      start_server "$out/$name.$i.server.log" || { failed=1; continue; }
      args+=(--server "ws://127.0.0.1:$port/ws" --seed 7)
    fi
    echo "capacity.sh: $name run $i (load $load)" >&2
    children_cpu_to "$out/.c0"
    m0=$(machine_cpu) c0=$(cat "$out/.c0") t0=$(date +%s.%N)
    timeout $((duration + 180)) "$load_bin" "${args[@]}" >"$out/$name.$i.log" 2>&1
    rc=$?
    stop_server
    children_cpu_to "$out/.c1"
    m1=$(machine_cpu) c1=$(cat "$out/.c1") t1=$(date +%s.%N)
    others=$(awk -v m0="$m0" -v m1="$m1" -v c0="$c0" -v c1="$c1" -v t0="$t0" -v t1="$t1" \
      'BEGIN { o = ((m1 - m0) - (c1 - c0)) / (t1 - t0); printf "%.2f", o < 0 ? 0 : o }')
    # Exit codes 3 and 4 are grotto-load's gates (stalls, p99): figures, not failures here.
    if [[ ! -s "$json" ]] || ((rc != 0 && rc != 3 && rc != 4)); then
      echo "capacity.sh: $name run $i failed (exit $rc): $(tail -n 3 "$out/$name.$i.log")" >&2
      failed=1
      continue
    fi
    # grotto-load's CPU seconds (the children's less the server's): with the server's, the cores
    # each kept busy over the load's run (the table divides by its elapsed_s). On a machine that
    # runs both, a server that stops growing may be sharing its cores with its players.
    load_cpu=$(awk -v c0="$c0" -v c1="$c1" -v s="${server_cpu:-0}" 'BEGIN { printf "%.3f", c1 - c0 - s }')
    echo "$load $others ${server_cpu:--} $load_cpu" >"$json.load"
  done
done

python3 - "$out" "$busy" "$load_flags" "${selected[@]}" <<'PY'
import json, statistics, sys, glob, os
out, busy, load_flags, rows = sys.argv[1], float(sys.argv[2]), sys.argv[3], sys.argv[4:]
if load_flags:
    print(f"grotto-load flags added to every run: `{load_flags}`\n")
def fmt(vals, digits=0):
    if not vals: return "-"
    med = statistics.median(vals)
    f = (lambda v: f"{v:,.{digits}f}")
    return f(med) if len(vals) == 1 else f"{f(med)} ({f(min(vals))}-{f(max(vals))})"
print("| row | players | joined over | m/s | horizon | runs | stalls | request->room p99 ms "
      "| due within 1 s: p99 ms | first room p99 ms | rooms/s | server CPU ms/room "
      "| cores busy: server / grotto-load | load before / others' cores |")
print("| --- | ---: | --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |")
for row in rows:
    name, where, players, ramp, speed, extra, *server_flags = row.split("|")
    runs = sorted(glob.glob(os.path.join(out, name + ".*.json")))
    runs = [r for r in runs if os.path.exists(r + ".load")]
    res = [json.load(open(r)) for r in runs]
    loads = [open(r + ".load").read().split() for r in runs]
    others = [float(l[1]) for l in loads]
    cpu_ms = [float(l[2]) * 1000 / r["rooms"]["ready"] for l, r in zip(loads, res)
              if len(l) > 2 and l[2] != "-" and r["rooms"]["ready"] > 0]
    stalls = [r["stalls"]["count"] for r in res]
    p99 = [r["latency_ms"]["p99"] for r in res]
    first = [r["first_room_ms"]["p99"] for r in res]
    urgent = [r["urgent_latency_ms"]["p99"] for r in res]
    rate = [r["rooms_per_s"] for r in res]
    horizon = "fixed 4 s" if "--min-horizon 0" in extra else "adaptive (default)"
    joined = "at once" if ramp == "0" else f"{ramp} s"
    mark = " **busy**" if any(o > busy for o in others) else ""
    server_cores = [float(l[2]) / r["elapsed_s"] for l, r in zip(loads, res)
                    if len(l) > 3 and l[2] != "-" and r["elapsed_s"] > 0]
    load_cores = [float(l[3]) / r["elapsed_s"] for l, r in zip(loads, res)
                  if len(l) > 3 and r["elapsed_s"] > 0]
    busy_cores = (f"{fmt(server_cores, 1)} / " if server_cores else "- / ") + fmt(load_cores, 1)
    print(f"| {name} ({where}) | {int(players):,} | {joined} | {speed} | {horizon} | {len(res)} "
          f"| {fmt(stalls)} | {fmt(p99)} | {fmt(urgent)} | {fmt(first)} | {fmt(rate)} "
          f"| {fmt(cpu_ms, 2)} | {busy_cores} "
          f"| {', '.join(f'{l[0]} / {l[1]}' for l in loads)}{mark} |")
PY
exit $failed
