#!/usr/bin/env bash
# deploy/nginx/render.sh as an operator meets it: a config nginx accepts, with every replica in
# the players' upstream (fewest connections; a newcomer's upgrade marked so that replicas without
# room at once decline it, then unmarked to @ws_queue when all do) and in the room tier's ring
# (hash of the room path, through the cache; --owners names another ring), a /replica/<i>/
# location each, and bad arguments refused with a message that names the option.
set -u
render="$(dirname "$0")/../../deploy/nginx/render.sh"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail=0

out=$(bash "$render" --prefix "$dir/ok" --listen 127.0.0.1:18080 \
  --replicas 127.0.0.1:7001,localhost:7002,[::1]:7003 2>&1) ||
  { echo "FAIL: a valid config was refused: $out"; fail=1; }
conf="$dir/ok/conf/nginx.conf"
for want in 'least_conn;' 'hash $uri consistent;' 'proxy_cache_lock on;' 'proxy_cache_key $uri;' \
  'max_size=1g' 'server 127.0.0.1:7001 max_fails=1 fail_timeout=5s;' \
  'server [::1]:7003 max_fails=1' 'location ~ ^/replica/2/(metrics|healthz|readyz)$' \
  'location /rooms/' 'proxy_set_header Upgrade $http_upgrade;' 'proxy_buffering off;' \
  'listen 127.0.0.1:18080;' 'proxy_set_header X-Grotto-Balancer try-others;' \
  'proxy_next_upstream error timeout http_403;' 'error_page 403 502 504 = @ws_queue;' \
  'location @ws_queue {' 'proxy_set_header X-Grotto-Balancer "";'; do
  grep -qF -- "$want" "$conf" 2>/dev/null || { echo "FAIL: the config lacks '$want'"; fail=1; }
done
# Every replica is in both upstreams by default (players and the ring).
[[ $(grep -c 'server 127.0.0.1:7001 max_fails' "$conf") -eq 2 ]] ||
  { echo "FAIL: replica 127.0.0.1:7001 is not in both upstreams"; fail=1; }
# --owners: the ring is those replicas, the players' upstream stays --replicas.
out=$(bash "$render" --prefix "$dir/own" --listen 18081 --replicas 127.0.0.1:7001 \
  --owners 127.0.0.1:7001,127.0.0.1:7009 --room-cache-size 64m 2>&1) ||
  { echo "FAIL: --owners was refused: $out"; fail=1; }
ring=$(sed -n '/upstream grotto_rooms/,/}/p' "$dir/own/conf/nginx.conf")
players=$(sed -n '/upstream grotto {/,/}/p' "$dir/own/conf/nginx.conf")
[[ "$ring" == *127.0.0.1:7009* && "$players" != *7009* ]] ||
  { echo "FAIL: --owners did not make the ring alone: $ring"; fail=1; }
grep -qF 'max_size=64m' "$dir/own/conf/nginx.conf" || { echo "FAIL: --room-cache-size ignored"; fail=1; }
grep -q '@[A-Z_]*@' "$conf" && { echo "FAIL: unfilled template fields: $(grep -o '@[A-Z_]*@' "$conf" | sort -u)"; fail=1; }

expect_refused() {
  local want=$1
  shift
  local out rc
  out=$(bash "$render" --prefix "$dir/bad" "$@" 2>&1)
  rc=$?
  if [[ $rc -ne 2 || "$out" != *"$want"* ]]; then
    echo "FAIL: render.sh $* should exit 2 naming '$want' (rc=$rc): $out"
    fail=1
  fi
}
expect_refused "--replicas" --listen 8080
expect_refused "--listen" --listen 70000 --replicas 127.0.0.1:7001
expect_refused "--replicas: '127.0.0.1'" --listen 8080 --replicas 127.0.0.1
expect_refused "--replicas: 'a:0'" --listen 8080 --replicas a:0
expect_refused "--max-fails" --listen 8080 --replicas a:1 --max-fails x
expect_refused "--fail-timeout" --listen 8080 --replicas a:1 --fail-timeout 0
expect_refused "--metrics-allow" --listen 8080 --replicas a:1 --metrics-allow 'x;y'
expect_refused "unknown argument '--bogus'" --bogus
expect_refused "--owners: 'x'" --listen 8080 --replicas a:1 --owners x
expect_refused "--room-cache-size" --listen 8080 --replicas a:1 --room-cache-size lots
[[ $fail -eq 0 ]] && echo "render.sh: nginx accepts its config; bad arguments are named"
exit $fail
