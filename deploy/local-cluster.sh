#!/usr/bin/env bash
# One world on many replicas, on this machine: N grotto-server replicas on loopback and
# nginx in front of them (deploy/nginx), in the foreground until SIGTERM or Ctrl-C, which stop
# them all. Players connect to ws://ADDR:PORT/ws and land on the replica with the fewest
# players; every replica asks the room tier (nginx's /rooms/, each room to its owner replica
# through one cache) for the rooms its players want, so a room is built once for the cluster.
# What an operator runs to try it, and what the tests start.
#
#   deploy/local-cluster.sh --replicas 4 --listen 8080 --prefix /tmp/grotto-cluster
#   grotto-load --server ws://127.0.0.1:8080/ws --seed 7 --players 120 --spread --speed 10
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: local-cluster.sh --replicas N --listen [ADDR:]PORT --prefix DIR [options] [-- SERVER FLAGS]

Starts N grotto-server replicas on 127.0.0.1 (ports chosen by the system) and nginx on
[ADDR:]PORT in front of them, in the foreground; SIGTERM or SIGINT stops everything (replicas
drain first) and exits 0. Every replica serves any world; each is started with
--room-tier http://<nginx>, so rooms come from their owner replica through nginx's cache.

  ws://ADDR:PORT/ws                    players (the replica with the fewest connections)
  http://ADDR:PORT/rooms/...           rooms as immutable HTTP resources (proto/PROTOCOL.md)
  http://ADDR:PORT/replica/<i>/metrics replica i's metrics (also /healthz, /readyz)

Options:
  --replicas N          replicas, 1..64
  --listen [ADDR:]PORT  where nginx listens (ADDR default 127.0.0.1)
  --prefix DIR          scratch directory: nginx's prefix (conf/, logs/, temp/ with the room
                        cache) and logs/replica-<i>.log; created if missing (as root, nginx's
                        workers run as an unprivileged user that must be able to enter it)
  --server PATH         the grotto-server binary (default: build/bin/grotto-server beside this
                        repository, else grotto-server on PATH)
  --workers N           build threads per replica (default 1: replicas share this machine)
  -h, --help            this text
Anything after -- goes to every replica (e.g. -- --max-worlds 8 --opencl-device none).

It prints one line per replica ("replica <i> pid <pid> port <port>") and "cluster ready" once
nginx answers; a replica that exits is reported and not restarted.
Exit codes: 0 stopped by a signal; 2 invalid arguments; 1 something did not start.
EOF
}

die() {
  echo "local-cluster.sh: $*" >&2
  exit 2
}
fail() {
  echo "local-cluster.sh: $*" >&2
  exit 1
}

here=$(cd "$(dirname "$0")" && pwd)
replicas="" listen="" prefix="" server="" workers=1 extra=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --replicas | --listen | --prefix | --server | --workers)
      [[ $# -ge 2 ]] || die "$1 needs a value (see --help)"
      case "$1" in
        --replicas) replicas=$2 ;;
        --listen) listen=$2 ;;
        --prefix) prefix=$2 ;;
        --server) server=$2 ;;
        --workers) workers=$2 ;;
      esac
      shift 2
      ;;
    --) shift; extra=("$@"); break ;;
    -h | --help) usage; exit 0 ;;
    *) die "unknown argument '$1' (see --help)" ;;
  esac
