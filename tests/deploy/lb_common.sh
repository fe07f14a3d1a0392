# Shared by tests/deploy/lb_*.sh and bench/replicas_bench.sh (sourced, not run): grotto-server
# replicas and an unprivileged nginx in front of them (deploy/nginx/render.sh), all on
# 127.0.0.1, all in one scratch directory, every process killed on exit.
#
# The caller sets GROTTO_SERVER and GROTTO_LOAD (binaries) and calls lb_init first. Only bash
# built-ins talk HTTP (/dev/tcp), so nothing beyond deploy/setup.sh's packages is needed.

lb_repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
lb_pids=()           # every process started here, stopped by lb_cleanup
lb_replica_pid=()    # replica i's pid ("" while it is down)
lb_replica_port=()   # replica i's port, kept across restarts
lb_replica_args=()   # extra grotto-server flags for every replica
lb_nginx_port=""
lb_nginx_pid=""

# lb_init NAME: a scratch directory ($lb_dir) and the exit trap. Keeps the directory when
# GROTTO_KEEP_LB_DIR=1, for reading logs after a failure.
lb_init() {
  for b in "$GROTTO_SERVER" "$GROTTO_LOAD"; do
    [[ -x "$b" ]] || { echo "FAIL: binary '$b' not found (build grotto-server and grotto-load)"; exit 1; }
  done
  if ! command -v nginx >/dev/null && [[ ! -x /usr/sbin/nginx ]]; then
    echo "FAIL: nginx is not installed (bash deploy/setup.sh installs it)"
    exit 1
  fi
  lb_dir=$(mktemp -d "${TMPDIR:-/tmp}/grotto-$1.XXXXXX")
  # nginx started as root runs its workers as an unprivileged user, which must enter the prefix
  # (the room tier's cache lives in it).
  chmod 755 "$lb_dir"
  trap lb_cleanup EXIT
  trap 'exit 130' INT TERM
}

