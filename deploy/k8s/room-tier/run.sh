#!/bin/sh
# The room tier's entrypoint (room-tier-deployment.yaml; nginx.conf beside this file says what the
# tier does). It keeps nginx's owner ring equal to the ready grotto-server pods:
#   1. waits until the headless Service's name resolves (at least one ready pod), writes
#      PREFIX/conf/ring.conf (one `server IP:PORT` per address) and starts nginx in the foreground;
#   2. every INTERVAL seconds resolves the name again and, when the set of addresses changed and
#      is not empty, rewrites ring.conf, checks it with `nginx -t` and reloads nginx (SIGHUP, what
#      `nginx -s reload` sends): old workers finish their requests, new ones use the new ring;
#   3. on SIGTERM asks nginx for a graceful stop (SIGQUIT) and exits with nginx's status.
# An empty answer (every pod unready, or DNS down) keeps the last ring: nginx's passive checks
# and proxy_next_upstream skip owners that do not answer, and replicas build rooms themselves
# when the tier fails. POSIX sh with getent, awk and sort, as in Debian-based nginx images.
#
# Environment (defaults for the pod): GROTTO_RING_NAME (grotto-server-ring), GROTTO_RING_PORT
# (7878), GROTTO_RING_INTERVAL (10 s), GROTTO_TIER_PREFIX (/var/cache/grotto-room-tier, writable),
# GROTTO_NGINX (nginx; not NGINX, which nginx itself reads as inherited sockets).
# tests/deploy/manifests_test.sh runs this script offline with a scratch prefix.
set -u

ring_name=${GROTTO_RING_NAME:-grotto-server-ring}
ring_port=${GROTTO_RING_PORT:-7878}
interval=${GROTTO_RING_INTERVAL:-10}
prefix=${GROTTO_TIER_PREFIX:-/var/cache/grotto-room-tier}
nginx=${GROTTO_NGINX:-nginx}
conf_src=$(dirname "$0")/nginx.conf

log() { echo "room-tier $*" >&2; }
# "servers=N addresses=A,B,..." for a list of addresses, one a line.
summary() { echo "servers=$(printf '%s\n' "$1" | grep -c .) addresses=$(printf '%s' "$1" | tr '\n' ,)"; }

# The ring's addresses, sorted, one a line (getent prints each address once per socket type).
resolve() { getent ahostsv4 "$ring_name" 2>/dev/null | awk '{print $1}' | sort -u; }

# Writes ring.conf for the addresses in $1. Same passive checks as deploy/nginx (render.sh's
# defaults): one failed connect skips a pod for 5 s.
write_ring() {
  for ip in $1; do
    echo "server $ip:$ring_port max_fails=1 fail_timeout=5s;"
  done >"$prefix/conf/ring.conf.new" && mv "$prefix/conf/ring.conf.new" "$prefix/conf/ring.conf"
}

nginx_cmd() { "$nginx" -p "$prefix/" -c conf/nginx.conf -e stderr "$@"; }

mkdir -p "$prefix/conf" "$prefix/temp" || exit 1
cp "$conf_src" "$prefix/conf/nginx.conf" || exit 1

stopping=0
nginx_pid=
# shellcheck disable=SC2317  # invoked by the trap
on_term() {
  stopping=1
  [ -n "$nginx_pid" ] && kill -QUIT "$nginx_pid" 2>/dev/null
}
trap on_term TERM INT

# Sleeps INTERVAL seconds, woken early by SIGTERM (a trap runs when `wait` returns).
pause() {
  sleep "$interval" &
  wait $! 2>/dev/null
}

ring=$(resolve)
while [ -z "$ring" ]; do
  [ "$stopping" -eq 1 ] && exit 0
  log "event=waiting_for_ring name=$ring_name"
  pause
  ring=$(resolve)
done
write_ring "$ring"
nginx_cmd -t -q || exit 1
log "event=start $(summary "$ring")"
# Not through nginx_cmd: a backgrounded function is a subshell, and its pid would get the signals.
"$nginx" -p "$prefix/" -c conf/nginx.conf -e stderr -g 'daemon off;' &
nginx_pid=$!
[ "$stopping" -eq 1 ] && kill -QUIT "$nginx_pid" 2>/dev/null

while kill -0 "$nginx_pid" 2>/dev/null; do
  pause
  [ "$stopping" -eq 1 ] && continue
  new=$(resolve)
  [ -z "$new" ] && { log "event=ring_empty name=$ring_name action=kept_last_ring"; continue; }
  [ "$new" = "$ring" ] && continue
  cp "$prefix/conf/ring.conf" "$prefix/conf/ring.conf.old"
  write_ring "$new"
  if nginx_cmd -t -q; then
    kill -HUP "$nginx_pid"
    log "event=ring_changed $(summary "$new")"
    ring=$new
  else
    mv "$prefix/conf/ring.conf.old" "$prefix/conf/ring.conf"
    log "event=ring_refused $(summary "$new") reason=nginx_t_failed"
  fi
done
wait "$nginx_pid"
status=$?
log "event=stopped status=$status"
exit "$status"