done
[[ "$replicas" =~ ^[1-9][0-9]?$ ]] && ((replicas <= 64)) || die "--replicas: must be 1..64 (got '$replicas')"
[[ -n "$listen" ]] || die "--listen is required (see --help)"
[[ -n "$prefix" ]] || die "--prefix is required (see --help)"
[[ "$workers" =~ ^[1-9][0-9]?$ ]] || die "--workers: must be 1..99 (got '$workers')"
[[ "$listen" == *:* ]] || listen="127.0.0.1:$listen"
port=${listen##*:} addr=${listen%:*}
[[ "$port" =~ ^[0-9]{1,5}$ ]] && ((10#$port >= 1 && 10#$port <= 65535)) || die "--listen: '$listen' needs a port in 1..65535"
# Where the replicas reach the tier: nginx's own address, loopback when it listens everywhere.
tier_addr=$addr
[[ "$tier_addr" == 0.0.0.0 || "$tier_addr" == "*" ]] && tier_addr=127.0.0.1
[[ "$tier_addr" == "[::]" ]] && tier_addr="[::1]"
if [[ -z "$server" ]]; then
  server="$here/../build/bin/grotto-server"
  [[ -x "$server" ]] || server=$(command -v grotto-server || true)
fi
[[ -n "$server" && -x "$server" ]] || die "--server: no grotto-server binary (build it, or pass --server PATH)"
mkdir -p "$prefix/logs" || die "--prefix: cannot create '$prefix'"
prefix=$(cd "$prefix" && pwd)
# nginx started as root runs its workers as an unprivileged user, which writes the room cache
# under DIR/temp: it must be able to enter DIR.
[[ $EUID -ne 0 ]] || chmod a+rx "$prefix"

pids=() replica_pid=() replica_port=() nginx_pid=""
stop_all() {
  trap - TERM INT
  # `|| true` throughout: a replica a test killed is gone, and under `set -e` one failed kill
  # ended this function there, leaving the replicas after it running, orphaned.
  [[ -n "$nginx_pid" ]] && { kill -QUIT "$nginx_pid" 2>/dev/null || true; }
  for p in "${replica_pid[@]}"; do
    kill -TERM "$p" 2>/dev/null || true
  done
  # Replicas drain (their --drain-timeout-ms) and exit; nothing waits longer than 10 s. nginx is
  # asked to stop at once (TERM) when its graceful stop takes longer: a SIGKILL of its master
  # would leave its workers running.
  local deadline=$((SECONDS + 10)) p
  for p in "${pids[@]}"; do
    while kill -0 "$p" 2>/dev/null && ((SECONDS < deadline)); do sleep 0.1; done
    if [[ "$p" == "$nginx_pid" ]] && kill -0 "$p" 2>/dev/null; then
      kill -TERM "$p" 2>/dev/null || true
      local grace=$((SECONDS + 3))
      while kill -0 "$p" 2>/dev/null && ((SECONDS < grace)); do sleep 0.1; done
    fi
    kill -KILL "$p" 2>/dev/null || true
  done
  wait 2>/dev/null || true
}
trap 'stop_all; exit 0' TERM INT
trap 'stop_all' EXIT

for ((i = 0; i < replicas; i++)); do
  out="$prefix/logs/replica-$i.out"
  : >"$out"
  "$server" --bind 127.0.0.1 --port 0 --workers "$workers" \
    --room-tier "http://$tier_addr:$port" "${extra[@]}" >"$out" 2>"$prefix/logs/replica-$i.log" &
  replica_pid[$i]=$!
  pids+=("$!")
done
for ((i = 0; i < replicas; i++)); do
  out="$prefix/logs/replica-$i.out"
  for ((t = 0; t < 600; t++)); do  # the first start may compile kernels: up to 60 s
    grep -q "listening on" "$out" && break
    kill -0 "${replica_pid[$i]}" 2>/dev/null || fail "replica $i exited at start: $(tail -n 3 "$prefix/logs/replica-$i.log")"
    sleep 0.1
  done
  replica_port[$i]=$(sed -n 's|.*listening on http://127\.0\.0\.1:\([0-9]*\).*|\1|p' "$out")
  [[ -n "${replica_port[$i]}" ]] || fail "replica $i did not start within 60 s (see $prefix/logs/replica-$i.log)"
  echo "replica $i pid ${replica_pid[$i]} port ${replica_port[$i]}"
done

list=""
for p in "${replica_port[@]}"; do list+="${list:+,}127.0.0.1:$p"; done
bash "$here/nginx/render.sh" --prefix "$prefix" --listen "$listen" --replicas "$list" --run \
  >"$prefix/logs/nginx.out" 2>&1 &
nginx_pid=$!
pids+=("$nginx_pid")
for ((t = 0; t < 100; t++)); do
  kill -0 "$nginx_pid" 2>/dev/null || fail "nginx exited: $(tail -n 3 "$prefix/logs/nginx.out")"
  if (exec 3<>"/dev/tcp/$tier_addr/$port") 2>/dev/null; then
    echo "cluster ready: players ws://$listen/ws, the viewer http://$listen/, rooms http://$listen/rooms/, metrics http://$listen/replica/<i>/metrics"
    break
  fi
  sleep 0.1
done
((t < 100)) || fail "nginx did not listen on $listen within 10 s (see $prefix/logs/nginx.out)"

# Foreground until a signal; say when a replica or nginx goes away (tests kill them on purpose).
declare -A reported=()
while true; do
  for ((i = 0; i < replicas; i++)); do
    if [[ -z "${reported[$i]:-}" ]] && ! kill -0 "${replica_pid[$i]}" 2>/dev/null; then
      echo "replica $i (pid ${replica_pid[$i]}) exited; nginx routes around it"
      reported[$i]=1
    fi
  done
  kill -0 "$nginx_pid" 2>/dev/null || fail "nginx exited: $(tail -n 3 "$prefix/logs/nginx.out")"
  sleep 0.5 &
  wait $! || true
done
