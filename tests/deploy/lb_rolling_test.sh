#!/usr/bin/env bash
# Rolling restart behind nginx: each of three replicas in turn gets SIGTERM (graceful drain),
# is started again on its port, and the next goes only once its /readyz (read through nginx)
# answers and nginx's fail_timeout has run out (the refused connects while it was down mark it
# failed for that long; taking the next one down sooner leaves nginx with no live replica and
# players get 502s). The players through nginx see no errors: grotto-load exits 0 with errors 0
# and every room verified; reconnects and the drain's `service_restart` notices are expected
# (grotto-load reports them apart from errors).
#   lb_rolling_test.sh GROTTO_SERVER GROTTO_LOAD
set -u
GROTTO_SERVER=$1 GROTTO_LOAD=$2
source "$(dirname "$0")/lb_common.sh"
lb_init lb-rolling

fail_timeout=2
lb_replica_args=(--workers 1 --io-threads 1)
lb_start_replicas 3
lb_start_nginx --fail-timeout "$fail_timeout"

timeout 75 "$GROTTO_LOAD" --server "ws://127.0.0.1:$lb_nginx_port/ws" --players 12 --mode walk \
  --duration 35 --verify --json "$lb_dir/load.json" --quiet --io-threads 2 --decode-workers 1 \
  >"$lb_dir/load.log" 2>&1 &
load_pid=$!
lb_pids+=("$load_pid")
sleep 3

for i in 0 1 2; do
  lb_stop_replica "$i" TERM
  lb_start_replica "$i" "${lb_replica_port[$i]}"
  lb_wait 20 lb_http_ok "$lb_nginx_port" "/replica/$i/readyz" ||
    lb_fail "replica $i not ready through nginx after its restart"
  sleep "$((fail_timeout + 1))"
  echo "replica $i restarted (SIGTERM), ready, back in nginx's rotation"
done
kill -0 "$load_pid" 2>/dev/null || lb_fail "grotto-load ended before the rolling restart did; make --duration longer"

lb_wait 70 lb_pid_gone "$load_pid" || lb_fail "grotto-load did not finish"
wait "$load_pid"
rc=$?
json="$lb_dir/load.json"
for key in streams_failed players_without_room verify.failures; do
  [[ "$(lb_json "$json" "$key")" == 0 ]] || lb_fail "$key is $(lb_json "$json" "$key"), want 0"
done
lb_all_players_connected "$json" 12 ||
  lb_fail "players still disconnected at the end: $(grep -o '"state": "[a-z_]*"' "$json" | sort | uniq -c | tr -s ' \n' ' ')"
[[ "$(lb_json "$json" errors_total)" == 0 ]] ||
  lb_fail "players saw errors during the rolling restart: $(grep -o '"errors": {[^}]*}' "$json" | head -n 1)"
[[ $rc -eq 0 ]] || lb_fail "grotto-load exited $rc during the rolling restart: $(tail -n 8 "$lb_dir/load.log")"
notices=$(lb_json "$json" restart_notices)
((notices > 0)) || lb_fail "no player was told of a drain (service_restart notices: ${notices:-none})"
echo "rolling restart of 3 replicas: $(lb_json "$json" reconnects) reconnects, $notices drain notices, $(lb_json "$json" rooms.ready) rooms ready, no errors"
