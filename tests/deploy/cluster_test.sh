#!/usr/bin/env bash
# One world on many replicas: deploy/local-cluster.sh with 4 replicas behind nginx.
#   1. 40 spread players of seed 7 get every room verified, no errors, no stalls; each replica
#      holds at least 15 % of the sessions (fewest connections first); the replicas together
#      build at most 1.05 times the distinct rooms the players received (each room once, by its
#      owner, whichever replica's player wanted it).
#   2. A room URL through nginx: 200 with the immutable cache headers and a strong ETag, then a
#      cache hit, then 304 to If-None-Match.
#   3. kill -9 of a replica mid-run (players on it and rooms owned by it): no errors, every room
#      asked for arrives and verifies, and the dead replica's rooms are built by the others.
#   cluster_test.sh GROTTO_SERVER GROTTO_LOAD
set -u
GROTTO_SERVER=$1 GROTTO_LOAD=$2
source "$(dirname "$0")/lb_common.sh"
lb_init cluster

# The cluster: a free port, then local-cluster.sh in the background (killed by lb_cleanup).
start_cluster() {
  local attempt
  for attempt in 1 2 3 4 5; do
    port=$((20000 + RANDOM % 40000))
    lb_http "$port" / >/dev/null && continue
    rm -rf "$lb_dir/c"
    bash "$lb_repo/deploy/local-cluster.sh" --replicas 4 --listen "127.0.0.1:$port" \
      --prefix "$lb_dir/c" --server "$GROTTO_SERVER" >"$lb_dir/cluster.log" 2>&1 &
    cluster_pid=$!
    lb_pids+=("$cluster_pid")
    if lb_wait 60 grep -q "cluster ready" "$lb_dir/cluster.log"; then
      lb_nginx_port=$port  # lb_metric reads /replica/<i>/metrics through it
      return 0
    fi
    kill -TERM "$cluster_pid" 2>/dev/null
    wait "$cluster_pid" 2>/dev/null
  done
  lb_fail "local-cluster.sh did not start: $(tail -n 5 "$lb_dir/cluster.log")"
}
replica_pid() { sed -n "s/^replica $1 pid \([0-9]*\) .*/\1/p" "$lb_dir/cluster.log"; }
built_total() {
  local i total=0 n
  for i in 0 1 2 3; do
    n=$(lb_metric "$i" grotto_rooms_built_total)
    total=$((total + ${n:-0}))
  done
  echo "$total"
}
check_load() {  # JSON: no errors, nothing lost, every room verified
  local json=$1 key
  for key in errors_total streams_failed players_without_room rooms.given_up verify.failures; do
    [[ "$(lb_json "$json" "$key")" == 0 ]] || lb_fail "$key is $(lb_json "$json" "$key"), want 0"
  done
  (($(lb_json "$json" verify.rooms_checked) > 0)) || lb_fail "no room was verified"
}
load_args=(--seed 7 --spread --speed 10 --verify --quiet --io-threads 2 --decode-workers 1)

# ---- 1. sessions by load, each room built once ----
start_cluster
timeout 90 "$GROTTO_LOAD" --server "ws://127.0.0.1:$port/ws" --players 40 --duration 15 \
  --max-stalls 0 --json "$lb_dir/load.json" "${load_args[@]}" >"$lb_dir/load.log" 2>&1
rc=$?
[[ $rc -eq 0 ]] || lb_fail "grotto-load through the cluster exited $rc: $(tail -n 5 "$lb_dir/load.log")"
check_load "$lb_dir/load.json"
unique=$(lb_json "$lb_dir/load.json" rooms.unique)
built=$(built_total)
for i in 0 1 2 3; do
  n=$(lb_metric "$i" grotto_connections_total)
  ((n * 100 >= 40 * 15)) || lb_fail "replica $i had $n of the 40 sessions, under 15 %"
  echo "replica $i: $n sessions, $(lb_metric "$i" grotto_rooms_built_total) built, $(lb_metric "$i" grotto_rooms_fetched_total) from their owner, $(lb_metric "$i" grotto_owner_failures_total) owner failures"
done
((unique > 0 && built * 100 <= unique * 105)) ||
  lb_fail "the replicas built $built rooms for $unique distinct rooms received (over 1.05x)"
echo "40 players: $unique distinct rooms, $built built ($(awk -v b="$built" -v u="$unique" 'BEGIN { printf "%.3f", b / u }')x), 0 errors, 0 stalls"

# ---- 2. a room URL through nginx's cache ----
url=$(grep -o 'GET /rooms/[^ ]*' "$lb_dir/c/logs/access.log" | head -n 1 | cut -d' ' -f2)
[[ -n "$url" ]] || lb_fail "no room URL in nginx's access log: the replicas fetched nothing from the tier"
first=$(curl -sS "http://127.0.0.1:$port$url" -o "$lb_dir/room.bin" -D - | tr -d '\r')
grep -qi '^cache-control: public, max-age=31536000, immutable' <<<"$first" ||
  lb_fail "no immutable Cache-Control on $url: $first"
