#!/usr/bin/env bash
# Three grotto-server replicas behind nginx (deploy/nginx): 24 walking players through nginx get
# every room verified, no errors and no stalls, and the rooms are spread over the replicas as
# the hash says: with multi-world replicas (--max-worlds) and grotto-load --seeds, every world's
# connections (nginx's access log) and so its rooms land on exactly one replica; players that
# name no world are spread by nginx's per-request id. Each replica's /metrics is read through
# nginx (/replica/<i>/metrics).
#   lb_spread_test.sh GROTTO_SERVER GROTTO_LOAD
set -u
GROTTO_SERVER=$1 GROTTO_LOAD=$2
source "$(dirname "$0")/lb_common.sh"
lb_init lb-spread

seeds=""
if "$GROTTO_SERVER" --help | grep -q -- --max-worlds && "$GROTTO_LOAD" --help | grep -q -- --seeds; then
  seeds="11,22,33,44,55,66"
  lb_replica_args=(--max-worlds 8)
fi
lb_replica_args+=(--workers 1 --io-threads 1)
lb_start_replicas 3
lb_start_nginx

load_args=(--server "ws://127.0.0.1:$lb_nginx_port/ws" --players 24 --mode walk --duration 6
  --verify --max-stalls 0 --json "$lb_dir/load.json" --quiet --io-threads 2 --decode-workers 1)
[[ -n "$seeds" ]] && load_args+=(--seeds "$seeds")
timeout 60 "$GROTTO_LOAD" "${load_args[@]}" >"$lb_dir/load.log" 2>&1
rc=$?
[[ $rc -eq 0 ]] || lb_fail "grotto-load through nginx exited $rc: $(tail -n 5 "$lb_dir/load.log")"
[[ "$(lb_json "$lb_dir/load.json" errors_total)" == 0 ]] || lb_fail "errors reported"
ready=$(lb_json "$lb_dir/load.json" rooms.ready)
((ready > 0)) || lb_fail "no room arrived through nginx"

# Rooms built per replica, read through nginx.
used=0 built_total=0
for i in 0 1 2; do
  built=$(lb_metric "$i" grotto_rooms_built_total)
  [[ "$built" =~ ^[0-9]+$ ]] || lb_fail "/replica/$i/metrics through nginx has no grotto_rooms_built_total"
  echo "replica $i (port ${lb_replica_port[$i]}): $built rooms built"
  ((built > 0)) && used=$((used + 1))
  built_total=$((built_total + built))
done
((used >= 2)) || lb_fail "rooms were built on $used replica(s); the hash should spread them over more"

# Which replica each WebSocket went to, from the access log (written when a WebSocket closes).
log="$lb_dir/nginx/logs/access.log"
lb_wait 10 grep -q 'GET /ws' "$log" || lb_fail "nginx logged no WebSocket"
if [[ -n "$seeds" ]]; then
  # Every world on exactly one replica: the hash on $arg_seed.
  IFS=, read -r -a seed_list <<<"$seeds"
  for s in "${seed_list[@]}"; do
    upstreams=$(grep "GET /ws?seed=$s " "$log" | sed -n 's/.* upstream=\([^ ]*\) .*/\1/p' | sort -u)
    n=$(grep -c . <<<"$upstreams")
    [[ $n -eq 1 ]] || lb_fail "world $s went to $n replicas ($(tr '\n' ' ' <<<"$upstreams")); the hash should keep it on one"
    echo "world $s -> $upstreams"
  done
fi
spread=$(grep 'GET /ws' "$log" | sed -n 's/.* upstream=\([^ ]*\) .*/\1/p' | sort -u | grep -c .)
((spread >= 2)) || lb_fail "all WebSockets went to $spread replica(s)"
echo "24 players through nginx: $ready rooms, 0 errors, 0 stalls; $built_total rooms built on $used of 3 replicas${seeds:+ (worlds $seeds, each on one replica)}"
