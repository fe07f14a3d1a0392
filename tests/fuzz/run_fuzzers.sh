#!/usr/bin/env bash
# Builds Grotto's libFuzzer targets with clang in a build directory of their own and runs each
# for a bounded time, seeded from tests/fuzz/seeds/<name>/. Fails on any crash, leak, sanitizer
# report, timeout or single allocation over 64 MB; exits 77 (CTest's skip) when clang or
# libFuzzer's runtime is missing.
#   tests/fuzz/run_fuzzers.sh [SOURCE_DIR] [BUILD_DIR]
# Environment: GROTTO_FUZZ_SECONDS per fuzzer (default 30), GROTTO_FUZZ_JOBS build jobs
# (default 2), GROTTO_FUZZERS a space-separated subset to run.
set -uo pipefail
src=$(cd "${1:-$(dirname "$0")/../..}" && pwd)
build=${2:-$src/build-fuzz}
seconds=${GROTTO_FUZZ_SECONDS:-30}
jobs=${GROTTO_FUZZ_JOBS:-2}

cxx=$(command -v clang++ || true)
if [[ -z "$cxx" ]]; then
  echo "fuzz: clang++ not found; skipping (deploy/setup.sh installs clang and libclang-rt-14-dev)"
  exit 77
fi
probe=$(mktemp -d)
trap 'rm -rf "$probe"' EXIT
echo 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }' \
  >"$probe/probe.cpp"
if ! "$cxx" -fsanitize=fuzzer "$probe/probe.cpp" -o "$probe/probe" 2>"$probe/err"; then
  echo "fuzz: $cxx cannot link libFuzzer (install libclang-rt-14-dev); skipping"
  sed 's/^/  /' "$probe/err" | head -5
  exit 77
fi

mkdir -p "$build"
if ! cmake -S "$src" -B "$build" -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
     -DGROTTO_FUZZ=ON -DGROTTO_BUILD_TESTS=OFF -DGROTTO_BUILD_BENCH=OFF >"$build/configure.log" 2>&1; then
  echo "fuzz: configuring the clang build failed:"; tail -20 "$build/configure.log"; exit 1
fi
mapfile -t fuzzers <"$build/fuzzers.txt"
[[ -n "${GROTTO_FUZZERS:-}" ]] && read -ra fuzzers <<<"$GROTTO_FUZZERS"
if ! cmake --build "$build" -j "$jobs" --target "${fuzzers[@]}" >"$build/build.log" 2>&1; then
  echo "fuzz: building ${fuzzers[*]} failed:"; grep -E "error|Error" "$build/build.log" | head -20
  exit 1
fi

fail=0
for name in "${fuzzers[@]}"; do
  corpus="$build/corpus/$name"
  artifacts="$build/artifacts/$name"
  mkdir -p "$corpus" "$artifacts"
  dirs=("$corpus")
  [[ -d "$src/tests/fuzz/seeds/$name" ]] && dirs+=("$src/tests/fuzz/seeds/$name")
  log="$build/$name.log"
  # -malloc_limit_mb: one allocation over 64 MB fails the run. Without it libFuzzer's limit is
  # rss_limit_mb (2 GB), which let a 255-component attribute claim 1.6 GB unseen; the room
  # decoder's largest single allocation at its default limits is ~1.1 MB (room_codec.hpp).
  "$build/bin/$name" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=64 \
    -print_final_stats=1 -artifact_prefix="$artifacts/" "${dirs[@]}" >"$log" 2>&1
  rc=$?
  runs=$(grep -m1 -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$')
  corpus_size=$(find "$corpus" -type f | wc -l)
  if [[ $rc -ne 0 ]]; then
    echo "FAIL: $name (exit $rc) after ${runs:-?} runs; reproducer in $artifacts/:"
    grep -E "ERROR|SUMMARY|proto_fuzz:|==[0-9]+==" "$log" | head -20
    fail=1
  else
    echo "fuzz: $name ran ${runs:-?} inputs in ${seconds}s, no crash (corpus $corpus_size files)"
  fi
done
exit $fail
