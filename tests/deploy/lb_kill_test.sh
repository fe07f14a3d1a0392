#!/usr/bin/env bash
# A replica killed mid-run (SIGKILL) and started again on its port: grotto-load's players
# through nginx reconnect (nginx skips the dead replica: passive health check and
# proxy_next_upstream), every room they asked for arrives and verifies, no errors, and the
# JSON report counts the reconnects.
#   lb_kill_test.sh GROTTO_SERVER GROTTO_LOAD
set -u
GROTTO_SERVER=$1 GROTTO_LOAD=$2
source "$(dirname "$0")/lb_common.sh"
lb_init lb-kill

lb_replica_args=(--workers 1 --io-threads 1)
lb_start_replicas 3
lb_start_nginx

timeout 60 "$GROTTO_LOAD" --server "ws://127.0.0.1:$lb_nginx_port/ws" --players 12 --mode walk \
  --duration 12 --verify --json "$lb_dir/load.json" --quiet --io-threads 2 --decode-workers 1 \
  >"$lb_dir/load.log" 2>&1 &
load_pid=$!
lb_pids+=("$load_pid")

# The victim: the replica with the most players on it once everyone is connected.
connected() {
  local total=0 i n
  for i in 0 1 2; do
    n=$(lb_metric "$i" grotto_connections_open)
    total=$((total + ${n:-0}))
  done
  ((total >= 12))
}
lb_wait 20 connected || lb_fail "the 12 players did not all connect through nginx"
sleep 2
victim=0 most=-1
for i in 0 1 2; do
  n=$(lb_metric "$i" grotto_connections_open)
  ((n > most)) && { victim=$i; most=$n; }
done
echo "killing replica $victim (port ${lb_replica_port[$victim]}, $most players) with SIGKILL"
lb_stop_replica "$victim" KILL
sleep 2
lb_start_replica "$victim" "${lb_replica_port[$victim]}"
echo "replica $victim is back on port ${lb_replica_port[$victim]}"

lb_wait 55 lb_pid_gone "$load_pid" || lb_fail "grotto-load did not finish"
wait "$load_pid"
rc=$?
[[ $rc -eq 0 ]] || lb_fail "grotto-load exited $rc after the kill: $(tail -n 5 "$lb_dir/load.log")"
json="$lb_dir/load.json"
reconnects=$(lb_json "$json" reconnects)
((reconnects > 0)) || lb_fail "the report shows $reconnects reconnects; the killed replica's players must have reconnected"
for key in errors_total streams_failed players_without_room rooms.given_up verify.failures; do
  [[ "$(lb_json "$json" "$key")" == 0 ]] || lb_fail "$key is $(lb_json "$json" "$key"), want 0"
done
lb_all_players_connected "$json" 12 ||
  lb_fail "players still disconnected at the end: $(grep -o '"state": "[a-z_]*"' "$json" | sort | uniq -c | tr -s ' \n' ' ')"
ready=$(lb_json "$json" rooms.ready)
checked=$(lb_json "$json" verify.rooms_checked)
((ready > 0 && checked > 0)) || lb_fail "no rooms arrived ($ready) or none was verified ($checked)"
echo "SIGKILL of replica $victim: $reconnects reconnects, $ready rooms ready, $checked verified, 0 given up, 0 errors"
