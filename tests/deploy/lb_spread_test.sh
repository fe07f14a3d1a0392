#!/usr/bin/env bash
# Three multi-world grotto-server replicas (--max-worlds) behind nginx (deploy/nginx): 24 walking
# players in eight worlds (grotto-load --seeds) get every room verified, no errors and no stalls,
# and the sessions are spread by load, not by world: each replica holds a third of
# them (nginx's least_conn; the access log, written when a WebSocket closes, says where each
# went), and a world's players are served by whichever replica took them (worlds open on more
# than one replica). Each replica's /metrics is read through nginx (/replica/<i>/metrics).
#   lb_spread_test.sh GROTTO_SERVER GROTTO_LOAD
set -u
GROTTO_SERVER=$1 GROTTO_LOAD=$2
source "$(dirname "$0")/lb_common.sh"
lb_init lb-spread

seeds="11,22,33,44,55,66,77,88"  # 8 worlds, 3 players each
lb_replica_args=(--max-worlds 16 --workers 1 --io-threads 1)
lb_start_replicas 3
lb_start_nginx

load_args=(--server "ws://127.0.0.1:$lb_nginx_port/ws" --players 24 --mode walk --duration 6
  --verify --max-stalls 0 --json "$lb_dir/load.json" --quiet --io-threads 2 --decode-workers 1
  --seeds "$seeds")
timeout 60 "$GROTTO_LOAD" "${load_args[@]}" >"$lb_dir/load.log" 2>&1
rc=$?
[[ $rc -eq 0 ]] || lb_fail "grotto-load through nginx exited $rc: $(tail -n 5 "$lb_dir/load.log")"
[[ "$(lb_json "$lb_dir/load.json" errors_total)" == 0 ]] || lb_fail "errors reported"
ready=$(lb_json "$lb_dir/load.json" rooms.ready)
((ready > 0)) || lb_fail "no room arrived through nginx"

# Where each WebSocket went, from the access log: the replicas share the sessions evenly.
log="$lb_dir/nginx/logs/access.log"
lb_wait 10 grep -q 'GET /ws' "$log" || lb_fail "nginx logged no WebSocket"
opened_total=0
for i in 0 1 2; do
  n=$(grep 'GET /ws' "$log" | grep -c "upstream=127.0.0.1:${lb_replica_port[$i]} ")
  opened=$(lb_metric "$i" grotto_worlds_opened_total)
  built=$(lb_metric "$i" grotto_rooms_built_total)
  [[ "$built" =~ ^[0-9]+$ && "$opened" =~ ^[0-9]+$ ]] ||
    lb_fail "/replica/$i/metrics through nginx lacks grotto_rooms_built_total or grotto_worlds_opened_total"
  echo "replica $i (port ${lb_replica_port[$i]}): $n sessions, $opened worlds opened, $built rooms built"
  ((n >= 6 && n <= 10)) || lb_fail "replica $i took $n of the 24 sessions; fewest connections first should give each about 8"
  ((built > 0)) || lb_fail "replica $i has players but built no room"
  opened_total=$((opened_total + opened))
done
# Eight worlds over three replicas by load: a world's three players need not share a replica, so
# the replicas opened more worlds than there are (with the old hash by seed they opened 8).
((opened_total > 8)) ||
  lb_fail "the replicas opened $opened_total worlds for 8: sessions still follow the world"
echo "24 players in worlds $seeds through nginx: $ready rooms, 0 errors, 0 stalls; sessions by load, $opened_total worlds opened over 3 replicas"