etag=$(sed -n 's/^[Ee][Tt][Aa][Gg]: *//p' <<<"$first")
[[ "$etag" == \"*\" ]] || lb_fail "no strong ETag on $url: $first"
[[ "$(head -c 4 "$lb_dir/room.bin")" == GRTO ]] || lb_fail "$url's body is not a room frame"
again=$(curl -sS "http://127.0.0.1:$port$url" -o /dev/null -D - | tr -d '\r')
grep -qi '^x-cache-status: HIT' <<<"$again" || lb_fail "a second GET of $url was not a cache hit: $again"
status=$(curl -sS -o /dev/null -w '%{http_code}' -H "If-None-Match: $etag" "http://127.0.0.1:$port$url")
[[ "$status" == 304 ]] || lb_fail "If-None-Match: $etag got $status, want 304"
echo "room URL $url: immutable, ETag $etag, then a cache hit, then 304"

# ---- the browser viewer through nginx: the page, its files, a room's extras ----
page=$(curl -sS "http://127.0.0.1:$port/" -D - -o "$lb_dir/index.html" | tr -d '\r')
grep -qi '^content-type: text/html' <<<"$page" || lb_fail "/ through nginx is not the viewer: $page"
grep -q 'viewer/main.js' "$lb_dir/index.html" || lb_fail "/ through nginx has no viewer script"
status=$(curl -sS -o /dev/null -w '%{http_code} %{content_type}' "http://127.0.0.1:$port/viewer/lib/draco_decoder.wasm")
[[ "$status" == "200 application/wasm" ]] || lb_fail "the viewer's decoder through nginx: $status"
extras=$(curl -sS "http://127.0.0.1:$port/extras/${url#/rooms/}" -o "$lb_dir/extras.json" -D - | tr -d '\r')
grep -qi '^content-type: application/json' <<<"$extras" || lb_fail "/extras/ through nginx: $extras"
grep -q '"formations":{"count":' "$lb_dir/extras.json" || lb_fail "extras through nginx: $(head -c 200 "$lb_dir/extras.json")"
echo "viewer through nginx: the page, its wasm decoder, and the extras of $url"

# ---- 3. kill -9 of a replica mid-run ----
victim_pid=$(replica_pid 1)
[[ -n "$victim_pid" ]] || lb_fail "no pid for replica 1 in the cluster's output"
before=$(built_total)
timeout 90 "$GROTTO_LOAD" --server "ws://127.0.0.1:$port/ws" --players 24 --duration 14 \
  --json "$lb_dir/kill.json" "${load_args[@]}" >"$lb_dir/kill.log" 2>&1 &
load_pid=$!
lb_pids+=("$load_pid")
sleep 5
victim_built=$(lb_metric 1 grotto_rooms_built_total)
kill -KILL "$victim_pid" || lb_fail "replica 1 (pid $victim_pid) was not running"
echo "killed replica 1 (pid $victim_pid, $victim_built rooms built) with SIGKILL"
lb_wait 80 lb_pid_gone "$load_pid" || lb_fail "grotto-load did not finish"
wait "$load_pid"
rc=$?
[[ $rc -eq 0 ]] || lb_fail "grotto-load exited $rc after the kill: $(tail -n 5 "$lb_dir/kill.log")"
check_load "$lb_dir/kill.json"
lb_all_players_connected "$lb_dir/kill.json" 24 || lb_fail "players still disconnected at the end"
# The survivors built what the dead owner's players and rooms needed after it went.
after=0
for i in 0 2 3; do after=$((after + $(lb_metric "$i" grotto_rooms_built_total))); done
grep -q "replica 1 (pid $victim_pid) exited" "$lb_dir/cluster.log" ||
  lb_fail "local-cluster.sh did not report the dead replica"
# Its rooms moved: nginx's log shows room requests that went to the dead owner first and were
# answered 200 by the next replica on the ring ("upstream=DEAD, NEXT").
victim_port=$(sed -n "s/^replica 1 pid [0-9]* port \([0-9]*\)$/\1/p" "$lb_dir/cluster.log")
moved=$(grep 'GET /rooms/' "$lb_dir/c/logs/access.log" | grep -c " 200 .*upstream=127.0.0.1:$victim_port, 127.0.0.1:")
((moved > 0)) || lb_fail "no room request moved from the dead owner (port $victim_port) to another replica"
echo "after the kill: $(lb_json "$lb_dir/kill.json" rooms.ready) rooms ready and verified, $(lb_json "$lb_dir/kill.json" reconnects) reconnects, 0 errors; $moved room requests moved from the dead owner to the next on the ring; survivors built $after rooms in all"
