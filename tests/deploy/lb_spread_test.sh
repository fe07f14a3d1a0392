#!/usr/bin/env bash
# Three multi-world grotto-server replicas (--max-worlds) behind nginx (deploy/nginx): 24 walking
# players in twelve worlds (grotto-load --seeds) get every room verified, no errors and no stalls,
# and the rooms are spread over the replicas as the hash says: every world's connections
# (nginx's access log) land on exactly one replica, which is the one that opened that world
# (its grotto_worlds_opened_total), and the worlds cover more than one replica. Each replica's
# /metrics is read through nginx (/replica/<i>/metrics).
#   lb_spread_test.sh GROTTO_SERVER GROTTO_LOAD
set -u
GROTTO_SERVER=$1 GROTTO_LOAD=$2
source "$(dirname "$0")/lb_common.sh"
lb_init lb-spread

seeds="11,22,33,44,55,66,77,88,99,110,121,132"  # 12 worlds: all on one replica ~1e-5
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

# Which replica each WebSocket went to, from the access log (written when a WebSocket closes):
# every world on exactly one replica (the hash on $arg_seed).
log="$lb_dir/nginx/logs/access.log"
lb_wait 10 grep -q 'GET /ws' "$log" || lb_fail "nginx logged no WebSocket"
declare -A worlds_on=()  # replica index -> worlds the hash sent there
IFS=, read -r -a seed_list <<<"$seeds"
for s in "${seed_list[@]}"; do
  received=$(lb_json "$lb_dir/load.json" "rooms_received_by_seed.$s")
  [[ "${received:-0}" -gt 0 ]] || lb_fail "no room of world $s arrived"
  upstreams=$(grep "GET /ws?seed=$s " "$log" | sed -n 's/.* upstream=\([^ ]*\) .*/\1/p' | sort -u)
  n=$(grep -c . <<<"$upstreams")
  [[ $n -eq 1 ]] || lb_fail "world $s went to $n replicas ($(tr '\n' ' ' <<<"$upstreams")); the hash should keep it on one"
  for i in 0 1 2; do
    [[ "$upstreams" == "127.0.0.1:${lb_replica_port[$i]}" ]] && worlds_on[$i]=$((${worlds_on[$i]:-0} + 1))
  done
  echo "world $s -> $upstreams ($received rooms)"
done

# Each replica opened exactly the worlds sent to it, and built rooms only if it had some.
used=0 built_total=0
for i in 0 1 2; do
  built=$(lb_metric "$i" grotto_rooms_built_total)
  opened=$(lb_metric "$i" grotto_worlds_opened_total)
  [[ "$built" =~ ^[0-9]+$ && "$opened" =~ ^[0-9]+$ ]] ||
    lb_fail "/replica/$i/metrics through nginx lacks grotto_rooms_built_total or grotto_worlds_opened_total"
  echo "replica $i (port ${lb_replica_port[$i]}): ${worlds_on[$i]:-0} worlds, $opened opened, $built rooms built"
  [[ "$opened" -eq "${worlds_on[$i]:-0}" ]] ||
    lb_fail "replica $i opened $opened worlds but the hash sent it ${worlds_on[$i]:-0}"
  if ((${worlds_on[$i]:-0} > 0)); then
    ((built > 0)) || lb_fail "replica $i has worlds but built no room"
    used=$((used + 1))
  else
    ((built == 0)) || lb_fail "replica $i has no world but built $built rooms"
  fi
  built_total=$((built_total + built))
done
((used >= 2)) || lb_fail "the twelve worlds went to $used replica(s); the hash should spread them over more"
echo "24 players in worlds $seeds through nginx: $ready rooms, 0 errors, 0 stalls; $built_total rooms built on $used of 3 replicas, each world on one"
