#!/usr/bin/env bash
# grotto-server's descriptor limit (server/fd_limit.hpp) with the real program: started
# under low RLIMIT_NOFILE limits (bash's ulimit, then exec), it must raise the soft limit to the
# hard one (its log line and /proc/PID/limits both say so) and warn, on one line with the numbers,
# when the limit is still below what --max-connections and --max-handshakes need. Each start is
# stopped with SIGTERM once it listens; every wait is bounded.
#
# Usage: fd_limit_test.sh GROTTO_SERVER
set -u
server=${1:?usage: fd_limit_test.sh GROTTO_SERVER}
[[ -x "$server" ]] || { echo "FAIL: '$server' is not an executable"; exit 1; }
dir=$(mktemp -d "${TMPDIR:-/tmp}/grotto-fdlimit.XXXXXX")
pid=""
cleanup() {
  [[ -n "$pid" ]] && kill -KILL "$pid" 2>/dev/null
  rm -rf "$dir"
}
trap cleanup EXIT
failures=0
fail() {
  echo "FAIL: $*"
  failures=$((failures + 1))
}

# run NAME SOFT HARD ARGS...: starts grotto-server with RLIMIT_NOFILE SOFT:HARD, waits (30 s at
# most) until it listens, keeps its "Max open files" from /proc in $dir/NAME.limits, stops it
# with SIGTERM (exit 0 within 15 s). Its log is $dir/NAME.log.
run() {
  local name=$1 soft=$2 hard=$3
  shift 3
  local log="$dir/$name.log"
  # The soft limit first: a hard limit below the soft one in force would be refused.
  bash -c 'ulimit -Sn "$1" && ulimit -Hn "$2" && shift 2 && exec "$@"' _ "$soft" "$hard" \
    "$server" --port 0 --opencl-device none --workers 1 --io-threads 1 "$@" >"$log" 2>&1 &
  pid=$!
  local i
  for ((i = 0; i < 300; ++i)); do
    grep -q "listening on" "$log" && break
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  if ! grep -q "listening on" "$log"; then
    fail "$name: grotto-server did not listen within 30 s"
    sed 's/^/  /' "$log" | tail -n 20
    return 1
  fi
  grep "Max open files" "/proc/$pid/limits" >"$dir/$name.limits"
  kill -TERM "$pid"
  for ((i = 0; i < 150; ++i)); do
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  local rc=0
  if kill -0 "$pid" 2>/dev/null; then
    fail "$name: grotto-server did not stop within 15 s of SIGTERM"
  else
    wait "$pid" || rc=$?
    [[ $rc -eq 0 ]] || fail "$name: grotto-server exited $rc after SIGTERM"
  fi
  pid=""
}

# expect_line NAME PATTERN: exactly one line of NAME's log matches the extended regex PATTERN.
expect_line() {
  local n
  n=$(grep -cE "$2" "$dir/$1.log")
  if [[ $n -ne 1 ]]; then
    fail "$1: expected one line matching '$2', found $n"
    sed 's/^/  /' "$dir/$1.log" | grep -E "fd_limit|listening" | head -n 5
  fi
}

# expect_limits NAME SOFT HARD: the running server's limits, as the kernel reports them.
expect_limits() {
  read -r -a f <"$dir/$1.limits"
  # "Max open files  SOFT  HARD  files"
  [[ "${f[3]:-}" == "$2" && "${f[4]:-}" == "$3" ]] ||
    fail "$1: /proc limits say soft ${f[3]:-?} hard ${f[4]:-?}, expected $2 and $3"
}

# 1. 64 descriptors, hard limit too: nothing to raise, and 1,000 players need 1,636
#    (1000 + 512 + 64 spare sockets + 4 reserve + 32 process + 24 for the one OpenCL context).
if run low 64 64 --max-connections 1000; then
  expect_line low 'event=fd_limit_low soft=64 soft_before=64 hard=64 need=1636 max_connections=1000 max_handshakes=512 contexts=1 connections_that_fit=0'
  expect_limits low 64 64
fi

# Cases 2 and 3 lower the hard limit to 4096 and 1024, which needs a hard limit at least that
# high to start from (only root may raise it).
hard_now=$(ulimit -Hn)
[[ $hard_now == unlimited ]] && hard_now=1048576
skipped=0

# 2. Soft 64 below a hard 4096: raised to 4096, which is enough (no warning).
if ((hard_now < 4096)); then
  echo "SKIP: raised: the hard limit here is $hard_now, below 4096"
  skipped=1
elif run raised 64 4096 --max-connections 1000; then
  expect_line raised 'event=fd_limit soft=4096 soft_before=64 hard=4096 need=1636 '
  expect_limits raised 4096 4096
  [[ $(grep -c "fd_limit_low" "$dir/raised.log") -eq 0 ]] || fail "raised: warned with enough descriptors"
fi

# 3. Soft 64 below a hard 1024: raised, still short: the warning says how many players fit
#    (1024 - 636 = 388).
if ((hard_now < 1024)); then
  echo "SKIP: short: the hard limit here is $hard_now, below 1024"
  skipped=1
elif run short 64 1024 --max-connections 1000; then
  expect_line short 'event=fd_limit_low soft=1024 soft_before=64 hard=1024 need=1636 max_connections=1000 max_handshakes=512 contexts=1 connections_that_fit=388'
  expect_limits short 1024 1024
fi

if [[ $failures -ne 0 ]]; then
  echo "$failures failure(s)"
  exit 1
fi
if [[ $skipped -ne 0 ]]; then
  exit 77
fi
echo "PASS: the soft limit is raised to the hard one, and a short limit is one warning with the numbers"
