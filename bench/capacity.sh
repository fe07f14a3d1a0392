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
# Besides the table: each player's admission (players admitted, those that queued first and
# those never let in by the end, their time queued p50 / max) and the stalls of admitted players
# alone. A player's walker starts at its start room, which comes after its welcome, so a
# newcomer waiting in the queue cannot stall: both stall counts agree unless a player was queued
# again after a reconnect. The same figures, run by run, go to DIR/capacity.json.
#
#   bash bench/capacity.sh [--runs N] [--duration S] [--rows LIST] [--build-dir DIR]
#                          [--out DIR] [--busy CORES] [--no-build] [--load-flags "FLAGS"]
#                          [--cpu-quota CORES]
#
# --load-flags adds FLAGS to every grotto-load run (an experiment against the defaults, such as
# "--min-horizon 1.0"); the table then says so in its first line.
#
# --cpu-quota CORES gives the measured side a slower machine's share of the CPU: a fresh cgroup
# for each run, its cpu.max CORES x 100000 us per 100000 us (0.5, 1, 1.5, ...). For a server row
# it holds grotto-server alone; for an embedded row it holds the grotto-load process, so the
# quota then covers the simulated players too (their decoding and walking), not the server
# alone. Rows ending in -1core set 1 core themselves; the flag sets rows that set none. The
# cgroups are made under the cgroup v2 root, else this shell's own v2 cgroup, else (a hybrid
# host, whose cpu controller is on cgroup v1) the v1 cpu hierarchy's root, with
# cpu.cfs_quota_us; they are removed after each run and when the script stops or is killed.
# Without a writable one the script stops before building, saying why (root, or a delegated
# cgroup, is needed). The table, capacity.json and the runs' .load files record the quota and
# the time the kernel held the processes back (throttled s).
#
# Rows (--rows takes their names, comma-separated; default: all of them, in this order):
#   embedded-300-once       300 players at once, embedded server, defaults (the target's check)
#   embedded-300-once-fixed the same with the fixed 4 s horizon (--min-horizon 0)
#   embedded-200-ramp10     200 players joining over 10 s, embedded server: under capacity, where
#                           admission must change nothing (nobody queued)
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
# Only with --rows, with a writable cgroup (--cpu-quota): a slower machine, one core's share
#   embedded-300-once-1core embedded-300-once, grotto-load (players and server) on 1 core
#   server-300-once-1core   server-300-once, grotto-server on 1 core (grotto-load unlimited)
# Only with --rows, for a machine of 16 cores (the scaling set-up, CPU reference path):
#   cores16-w2              1,000 players over 10 s; grotto-server --opencl-device none --workers 2
#   cores16-w10             4,000 players over 20 s; --workers 10 --io-threads 4
# Every row is 10 m/s unless its name ends in -30 or -20. Exit: 0 when every run ran (whatever its
# figures), 1 when a build or a run failed or no cgroup could take the quota, 2 on a bad flag.
set -u
cd "$(dirname "$0")/.." || exit 1

runs=3 duration=60 rows="" build_dir=build-capacity out="" busy=0.25 build=1 load_flags="" cpu_quota="" quota_flag=0
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
    --cpu-quota) cpu_quota=${2:-} quota_flag=1 && shift ;;
    -h | --help) usage; exit 0 ;;  # exit 0 even when a reader closes the pipe early (SIGPIPE)
    *) echo "capacity.sh: unknown flag '$1' (--help lists them)" >&2 && exit 2 ;;
  esac
  shift
done
[[ "$runs" =~ ^[1-9][0-9]*$ ]] || { echo "capacity.sh: --runs must be a whole number >= 1" >&2; exit 2; }
[[ "$duration" =~ ^[1-9][0-9]*$ ]] || { echo "capacity.sh: --duration must be whole seconds >= 1" >&2; exit 2; }
[[ "$busy" =~ ^[0-9]+([.][0-9]+)?$ ]] || { echo "capacity.sh: --busy must be a number of cores" >&2; exit 2; }
# At least 0.01 core: the kernel's shortest quota is 1 ms a period.
if ((quota_flag)) && ! { [[ "$cpu_quota" =~ ^[0-9]+([.][0-9]+)?$ ]] &&
  awk -v c="$cpu_quota" 'BEGIN { exit !(c >= 0.01) }'; }; then
  echo "capacity.sh: --cpu-quota must be a number of cores >= 0.01 (1 or 0.5, say)" >&2
  exit 2
fi

