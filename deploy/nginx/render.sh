#!/usr/bin/env bash
# Writes a concrete nginx config for grotto-server replicas from deploy/nginx/grotto.conf.in into
# PREFIX/conf/nginx.conf (with PREFIX/logs and PREFIX/temp), checks it with `nginx -t`, and with
# --run runs nginx in the foreground in that prefix, unprivileged, beside any system nginx.
# Used by tests/deploy/lb_*.sh and bench/replicas_bench.sh; an operator can try it by hand:
#
#   grotto-server --port 7001 & grotto-server --port 7002 &
#   deploy/nginx/render.sh --prefix /tmp/grotto-lb --listen 127.0.0.1:8080 \
#       --replicas 127.0.0.1:7001,127.0.0.1:7002 --run
#   grotto-load --server ws://127.0.0.1:8080/ws --players 8 --duration 10
set -euo pipefail

usage() {
  cat <<'EOF'
Usage: render.sh --prefix DIR --listen [ADDR:]PORT --replicas HOST:PORT[,HOST:PORT...] [options]

Writes DIR/conf/nginx.conf for grotto-server replicas behind nginx and checks it with `nginx -t`:
players' WebSockets on /ws to the replica with the fewest connections that has room for them at
once (when none has, to the queue of the one with the fewest connections); room URLs (/rooms/...) to
each room's owner replica (consistent hash of the path) through a cache in DIR/temp/rooms, the
room tier that replicas started with --room-tier http://ADDR:PORT use; /healthz of nginx itself;
/replica/<i>/{metrics,healthz,readyz} of replica i, counted from 0 in --replicas order.

Options:
  --prefix DIR           nginx prefix: conf/, logs/ (access.log, error.log), temp/, nginx.pid
  --listen [ADDR:]PORT   where players connect (ws://ADDR:PORT/ws)
  --replicas LIST        comma-separated HOST:PORT of the grotto-server replicas, at least one
  --metrics-allow LIST   comma-separated addresses/CIDRs allowed on /replica/... (default 127.0.0.1)
  --max-fails N          passive health check: failed connects before a replica is skipped (default 1)
  --fail-timeout SECONDS how long a failed replica is skipped, and the window for --max-fails (default 5)
  --workers N            nginx worker processes, or auto (default 1)
  --room-cache-size SIZE rooms kept on disk by the tier's cache, nginx size syntax (default 1g)
  --owners LIST          comma-separated HOST:PORT of the replicas that own rooms (the tier's ring;
                         default: --replicas), e.g. builders that take no players
  --nginx PATH           the nginx binary (default: nginx on PATH, else /usr/sbin/nginx)
  --run                  after writing, exec nginx in the foreground (daemon off) in DIR
  --print-command        print the nginx command line that --run would exec, and exit
  -h, --help             this text

Exit codes: 0 ok; 2 invalid arguments (the message names the option); 1 nginx rejected the config.
EOF
}

die() {
  echo "render.sh: $*" >&2
  exit 2
}

prefix="" listen="" replicas="" metrics_allow="127.0.0.1" max_fails=1 fail_timeout=5 workers=1
nginx_bin="" run=0 print_command=0 room_cache_size=1g owners=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    --prefix | --listen | --replicas | --metrics-allow | --max-fails | --fail-timeout | --workers | --nginx | --room-cache-size | --owners)
      [[ $# -ge 2 ]] || die "$1 needs a value"
      case "$1" in
        --prefix) prefix=$2 ;;
        --listen) listen=$2 ;;
        --replicas) replicas=$2 ;;
        --metrics-allow) metrics_allow=$2 ;;
        --max-fails) max_fails=$2 ;;
        --fail-timeout) fail_timeout=$2 ;;
        --workers) workers=$2 ;;
        --nginx) nginx_bin=$2 ;;
        --room-cache-size) room_cache_size=$2 ;;
        --owners) owners=$2 ;;
      esac
      shift 2
      ;;
    --run) run=1; shift ;;
    --print-command) print_command=1; shift ;;
    -h | --help) usage; exit 0 ;;
    *) die "unknown argument '$1' (see --help)" ;;
  esac
done

