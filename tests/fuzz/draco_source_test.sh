#!/usr/bin/env bash
# run_fuzzers.sh where Draco's Debian source is missing: it must fail at once with one line that
# says how to fix it, not skip (the fuzz test would pass in CI without fuzzing Draco) and not go
# on to build against the system's uninstrumented libdraco.
set -u
src=$(cd "$(dirname "$0")/../.." && pwd)
tmp=$(mktemp -d) || exit 1
trap 'rm -rf "$tmp"' EXIT

out=$(GROTTO_DRACO_SOURCE_DIR="$tmp/none" GROTTO_FUZZERS= bash "$src/tests/fuzz/run_fuzzers.sh" \
  "$src" "$tmp/build" 2>&1)
rc=$?
# No clang or libFuzzer: run_fuzzers.sh skips before it looks for Draco. A skip that names Draco
# is no such skip, and fails below.
if [[ $rc -eq 77 && "$out" != *Draco* ]]; then
  echo "$out"
  exit 77
fi
if [[ $rc -ne 1 || $(wc -l <<<"$out") -ne 1 || "$out" != *"Draco's Debian source"* ||
      "$out" != *"deploy/setup.sh"* || -e "$tmp/build/CMakeCache.txt" ]]; then
  echo "FAIL: without Draco's source run_fuzzers.sh must fail before configuring, in one line" \
    "naming deploy/setup.sh (rc=$rc): $out"
  exit 1
fi
echo "run_fuzzers.sh without Draco's source: $out"