# name | server (embedded or server) | players | ramp s | speed m/s | grotto-load flags | server flags
# | CPU quota in cores (empty: --cpu-quota's, if any)
all_rows=(
  "embedded-300-once|embedded|300|0|10|"
  "embedded-300-once-fixed|embedded|300|0|10|--min-horizon 0"
  "embedded-200-ramp10|embedded|200|10|10|"
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
quota_rows=(
  "embedded-300-once-1core|embedded|300|0|10|||1"
  "server-300-once-1core|server|300|0|10|||1"
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
    for r in "${all_rows[@]}" "${quota_rows[@]}" "${big_rows[@]}"; do [[ "${r%%|*}" == "$w" ]] && found=$r; done
    [[ -n "$found" ]] || { echo "capacity.sh: no row '$w' (--help lists them)" >&2; exit 2; }
    selected+=("$found")
  done
fi

command -v python3 >/dev/null || { echo "capacity.sh: python3 is needed for the table" >&2; exit 1; }

# Each row's quota in cores: its own (the -1core rows), else --cpu-quota's, else none.
row_quota() {
  local name where players ramp speed extra server_flags quota
  IFS='|' read -r name where players ramp speed extra server_flags quota <<<"$1"
  echo "${quota:-$cpu_quota}"
}
need_cgroup=0
for row in "${selected[@]}"; do [[ -n "$(row_quota "$row")" ]] && need_cgroup=1; done

# Where a run's cgroup is made (cg_parent) and how its quota is written (cg_kind): cgroup v2's
# cpu.max where the cpu controller is on v2 (the root, else this shell's own cgroup, which
# must be able to delegate cpu: the root, or a systemd-delegated or empty one); else cgroup
# v1's cpu hierarchy (hosts that keep cpu on v1, with v2 mounted for systemd alone). Each
# candidate is tried by making a child and writing a quota into it. systemd-run is not used:
# containers rarely run systemd, and plain cgroupfs works with or without it.
cg_kind="" cg_parent="" cg_why=()
cg_try() {  # cg_try KIND DIR: can a child of DIR take a quota?
  local kind=$1 dir=$2 probe=$2/grotto-capacity.$$.probe ok=1
  [[ -d "$dir" ]] || { cg_why+=("$dir: no such cgroup"); return 1; }
  if [[ "$kind" == v2 ]]; then
    grep -qw cpu "$dir/cgroup.controllers" 2>/dev/null ||
      { cg_why+=("$dir: no cpu controller in cgroup v2"); return 1; }
    grep -qw cpu "$dir/cgroup.subtree_control" 2>/dev/null ||
      echo +cpu 2>/dev/null >"$dir/cgroup.subtree_control" ||
      { cg_why+=("$dir: cannot enable cpu for children"); return 1; }
  fi
  mkdir "$probe" 2>/dev/null || { cg_why+=("$dir: not writable"); return 1; }
  if [[ "$kind" == v2 ]]; then
    echo "100000 100000" 2>/dev/null >"$probe/cpu.max" || ok=0
  else
    echo 100000 2>/dev/null >"$probe/cpu.cfs_quota_us" || ok=0
  fi
  rmdir "$probe" 2>/dev/null
  ((ok)) || { cg_why+=("$dir: cannot set a child's quota"); return 1; }
  cg_kind=$kind cg_parent=$dir
}
cg_find() {
  local v2 own v1 v1own
  v2=$(awk '$3 == "cgroup2" { print $2; exit }' /proc/self/mounts)
  own=$(awk -F: '$1 == "0" && $2 == "" { print $3; exit }' /proc/self/cgroup)
  if [[ -n "$v2" ]]; then
    cg_try v2 "$v2" && return 0
    [[ -n "$own" && "$own" != / ]] && cg_try v2 "$v2$own" && return 0
  else
    cg_why+=("no cgroup v2 mounted")
  fi
  v1=$(awk '$3 == "cgroup" && $4 ~ /(^|,)cpu(,|$)/ { print $2; exit }' /proc/self/mounts)
  if [[ -n "$v1" ]]; then
    cg_try v1 "$v1" && return 0
    v1own=$(awk -F: '$2 ~ /(^|,)cpu(,|$)/ { print $3; exit }' /proc/self/cgroup)
    [[ -n "$v1own" && "$v1own" != / ]] && cg_try v1 "$v1$v1own" && return 0
  fi
  return 1
}
if ((need_cgroup)); then
  cg_find || {
    why=$(IFS=';' && echo "${cg_why[*]}")
    echo "capacity.sh: no writable cgroup with the cpu controller for the quota (${why//;/; })" >&2
    exit 1
  }
  echo "capacity.sh: quotas in cgroup ${cg_kind} under $cg_parent" >&2
fi
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

# A run's cgroup (cg, empty without a quota) and the command prefix that starts a program in it
# (in_cg: a shell that moves itself in, then becomes the program, so its pid stays the one
# waited for and read in /proc).
cg="" in_cg=()
cg_make() {  # cg_make NAME CORES
  local quota_us
  quota_us=$(awk -v c="$2" 'BEGIN { printf "%d", c * 100000 + 0.5 }')
  cg=$cg_parent/grotto-capacity.$$.$1
  mkdir "$cg" || { cg=""; return 1; }
  if [[ "$cg_kind" == v2 ]]; then
    echo "$quota_us 100000" >"$cg/cpu.max" || return 1
  else
    { echo 100000 >"$cg/cpu.cfs_period_us" && echo "$quota_us" >"$cg/cpu.cfs_quota_us"; } || return 1
  fi
  # shellcheck disable=SC2016
  in_cg=(bash -c 'echo "$$" >"$0/cgroup.procs" || exit 125; exec "$@"' "$cg")
}
# How long the kernel held the run's processes back, and in how many of the periods they ran.
cg_throttled() {
  awk '$1 == "throttled_usec" { t = $2 / 1e6 } $1 == "throttled_time" { t = $2 / 1e9 }
       $1 == "nr_throttled" { n = $2 } $1 == "nr_periods" { p = $2 }
       END { printf "%.2f %d/%d", t, n, p }' "$cg/cpu.stat" 2>/dev/null
}
cg_remove() {
  [[ -n "$cg" ]] || return 0
  local pid
  for _ in $(seq 1 50); do
    rmdir "$cg" 2>/dev/null && break
    [[ -d "$cg" ]] || break
    # Whatever is still in it is this run's grotto-server or grotto-load.
    { while read -r pid; do kill -9 "$pid"; done <"$cg/cgroup.procs"; } 2>/dev/null
    sleep 0.1
  done
  [[ -d "$cg" ]] && echo "capacity.sh: could not remove the cgroup $cg" >&2
  cg="" in_cg=()
}

# grotto-load runs in the background and is waited for, so that a signal to this script is
# handled at once (bash runs a trap only after a foreground command ends); timeout passes the
# signal on and kills it 10 s later if it is still there.
load_pid=""
# shellcheck disable=SC2317 # (called from the trap)
stop_load() {
  [[ -n "$load_pid" ]] || return 0
  kill "$load_pid" 2>/dev/null
  wait "$load_pid" 2>/dev/null
  load_pid=""
}
# shellcheck disable=SC2317
cleanup() { stop_load; stop_server; cg_remove; }
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# A free loopback port: the kernel's choice, read back from the server's first line.
start_server() {
  local log=$1
  # shellcheck disable=SC2086
  "${server_in_cg[@]}" "$server_bin" --port 0 --log-level warn $server_flags >"$log" 2>&1 &
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
  IFS='|' read -r name where players ramp speed extra server_flags quota <<<"$row"
  quota=${quota:-$cpu_quota}
  for ((i = 1; i <= runs; i++)); do
    json=$out/$name.$i.json
    load=$(cut -d' ' -f1 /proc/loadavg)
    args=(--players "$players" --spread --speed "$speed" --duration "$duration" --quiet --json "$json")
    ((ramp > 0)) && args+=(--ramp "$ramp")
    # shellcheck disable=SC2206
    [[ -n "$extra" ]] && args+=($extra)
    # shellcheck disable=SC2206
    [[ -n "$load_flags" ]] && args+=($load_flags)
    server_cpu="" server_in_cg=() load_in_cg=() throttled="- -"
    if [[ -n "$quota" ]]; then
      cg_make "$name.$i" "$quota" || {
        echo "capacity.sh: $name run $i: cannot make a cgroup of $quota core(s) under $cg_parent" >&2
        cg_remove
        failed=1
        continue
      }
      if [[ "$where" == server ]]; then server_in_cg=("${in_cg[@]}"); else load_in_cg=("${in_cg[@]}"); fi
    fi
    if [[ "$where" == server ]]; then
      start_server "$out/$name.$i.server.log" || { stop_server; cg_remove; failed=1; continue; }
      args+=(--server "ws://127.0.0.1:$port/ws")
      # Spread players against a server need a seed: 7 unless the row or --load-flags names one.
      [[ " $extra $load_flags " == *" --seed "* ]] || args+=(--seed 7)
    fi
    who="grotto-load and its embedded server"
    [[ "$where" == server ]] && who=grotto-server
    echo "capacity.sh: $name run $i (load $load${quota:+, $quota core(s) for $who})" >&2
    children_cpu_to "$out/.c0"
    m0=$(machine_cpu) c0=$(cat "$out/.c0") t0=$(date +%s.%N)
    timeout -k 10 $((duration + 180)) "${load_in_cg[@]}" "$load_bin" "${args[@]}" >"$out/$name.$i.log" 2>&1 &
    load_pid=$!
    wait "$load_pid"
    rc=$?
    load_pid=""
    stop_server
    [[ -n "$cg" ]] && throttled=$(cg_throttled)
    cg_remove
    children_cpu_to "$out/.c1"
    m1=$(machine_cpu) c1=$(cat "$out/.c1") t1=$(date +%s.%N)
    others=$(awk -v m0="$m0" -v m1="$m1" -v c0="$c0" -v c1="$c1" -v t0="$t0" -v t1="$t1" \
      'BEGIN { o = ((m1 - m0) - (c1 - c0)) / (t1 - t0); printf "%.2f", o < 0 ? 0 : o }')
    # Exit codes 3 and 4 are grotto-load's gates (stalls, p99): figures, not failures here. Past
    # capacity (the past-* rows) so is 1: newcomers refused, or admitted with no room yet at the
    # end, are what those rows measure (capacity.json counts them).
    errors_are_figures=0
    [[ "$name" == past-* && "$rc" == 1 ]] && errors_are_figures=1
    if [[ ! -s "$json" ]] || ((rc != 0 && rc != 3 && rc != 4 && !errors_are_figures)); then
      echo "capacity.sh: $name run $i failed (exit $rc): $(tail -n 3 "$out/$name.$i.log")" >&2
      failed=1
      continue
    fi
    # grotto-load's CPU seconds (the children's less the server's): with the server's, the cores
    # each kept busy over the load's run (the table divides by its elapsed_s). On a machine that
    # runs both, a server that stops growing may be sharing its cores with its players.
    load_cpu=$(awk -v c0="$c0" -v c1="$c1" -v s="${server_cpu:-0}" 'BEGIN { printf "%.3f", c1 - c0 - s }')
    # Then the quota in cores and the time the kernel throttled its cgroup ("-": none).
    echo "$load $others ${server_cpu:--} $load_cpu ${quota:--} $throttled" >"$json.load"
  done
done

python3 - "$out" "$busy" "$load_flags" "$cpu_quota" "$cg_kind" "$cg_parent" "${selected[@]}" <<'PY'
import json, statistics, sys, glob, os, re
out, busy, load_flags, cpu_quota, cg_kind, cg_parent = sys.argv[1:7]
busy, rows = float(busy), sys.argv[7:]
if load_flags:
    print(f"grotto-load flags added to every run: `{load_flags}`\n")
if cg_kind:
    print(f"CPU quotas: a cgroup of each run ({'cgroup v2, cpu.max' if cg_kind == 'v2' else 'cgroup v1, cpu.cfs_quota_us'}"
          f" under {cg_parent}), 100 ms periods\n")
def fmt(vals, digits=0):
    if not vals: return "-"
    med = statistics.median(vals)
    f = (lambda v: f"{v:,.{digits}f}")
    return f(med) if len(vals) == 1 else f"{f(med)} ({f(min(vals))}-{f(max(vals))})"
def median(vals):
    return statistics.median(vals) if vals else None
print("| row | players | joined over | m/s | horizon | CPU quota | runs | stalls | stalls of admitted "
      "| admitted / queued first / never in | time queued p50 / max s | request->room p99 ms "
      "| due within 1 s: p99 ms | first room p99 ms | rooms/s | server CPU ms/room "
      "| cores busy: server / grotto-load | throttled s | load before / others' cores |")
print("| --- | ---: | --- | ---: | --- | --- | ---: | ---: | ---: | --- | --- | ---: | ---: | ---: "
      "| ---: | ---: | ---: | ---: | --- |")
cpuinfo = open("/proc/cpuinfo").read()
model = re.search(r"^model name\s*:\s*(.*)$", cpuinfo, re.M)
flags = re.search(r"^flags\s*:\s*(.*)$", cpuinfo, re.M)
flags = flags.group(1).split() if flags else []
report = {"tool": "capacity.sh", "cores": os.cpu_count(),
          "cpu": model.group(1) if model else "", "avx2": "avx2" in flags, "avx512f": "avx512f" in flags,
          "load_flags": load_flags, "busy_cores": busy,
          "cpu_quota": {"cores": float(cpu_quota) if cpu_quota else None,
                        "cgroup": cg_kind or None, "parent": cg_parent or None, "period_us": 100000},
          "rows": []}
for row in rows:
    name, where, players, ramp, speed, extra, *rest = row.split("|") + [""] * 2
    server_flags, quota = rest[0], rest[1] or cpu_quota
    runs = sorted(glob.glob(os.path.join(out, name + ".*.json")))
    runs = [r for r in runs if os.path.exists(r + ".load")]
    res = [json.load(open(r)) for r in runs]
    loads = [open(r + ".load").read().split() for r in runs]
    per_run = []
    for path, r, l in zip(runs, res, loads):
        pp = r.get("per_player", [])
        # Never let in: still queued at the end without a start room (a player queued again
        # after a reconnect had one).
        never = {p["index"] for p in pp if p.get("queued_at_end") and p.get("first_room_ms", -1) < 0}
        server_s = float(l[2]) if len(l) > 2 and l[2] != "-" else None
        load_s = float(l[3]) if len(l) > 3 else None
        elapsed = r["elapsed_s"]
        per_run.append({
            "json": path, "load_before": float(l[0]), "others_cores": float(l[1]),
            "server_cpu_s": server_s, "load_cpu_s": load_s,
            "cpu_quota_cores": float(l[4]) if len(l) > 4 and l[4] != "-" else None,
            "throttled_s": float(l[5]) if len(l) > 5 and l[5] != "-" else None,
            "throttled_periods": l[6] if len(l) > 6 and l[6] != "-" else None,
            "exit_code": r["exit_code"], "errors_total": r["errors_total"],
            "players_without_room": r["players_without_room"],
            "stalls": r["stalls"]["count"],
            "admitted_stalls": sum(p.get("stalls", 0) for p in pp if p["index"] not in never),
            "players_admitted": len(pp) - len(never),
            "players_queued": r["queued"]["players"],
            "players_never_admitted": len(never),
            "queued_s_p50": r["queued"]["ms"]["p50"] / 1000, "queued_s_max": r["queued"]["ms"]["max"] / 1000,
            "latency_p99_ms": r["latency_ms"]["p99"], "urgent_p99_ms": r["urgent_latency_ms"]["p99"],
            "first_room_p99_ms": r["first_room_ms"]["p99"], "rooms_per_s": r["rooms_per_s"],
            "server_ms_per_room": server_s * 1000 / r["rooms"]["ready"]
                if server_s is not None and r["rooms"]["ready"] > 0 else None,
            "server_cores": server_s / elapsed if server_s is not None and elapsed > 0 else None,
            "load_cores": load_s / elapsed if load_s is not None and elapsed > 0 else None,
        })
    col = lambda k: [x[k] for x in per_run if x[k] is not None]
    horizon = "fixed 4 s" if "--min-horizon 0" in extra else "adaptive (default)"
    joined = "at once" if ramp == "0" else f"{ramp} s"
    quota_text = "-" if not quota else f"{quota} core: " + ("server" if where == "server" else "server + players")
    mark = " **busy**" if any(x["others_cores"] > busy for x in per_run) else ""
    busy_cores = (f"{fmt(col('server_cores'), 1)} / " if col("server_cores") else "- / ") + fmt(col("load_cores"), 1)
    admitted = f"{fmt(col('players_admitted'))} / {fmt(col('players_queued'))} / {fmt(col('players_never_admitted'))}"
    queued_s = (f"{fmt(col('queued_s_p50'), 1)} / {fmt(col('queued_s_max'), 1)}"
                if any(x["players_queued"] for x in per_run) else "-")
    print(f"| {name} ({where}) | {int(players):,} | {joined} | {speed} | {horizon} | {quota_text} | {len(res)} "
          f"| {fmt(col('stalls'))} | {fmt(col('admitted_stalls'))} | {admitted} | {queued_s} "
          f"| {fmt(col('latency_p99_ms'))} | {fmt(col('urgent_p99_ms'))} | {fmt(col('first_room_p99_ms'))} "
          f"| {fmt(col('rooms_per_s'))} | {fmt(col('server_ms_per_room'), 2)} | {busy_cores} "
          f"| {fmt(col('throttled_s'), 1)} "
          f"| {', '.join(f'{l[0]} / {l[1]}' for l in loads)}{mark} |")
    keys = [k for k in (per_run[0] if per_run else {}) if k not in ("json", "throttled_periods", "exit_code")]
    report["rows"].append({
        "name": name, "where": where, "players": int(players), "ramp_s": float(ramp),
        "speed_m_s": float(speed), "load_flags": extra, "server_flags": server_flags,
        "cpu_quota_cores": float(quota) if quota else None, "busy": bool(mark),
        "runs": per_run, "median": {k: median(col(k)) for k in keys}})
with open(os.path.join(out, "capacity.json"), "w") as f:
    json.dump(report, f, indent=2)
PY
exit $failed
