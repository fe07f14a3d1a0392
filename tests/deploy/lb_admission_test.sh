#!/usr/bin/env bash
# Admission across replicas behind nginx (deploy/nginx, proto/PROTOCOL.md "Balancers"): replica 0
# has room for one player (--max-players 1), replica 1 for three. Players connect through nginx one
# at a time and stay. None waits in a queue while a replica has room: the first four are
# welcomed (least_conn alone, counting connections, sends the third or the fourth into replica
# 0's queue while replica 1 has room). With both full, the fifth is queued: every replica declined
# its marked upgrade, and nginx's fallback sent it unmarked. Each replica counts the newcomers it
# sent on (grotto_admission_redirected_total). The players' own reports (grotto-load --json) say
# the same: queued never for the four, queued to the end for the fifth.
#   lb_admission_test.sh GROTTO_SERVER GROTTO_LOAD
set -u
GROTTO_SERVER=$1 GROTTO_LOAD=$2
source "$(dirname "$0")/lb_common.sh"
lb_init lb-admission

# --max-players alone decides (--admission-late-ms 0): a replica slowed by this machine's other
# work never queues anyone for being late, so what happens does not depend on timing.
common=(--workers 1 --io-threads 1 --admission-late-ms 0)
lb_replica_args=("${common[@]}" --max-players 1)
lb_start_replica 0
lb_replica_args=("${common[@]}" --max-players 3)
lb_start_replica 1
lb_start_nginx

# replica I's players (welcomed and in), queued sessions and answered sessions (players + queued:
# every session whose hello was answered).
sessions() { echo $(($(lb_metric "$1" grotto_connections_open) - $(lb_metric "$1" grotto_handshakes_open))); }
queued() { lb_metric "$1" grotto_sessions_queued; }
players() { echo $(($(sessions "$1") - $(queued "$1"))); }
answered() { (($(sessions 0) + $(sessions 1) == $1)); }
state() {
  echo "replica 0: $(players 0) players, $(queued 0) queued; replica 1: $(players 1) players, $(queued 1) queued"
}

# Every player's run ends at the same time, well after the last one has connected (each connect
# takes about a second here; the players must all still be there when the fifth arrives).
end=$((SECONDS + 25))
start_player() {  # player [seconds it ends before the others]
  local k=$1 left=$((end - SECONDS - ${2:-0}))
  ((left >= 8)) || lb_fail "player $k would start with ${left} s left: connecting is too slow here"
  "$GROTTO_LOAD" --server "ws://127.0.0.1:$lb_nginx_port/ws" --players 1 --mode walk --speed 0.5 \
    --horizon 2 --duration "$left" --rng-seed "$k" --json "$lb_dir/player-$k.json" --quiet \
    --io-threads 1 --decode-workers 1 >"$lb_dir/player-$k.log" 2>&1 &
  player_pid[$k]=$!
  lb_pids+=("$!")
  lb_wait 15 answered "$k" || lb_fail "player $k got no answer to its hello through nginx: $(state)"
}

player_pid=()
for k in 1 2 3 4; do
  start_player "$k"
  echo "player $k connected: $(state)"
  (($(queued 0) + $(queued 1) == 0)) ||
    lb_fail "player $k was queued though a replica had room: $(state)"
done
(($(players 0) == 1 && $(players 1) == 3)) || lb_fail "4 players should fill both replicas: $(state)"

# The fifth ends 5 s before the others: they leave one after another when their runs end, and
# the fifth, still queued then, would be let in as the first of them left.
start_player 5 5
echo "player 5 connected: $(state)"
(($(queued 0) + $(queued 1) == 1)) ||
  lb_fail "with both replicas full the fifth player should wait in a queue: $(state)"
for i in 0 1; do
  n=$(lb_metric "$i" 'grotto_admission_redirected_total{reason="max_players"}')
  [[ "$n" =~ ^[0-9]+$ ]] && ((n >= 1)) ||
    lb_fail "replica $i sent on no newcomer (grotto_admission_redirected_total{reason=\"max_players\"} = '${n}')"
  echo "replica $i sent on $n marked newcomers (max_players)"
done

# The players' own reports, once their runs end.
for k in 1 2 3 4 5; do
  lb_wait 30 lb_pid_gone "${player_pid[$k]}" || lb_fail "player $k did not finish"
  wait "${player_pid[$k]}"
  json="$lb_dir/player-$k.json"
  [[ -s "$json" ]] || lb_fail "player $k wrote no report: $(tail -n 3 "$lb_dir/player-$k.log")"
  q=$(lb_json "$json" queued.players) at_end=$(lb_json "$json" queued.at_end)
  if ((k <= 4)); then
    [[ "$q" == 0 ]] || lb_fail "player $k reports it was queued ($q times)"
    lb_all_players_connected "$json" 1 || lb_fail "player $k did not end connected and playing"
  else
    [[ "$q" == 1 && "$at_end" == 1 ]] ||
      lb_fail "player 5 reports queued.players=$q queued.at_end=$at_end; it should have waited to the end"
  fi
done
echo "replicas for 1 and 3 players behind nginx: 4 players welcomed one by one, none queued while a replica had room; the fifth queued"