lb_cleanup() {
  local rc=$?
  # TERM first, so that what we started stops what it started (nginx's master its workers,
  # local-cluster.sh its replicas and nginx: a SIGKILL leaves those running, orphaned); KILL what
  # is still there after a bounded wait.
  local p deadline=$((SECONDS + 15))
  for p in "${lb_pids[@]}"; do
    kill -TERM "$p" 2>/dev/null
  done
  for p in "${lb_pids[@]}"; do
    while kill -0 "$p" 2>/dev/null && ((SECONDS < deadline)); do sleep 0.1; done
    kill -KILL "$p" 2>/dev/null
  done
  wait 2>/dev/null
  if [[ $rc -ne 0 ]]; then
    echo "--- logs in $lb_dir (last lines) ---"
    for f in "$lb_dir"/*.log "$lb_dir"/nginx/logs/error.log; do
      [[ -f "$f" ]] && { echo "== $f"; tail -n 15 "$f"; }
    done
  fi
  [[ "${GROTTO_KEEP_LB_DIR:-0}" == 1 ]] || rm -rf "$lb_dir"
  exit $rc
}

lb_fail() {
  echo "FAIL: $*"
  exit 1
}

# lb_http PORT PATH: prints the response (status line, headers, body) of GET PATH on
# 127.0.0.1:PORT; returns 1 when nothing answers within 5 s.
lb_http() {
  local port=$1 path=$2
  (
    exec 3<>"/dev/tcp/127.0.0.1/$port" || exit 1
    printf 'GET %s HTTP/1.0\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n' "$path" >&3
    timeout 5 cat <&3
  ) 2>/dev/null
}

# lb_http_ok PORT PATH: true when GET PATH answers 200.
lb_http_ok() {
  [[ "$(lb_http "$1" "$2" | head -n 1)" == *" 200 "* ]]
}

# lb_wait SECONDS COMMAND...: polls COMMAND every 0.1 s until it succeeds; false on timeout.
lb_wait() {
  local deadline=$((SECONDS + $1))
  shift
  until "$@"; do
    ((SECONDS < deadline)) || return 1
    sleep 0.1
  done
}

lb_pid_gone() { ! kill -0 "$1" 2>/dev/null; }

# lb_start_replica I [PORT]: starts replica I (port 0: an ephemeral one, read from its first
# stdout line) and waits for its /readyz. Logs go to $lb_dir/replica-I.log.
lb_start_replica() {
  local i=$1 port=${2:-0} out="$lb_dir/replica-$1.out"
  : >"$out"
  "$GROTTO_SERVER" --bind 127.0.0.1 --port "$port" "${lb_replica_args[@]}" \
    >"$out" 2>>"$lb_dir/replica-$i.log" &
  local pid=$!
  lb_pids+=("$pid")
  lb_replica_pid[$i]=$pid
  # "grotto-server listening on http://127.0.0.1:PORT (...)": first run may compile kernels.
  lb_wait 60 grep -q "listening on" "$out" || lb_fail "replica $i did not start (port $port)"
  port=$(sed -n 's|.*listening on http://127\.0\.0\.1:\([0-9]*\).*|\1|p' "$out")
  [[ -n "$port" ]] || lb_fail "replica $i printed no port: $(head -c 200 "$out")"
  lb_replica_port[$i]=$port
  lb_wait 30 lb_http_ok "$port" /readyz || lb_fail "replica $i on port $port never became ready"
}

# lb_start_replicas N: replicas 0..N-1.
lb_start_replicas() {
  local i
  for ((i = 0; i < $1; i++)); do
    lb_start_replica "$i"
  done
}

# lb_stop_replica I SIGNAL: signals replica I and waits (at most 20 s) for it to exit.
lb_stop_replica() {
  local pid=${lb_replica_pid[$1]}
  kill "-$2" "$pid" || lb_fail "replica $1 (pid $pid) was not running"
  lb_wait 20 lb_pid_gone "$pid" || lb_fail "replica $1 did not exit within 20 s of SIG$2"
  wait "$pid" 2>/dev/null
  lb_replica_pid[$1]=""
}

# lb_start_nginx: renders deploy/nginx for every started replica on a free port ($lb_nginx_port)
# and waits for nginx's /healthz. A port taken between the probe and nginx's bind: try another.
lb_start_nginx() {
  local replicas="" i attempt
  for i in "${!lb_replica_port[@]}"; do
    replicas+="${replicas:+,}127.0.0.1:${lb_replica_port[$i]}"
  done
  for attempt in 1 2 3 4 5; do
    lb_nginx_port=$((20000 + RANDOM % 40000))
    lb_http "$lb_nginx_port" / >/dev/null && continue  # something listens there already
    bash "$lb_repo/deploy/nginx/render.sh" --prefix "$lb_dir/nginx" \
      --listen "127.0.0.1:$lb_nginx_port" --replicas "$replicas" "$@" --run \
      >>"$lb_dir/nginx.log" 2>&1 &
    lb_nginx_pid=$!
    lb_pids+=("$lb_nginx_pid")
    if lb_wait 10 lb_nginx_up; then
      return 0
    fi
    kill -KILL "$lb_nginx_pid" 2>/dev/null
    wait "$lb_nginx_pid" 2>/dev/null
  done
  lb_fail "nginx did not start (see $lb_dir/nginx.log)"
}

lb_nginx_up() {
  kill -0 "$lb_nginx_pid" 2>/dev/null || return 1
  lb_http_ok "$lb_nginx_port" /healthz
}

# lb_metric I NAME: replica I's value of metric NAME (no labels), scraped through nginx.
lb_metric() {
  lb_http "$lb_nginx_port" "/replica/$1/metrics" | awk -v m="$2" '$1 == m { print $2; f = 1 } END { if (!f) print "" }'
}

# lb_json FILE EXPR: a value from grotto-load's JSON report (python3 -c is not in setup.sh's
# list, so a jq-free extractor of top-level and one-level-nested numbers).
lb_json() {
  local file=$1 key=$2
  awk -v key="$key" '
    BEGIN { n = split(key, parts, "."); depth = 0 }
    {
      line = $0
      if (match(line, /^ *"[^"]+": /)) {
        k = line; sub(/^ *"/, "", k); sub(/".*/, "", k)
        indent = match(line, /[^ ]/) - 1
        level = indent / 2
        if (level == 1) top = k
        if ((n == 1 && level == 1 && k == parts[1]) || (n == 2 && level == 2 && top == parts[1] && k == parts[2])) {
          v = line; sub(/^ *"[^"]+": /, "", v); sub(/,$/, "", v); print v; exit
        }
      }
    }' "$file"
}

# lb_stop_all: stops nginx and every replica (SIGTERM, bounded) and forgets them, so a caller
# can start a fresh set (bench/replicas_bench.sh: cold caches for every measurement).
lb_stop_all() {
  local i
  if [[ -n "$lb_nginx_pid" ]]; then
    kill -QUIT "$lb_nginx_pid" 2>/dev/null
    lb_wait 10 lb_pid_gone "$lb_nginx_pid" || kill -KILL "$lb_nginx_pid" 2>/dev/null
    wait "$lb_nginx_pid" 2>/dev/null
    lb_nginx_pid=""
  fi
  for i in "${!lb_replica_pid[@]}"; do
    [[ -n "${lb_replica_pid[$i]}" ]] && lb_stop_replica "$i" TERM
  done
  lb_replica_pid=()
  lb_replica_port=()
}

# lb_all_players_connected FILE N: true when all N players of grotto-load's report ended
# connected (per_player state "ready"), i.e. none was left reconnecting against 502s.
lb_all_players_connected() {
  [[ "$(grep -c '"state": "ready"' "$1")" -eq "$2" ]]
}