valid_port() { [[ "$1" =~ ^[0-9]{1,5}$ ]] && ((10#$1 >= 1 && 10#$1 <= 65535)); }

[[ -n "$prefix" ]] || die "--prefix is required (see --help)"
[[ -n "$listen" ]] || die "--listen is required (see --help)"
[[ -n "$replicas" ]] || die "--replicas is required (see --help)"
valid_port "${listen##*:}" || die "--listen: '$listen' needs a port in 1..65535 ([ADDR:]PORT)"
[[ "$max_fails" =~ ^[0-9]+$ ]] || die "--max-fails: must be a whole number (got '$max_fails')"
[[ "$fail_timeout" =~ ^[1-9][0-9]*$ ]] || die "--fail-timeout: must be whole seconds >= 1 (got '$fail_timeout')"
[[ "$room_cache_size" =~ ^[1-9][0-9]*[kKmMgG]?$ ]] || die "--room-cache-size: must be a size like 512m or 2g (got '$room_cache_size')"
[[ "$workers" == auto || "$workers" =~ ^[1-9][0-9]?$ ]] || die "--workers: must be 1..99 or auto (got '$workers')"

IFS=, read -r -a replica_list <<<"$replicas"
[[ ${#replica_list[@]} -ge 1 ]] || die "--replicas: no replica given"
host_port_re='^[][A-Za-z0-9.:_-]+:[0-9]+$'  # a name, IPv4 or [IPv6], then :PORT
for r in "${replica_list[@]}"; do
  [[ "$r" =~ $host_port_re ]] && valid_port "${r##*:}" ||
    die "--replicas: '$r' is not HOST:PORT with a port in 1..65535"
done
IFS=, read -r -a owner_list <<<"${owners:-$replicas}"
[[ ${#owner_list[@]} -ge 1 ]] || die "--owners: no replica given"
for r in "${owner_list[@]}"; do
  [[ "$r" =~ $host_port_re ]] && valid_port "${r##*:}" ||
    die "--owners: '$r' is not HOST:PORT with a port in 1..65535"
done
IFS=, read -r -a allow_list <<<"$metrics_allow"
for a in "${allow_list[@]}"; do
  [[ "$a" =~ ^[0-9A-Fa-f.:/]+$ || "$a" == all ]] ||
    die "--metrics-allow: '$a' is not an address, a CIDR or 'all'"
done

if [[ -z "$nginx_bin" ]]; then
  nginx_bin=$(command -v nginx || true)
  [[ -n "$nginx_bin" ]] || nginx_bin=/usr/sbin/nginx
fi
[[ -x "$nginx_bin" ]] || die "--nginx: no nginx at '$nginx_bin' (Debian: apt-get install nginx, or bash deploy/setup.sh)"

mkdir -p "$prefix/conf" "$prefix/logs" "$prefix/temp" || die "--prefix: cannot create '$prefix'"
prefix=$(cd "$prefix" && pwd)

upstream_servers="" owner_servers=""
for r in "${owner_list[@]}"; do
  owner_servers+="    server $r max_fails=$max_fails fail_timeout=${fail_timeout}s;"$'\n'
done
replica_upstreams=""
replica_locations=""
allow_lines=""
for a in "${allow_list[@]}"; do
  allow_lines+="      allow $a;"$'\n'
done
allow_lines+="      deny all;"
for i in "${!replica_list[@]}"; do
  r=${replica_list[$i]}
  upstream_servers+="    server $r max_fails=$max_fails fail_timeout=${fail_timeout}s;"$'\n'
  # A group of its own per replica: proxy_pass with a variable ($1) then names a group known
  # at load time, so replicas given by host name need no run-time resolver.
  replica_upstreams+="  upstream grotto_replica_$i {
    server $r;
  }"$'\n'
  replica_locations+="    location ~ ^/replica/$i/(metrics|healthz|readyz)\$ {
$allow_lines
      proxy_pass http://grotto_replica_$i/\$1;
      proxy_connect_timeout 2s;
      proxy_read_timeout 10s;
      proxy_max_temp_file_size 0;  # never spill a scrape to disk (temp/ may not be writable)
    }"$'\n'
done

template="$(dirname "$0")/grotto.conf.in"
[[ -r "$template" ]] || die "template '$template' is missing"
conf=$(<"$template")
conf=${conf//@WORKERS@/$workers}
conf=${conf//@WORKER_CONNECTIONS@/4096}
conf=${conf//@LISTEN@/$listen}
conf=${conf//@ROOM_CACHE_SIZE@/$room_cache_size}
conf=${conf//@METRICS_ALLOW@/$metrics_allow}
conf=${conf//@UPSTREAM_SERVERS@/${upstream_servers%$'\n'}}
conf=${conf//@OWNER_SERVERS@/${owner_servers%$'\n'}}
conf=${conf//@REPLICA_UPSTREAMS@/${replica_upstreams%$'\n'}}
conf=${conf//@REPLICA_LOCATIONS@/${replica_locations%$'\n'}}
printf '%s\n' "$conf" >"$prefix/conf/nginx.conf"

globals="daemon off; pid $prefix/nginx.pid; error_log $prefix/logs/error.log notice;"
command=("$nginx_bin" -p "$prefix/" -c conf/nginx.conf -g "$globals")
if [[ $print_command -eq 1 ]]; then
  printf '%q ' "${command[@]}"
  echo
  exit 0
fi
if ! out=$("${command[@]}" -t 2>&1); then
  echo "render.sh: nginx rejected $prefix/conf/nginx.conf:" >&2
  echo "$out" >&2
  exit 1
fi
[[ $run -eq 1 ]] && exec "${command[@]}"
exit 0
