#!/usr/bin/env bash
# deploy/nginx/render.sh as an operator meets it: a config nginx accepts, with every replica in
# the hashed upstream and a /replica/<i>/ location each, and bad arguments refused with a message
# that names the option.
set -u
render="$(dirname "$0")/../../deploy/nginx/render.sh"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fail=0

out=$(bash "$render" --prefix "$dir/ok" --listen 127.0.0.1:18080 \
  --replicas 127.0.0.1:7001,localhost:7002,[::1]:7003 2>&1) ||
  { echo "FAIL: a valid config was refused: $out"; fail=1; }
conf="$dir/ok/conf/nginx.conf"
for want in 'hash $grotto_route consistent;' 'server 127.0.0.1:7001 max_fails=1 fail_timeout=5s;' \
  'server [::1]:7003 max_fails=1' 'location ~ ^/replica/2/(metrics|healthz|readyz)$' \
  'proxy_set_header Upgrade $http_upgrade;' 'proxy_buffering off;' 'listen 127.0.0.1:18080;'; do
  grep -qF -- "$want" "$conf" 2>/dev/null || { echo "FAIL: the config lacks '$want'"; fail=1; }
done
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
[[ $fail -eq 0 ]] && echo "render.sh: nginx accepts its config; bad arguments are named"
exit $fail
