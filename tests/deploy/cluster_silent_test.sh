#!/usr/bin/env bash
# A room owner that accepts connections and never answers: three replicas take the
# players, and the room tier's ring (deploy/nginx/render.sh --owners) holds them plus a silent
# peer (a socket that accepts and reads, never writes). Its rooms stall at nginx until its read
# timeout; the replicas asking for them give up after their wait (150 ms for a room due now, the
# want's slack for prefetch) and build them themselves. 24 walking players get every room
# verified with no errors, the next room (due within a second) at p99 under the owner timeout,
# and the replicas count the owner failures. Stalls are reported, not gated: alone on this
# machine the run has 0, but one in a few runs beside the suite's other tests (RelWithDebInfo
# binaries) had 1-2, and the latency gate is what says a silent owner holds nobody up.
#   cluster_silent_test.sh GROTTO_SERVER GROTTO_LOAD
set -u
GROTTO_SERVER=$1 GROTTO_LOAD=$2
source "$(dirname "$0")/lb_common.sh"
lb_init cluster-silent

python=/usr/bin/python3
[[ -x $python ]] || python=python3
# The silent peer: prints its port, accepts forever, reads and discards, never answers.
"$python" -u -c '
import socket, threading
s = socket.socket(); s.bind(("127.0.0.1", 0)); s.listen(256)
print(s.getsockname()[1])
def drain(c):
    while c.recv(4096): pass
while True:
    c, _ = s.accept()
    threading.Thread(target=drain, args=(c,), daemon=True).start()
' >"$lb_dir/silent.port" 2>"$lb_dir/silent.log" &
lb_pids+=("$!")
lb_wait 10 grep -qs . "$lb_dir/silent.port" || lb_fail "the silent peer did not start"
silent="127.0.0.1:$(head -n 1 "$lb_dir/silent.port")"

# nginx's port first: the replicas are started pointing their room tier at it.
for attempt in 1 2 3 4 5; do
  port=$((20000 + RANDOM % 40000))
  lb_http "$port" / >/dev/null || break
done
lb_replica_args=(--workers 1 --io-threads 1 --room-tier "http://127.0.0.1:$port")
lb_start_replicas 3
replicas="" owners=""
for i in 0 1 2; do replicas+="${replicas:+,}127.0.0.1:${lb_replica_port[$i]}"; done
owners="$replicas,$silent"
bash "$lb_repo/deploy/nginx/render.sh" --prefix "$lb_dir/nginx" --listen "127.0.0.1:$port" \
  --replicas "$replicas" --owners "$owners" --run >>"$lb_dir/nginx.log" 2>&1 &
lb_nginx_pid=$!
lb_pids+=("$lb_nginx_pid")
lb_nginx_port=$port
lb_wait 10 lb_nginx_up || lb_fail "nginx did not start on $port (see $lb_dir/nginx.log)"

timeout 90 "$GROTTO_LOAD" --server "ws://127.0.0.1:$port/ws" --seed 7 --players 24 --spread \
  --speed 10 --duration 15 --verify --json "$lb_dir/load.json" --quiet \
  --io-threads 2 --decode-workers 1 >"$lb_dir/load.log" 2>&1
rc=$?
[[ $rc -eq 0 ]] || lb_fail "grotto-load exited $rc with a silent owner in the ring: $(tail -n 5 "$lb_dir/load.log")"
json="$lb_dir/load.json"
for key in errors_total streams_failed players_without_room rooms.given_up verify.failures; do
  [[ "$(lb_json "$json" "$key")" == 0 ]] || lb_fail "$key is $(lb_json "$json" "$key"), want 0"
done
urgent_p99=$(lb_json "$json" urgent_latency_ms.p99)
awk -v p="$urgent_p99" 'BEGIN { exit !(p < 1000) }' ||
  lb_fail "the next room's p99 is $urgent_p99 ms with a silent owner (want under the 1,000 ms owner timeout)"
failures=0
for i in 0 1 2; do failures=$((failures + $(lb_metric "$i" grotto_owner_failures_total))); done
((failures > 0)) || lb_fail "no replica counted an owner failure: the silent peer owned no room asked for?"
silent_tries=$(grep 'GET /rooms/' "$lb_dir/nginx/logs/access.log" | grep -c "upstream=$silent")
echo "silent owner $silent in the ring: $(lb_json "$json" rooms.ready) rooms verified, $(lb_json "$json" stalls.count) stalls, 0 errors; next room p99 $urgent_p99 ms; $failures rooms built by the asking replica after its wait; nginx tried the silent peer $silent_tries times"
