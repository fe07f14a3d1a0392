#!/usr/bin/env bash
# One world across replicas: deploy/local-cluster.sh with N replicas on this machine,
# grotto-load through its nginx, and one line of figures per run: sessions per replica, rooms the
# replicas built against the distinct rooms the players received, the room tier's cache hits,
# stalls, errors, latency, and the load average and CPU flags beside them.
#
#   bash bench/cluster.sh [--build-dir build] [--replicas 4] [--players 120] [--duration 40]
#                         [--runs 1] [--together]
# --together: every player starts at the world's spawn (shared rooms: the cache's case) instead
# of --spread (each player in a sector of its own: every room built for one player).
set -euo pipefail
build=build replicas=4 players=120 duration=40 runs=1 spread=(--spread)
while [[ $# -gt 0 ]]; do
  case "$1" in
    --build-dir) build=$2; shift 2 ;;
    --replicas) replicas=$2; shift 2 ;;
    --players) players=$2; shift 2 ;;
    --duration) duration=$2; shift 2 ;;
    --runs) runs=$2; shift 2 ;;
    --together) spread=(); shift ;;
    -h | --help) sed -n '2,11p' "$0"; exit 0 ;;
    *) echo "cluster.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
repo=$(cd "$(dirname "$0")/.." && pwd)
server="$build/bin/grotto-server" load="$build/bin/grotto-load"
[[ -x $server && -x $load ]] || { echo "cluster.sh: build grotto-server and grotto-load in $build first" >&2; exit 2; }
flags=$(grep -o -w -E 'avx512f|avx2' /proc/cpuinfo | sort -u | tr '\n' ' ')
echo "# $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), flags: ${flags:-none of avx2/avx512f}"
echo "| run | replicas | players | start | stalls | errors | p99 ms | next room p99 ms | sessions per replica | built | distinct | built/distinct | tier cache hits | owner failures | load before |"
echo "| --- | ---: | ---: | --- | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | --- |"
for ((r = 1; r <= runs; r++)); do
  dir=$(mktemp -d /tmp/grotto-cluster-bench.XXXXXX)
  chmod 755 "$dir"
  port=$((20000 + RANDOM % 40000))
  load_before=$(cut -d' ' -f1 /proc/loadavg)
  : >"$dir/cluster.log"
  bash "$repo/deploy/local-cluster.sh" --replicas "$replicas" --listen "127.0.0.1:$port" \
    --prefix "$dir/c" --server "$server" >"$dir/cluster.log" 2>&1 &
  cluster=$!
  for ((t = 0; t < 600; t++)); do grep -q "cluster ready" "$dir/cluster.log" && break; sleep 0.1; done
  grep -q "cluster ready" "$dir/cluster.log" || { cat "$dir/cluster.log"; kill "$cluster"; exit 1; }
  "$load" --server "ws://127.0.0.1:$port/ws" --seed 7 --players "$players" "${spread[@]}" \
    --speed 10 --duration "$duration" --quiet --json "$dir/load.json" >"$dir/load.log" 2>&1 || true
  sessions="" built=0 failures=0
  for ((i = 0; i < replicas; i++)); do
    m=$(curl -s "http://127.0.0.1:$port/replica/$i/metrics")
    n=$(awk '$1 == "grotto_connections_total" { print $2 }' <<<"$m")
    b=$(awk '$1 == "grotto_rooms_built_total" { print $2 }' <<<"$m")
    f=$(awk '$1 == "grotto_owner_failures_total" { print $2 }' <<<"$m")
    sessions+="${sessions:+ / }$n" built=$((built + b)) failures=$((failures + f))
  done
  kill -TERM "$cluster"
  wait "$cluster" 2>/dev/null || true
  hits=$(grep -c 'GET /rooms/.* cache=HIT' "$dir/c/logs/access.log" || true)
  tier=$(grep -c 'GET /rooms/' "$dir/c/logs/access.log" || true)
  python3 - "$dir/load.json" "$r" "$replicas" "$players" "${spread[*]:-together}" "$sessions" \
    "$built" "$hits" "$tier" "$failures" "$load_before" <<'EOF'
import json, sys
j = json.load(open(sys.argv[1]))
r, reps, players, start, sessions, built, hits, tier, failures, load = sys.argv[2:]
unique = j["rooms"]["unique"]
start = "spread" if start == "--spread" else "at the spawn"
print(f"| {r} | {reps} | {players} | {start} | {j['stalls']['count']} | {j['errors_total']} | "
      f"{j['latency_ms']['p99']:.0f} | {j['urgent_latency_ms']['p99']:.0f} | {sessions} | {built} | "
      f"{unique} | {int(built) / max(unique, 1):.3f} | {hits} of {tier} | {failures} | {load} |")
EOF
  rm -rf "$dir"
done
