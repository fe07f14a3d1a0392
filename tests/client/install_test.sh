#!/usr/bin/env bash
# Grotto::stream as a game uses it: install the built library into a scratch prefix
# (cmake --install --component grotto_stream: nothing is rebuilt), check what was installed (the
# package files, headers that include only the standard library, a library that exports only its
# public functions), then build examples/minimal_stream (C++) and examples/minimal_stream_c (C) as
# separate projects with find_package(Grotto) against that prefix, and run each for a few seconds
# against a real grotto-server on 127.0.0.1 (an ephemeral port, the CPU reference): each must
# print the ground around the spawn ready and rooms as they arrive, and walk into other rooms;
# the C example's walk must bring rooms that standing at the spawn point never fetches. The server
# takes one player (--max-players 1), and the C example starts while the C++ one plays: it must
# wait in the admission queue, say where it stands, and play once the C++ one has left.
#
# Usage: install_test.sh <build dir> <source dir> <grotto-server binary>
set -u
build=${1:?usage: install_test.sh <build dir> <source dir> <grotto-server>}
src=${2:?}
server_bin=${3:?}
cmake=${CMAKE:-cmake}  # ctest passes the cmake that configured the build
work=$(mktemp -d "${TMPDIR:-/tmp}/grotto-install.XXXXXX")
server_pid=""
first_pid=""
cleanup() {
  local rc=$?
  # timeout(1) passes TERM on to the example it runs.
  [[ -n $first_pid ]] && kill -TERM "$first_pid" 2>/dev/null && wait "$first_pid" 2>/dev/null
  [[ -n $server_pid ]] && kill -KILL "$server_pid" 2>/dev/null && wait "$server_pid" 2>/dev/null
  if [[ $rc -ne 0 ]]; then
    for f in "$work"/*.log; do
      [[ -f $f ]] && { echo "== $f (last lines)"; tail -n 20 "$f"; }
    done
  fi
  rm -rf "$work"
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM
fail() {
  echo "FAIL: $*"
  exit 1
}
step() { echo "[$SECONDS s] $*"; }

prefix=$work/prefix
step "install into $prefix"
"$cmake" --install "$build" --prefix "$prefix" --component grotto_stream >"$work/install.log" 2>&1 ||
  fail "cmake --install failed"

# What a game gets: two headers, the library, the CMake package. Nothing else.
for f in include/grotto/stream.hpp include/grotto/grotto_stream.h; do
  [[ -f $prefix/$f ]] || fail "$f was not installed"
done
config=$(find "$prefix" -name GrottoConfig.cmake)
[[ -n $config ]] || fail "GrottoConfig.cmake was not installed"
[[ -f $(dirname "$config")/GrottoConfigVersion.cmake ]] || fail "no GrottoConfigVersion.cmake"
lib=$(find "$prefix" -name 'libgrotto_stream.so.*' -type f | head -n 1)
[[ -n $lib ]] || fail "libgrotto_stream.so was not installed"
others=$(find "$prefix" -type f | grep -v -e /include/grotto/ -e /cmake/Grotto/ -e libgrotto_stream)
[[ -z $others ]] || fail "installed more than the stream library: $others"

# The public headers reach no Boost, Beast, Asio, OpenCL, Draco, spdlog or nlohmann header: they
# include standard headers only (<...> without a slash or dot, or C's <std*.h>).
for h in "$prefix"/include/grotto/*; do
  while read -r inc; do
    [[ $inc =~ ^\<[a-z_]+\>$ || $inc =~ ^\<std[a-z]+\.h\>$ ]] ||
      fail "$(basename "$h") includes $inc (public headers include the standard library only)"
  done < <(sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*\([<"][^>"]*[>"]\).*/\1/p' "$h")
done

# The library exports the two headers' functions and nothing of what it is built from: no Boost,
# Draco, spdlog, fmt or nlohmann symbol, and none of Grotto's internal namespaces.
nm -D --defined-only -C "$lib" >"$work/symbols.log" || fail "nm -D $lib"
leaked=$(grep -E ' (boost::|draco::|spdlog::|fmt::|nlohmann::|grotto::(client|cave|mesh|codec|proto|server)::)' \
  "$work/symbols.log" | head -n 5)
[[ -z $leaked ]] || fail "the library exports internal symbols, e.g.: $leaked"
grep -q ' grotto_stream_create$' "$work/symbols.log" || fail "grotto_stream_create is not exported"
grep -q ' grotto::Stream::start(' "$work/symbols.log" || fail "grotto::Stream::start is not exported"

# Each example as a separate project: find_package(Grotto) from the prefix, no ccache, no flags
# from this build.
for ex in minimal_stream minimal_stream_c; do
  step "build examples/$ex against the installed tree"
  "$cmake" -G "Unix Makefiles" -S "$src/examples/$ex" -B "$work/$ex" -DCMAKE_PREFIX_PATH="$prefix" \
    -DCMAKE_BUILD_TYPE=Release >"$work/$ex-configure.log" 2>&1 || fail "configuring $ex"
  "$cmake" --build "$work/$ex" >"$work/$ex-build.log" 2>&1 || fail "building $ex"
  [[ -x $work/$ex/$ex ]] || fail "$ex was not built"
  # The game's link line names the one library: its dependencies stay private.
  link=$work/$ex/CMakeFiles/$ex.dir/link.txt
  grep -q libgrotto_stream "$link" || fail "$ex: no libgrotto_stream in its link line ($link)"
  linked=$(grep -oE '(lib|-l)(boost|draco|spdlog|fmt|OpenCL|nlohmann|pthread)' "$link" | sort -u | tr '\n' ' ')
  [[ -z $linked ]] || fail "$ex links more than Grotto::stream: $linked"
done

step "start grotto-server (one player at a time)"
: >"$work/server.out"
"$server_bin" --bind 127.0.0.1 --port 0 --opencl-device none --workers 2 --log-level warn \
  --max-players 1 >"$work/server.out" 2>"$work/server.log" &
server_pid=$!
for _ in $(seq 1 300); do
  grep -q "listening on" "$work/server.out" && break
  kill -0 "$server_pid" 2>/dev/null || fail "grotto-server exited"
  sleep 0.1
done
port=$(sed -n 's|.*listening on http://127\.0\.0\.1:\([0-9]*\).*|\1|p' "$work/server.out")
[[ -n $port ]] || fail "grotto-server printed no port: $(head -c 200 "$work/server.out")"
url="ws://127.0.0.1:$port/ws"

# Both examples walk from the spawn point at 4 m/s: 6 s (C++) and 8 s (C) leave them time to
# pass a few portals even on a loaded machine. The C++ one is the server's one player; the C one
# starts once it is in (its spawn line printed: stdbuf makes the examples' stdout line-buffered)
# and waits in the queue until it leaves.
step "run minimal_stream $url 6"
timeout 60 stdbuf -oL "$work/minimal_stream/minimal_stream" "$url" 6 \
  >"$work/minimal_stream-run.log" 2>&1 &
first_pid=$!
for _ in $(seq 1 300); do
  grep -q "ground within 8 m" "$work/minimal_stream-run.log" && break
  kill -0 "$first_pid" 2>/dev/null || break
  sleep 0.1
done
grep -q "ground within 8 m" "$work/minimal_stream-run.log" || fail "minimal_stream never got in"
step "run minimal_stream_c $url 8 (queued behind minimal_stream)"
timeout 90 stdbuf -oL "$work/minimal_stream_c/minimal_stream_c" "$url" 8 \
  >"$work/minimal_stream_c-run.log" 2>&1
c_rc=$?
wait "$first_pid"
first_rc=$?
first_pid=""
((first_rc == 0)) || fail "minimal_stream exited $first_rc"
((c_rc == 0)) || fail "minimal_stream_c exited $c_rc"
grep -q "^waiting to enter: 1st of 1, about [0-9]* s$" "$work/minimal_stream_c-run.log" ||
  fail "minimal_stream_c: no 'waiting to enter: 1st of 1' while the server was full"
for ex in minimal_stream minimal_stream_c; do
  grep -q "ground within 8 m: ready" "$work/$ex-run.log" || fail "$ex: the ground never got ready"
  rooms=$(grep -c '^room ' "$work/$ex-run.log")
  ((rooms >= 3)) || fail "$ex printed $rooms rooms (at least 3 expected)"
  echo "  $ex: $rooms rooms, $(grep -c '^entered ' "$work/$ex-run.log") rooms entered"
  grep -q '^entered ' "$work/$ex-run.log" || fail "$ex never left its room"
done
# The C example's walk made the stream fetch what standing at the spawn point never would: a room
# more than 16 m from it (the prefetch horizon, 4 s at 4 m/s; every path to such a room is longer).
farthest=$(sed -n 's/^room .*, \([0-9.]*\) m from the spawn$/\1/p' "$work/minimal_stream_c-run.log" |
  sort -g | tail -n 1)
echo "  minimal_stream_c: farthest room ${farthest:-none} m from the spawn"
awk -v d="${farthest:-0}" 'BEGIN { exit !(d > 16) }' ||
  fail "minimal_stream_c: no room beyond 16 m of the spawn arrived (farthest: ${farthest:-none} m)"
step "pass"
