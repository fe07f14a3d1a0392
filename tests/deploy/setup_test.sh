#!/usr/bin/env bash
# deploy/setup.sh as a newcomer meets it: quiet when nothing is missing, a clear message without
# apt. Run by CTest after the set-up step has installed everything (so nothing is missing).
set -u
script="$(dirname "$0")/../../deploy/setup.sh"
fail=0

out=$(bash "$script" 2>&1); rc=$?
if [[ $rc -ne 0 || -n "$out" ]]; then
  echo "FAIL: with every package present, setup.sh must exit 0 and print nothing (rc=$rc): $out"
  fail=1
fi

list=$(bash "$script" --list)
for p in cmake libdraco-dev pocl-opencl-icd libgtest-dev; do
  grep -qx "$p" <<<"$list" || { echo "FAIL: --list lacks $p"; fail=1; }
done

# Without dpkg and apt-get on PATH (bash itself is called by its full path).
out=$(PATH=/nonexistent /bin/bash "$script" 2>&1); rc=$?
if [[ $rc -eq 0 || "$out" != *"needs Debian's dpkg and apt-get"* ]]; then
  echo "FAIL: without apt, setup.sh must fail with a clear message (rc=$rc): $out"
  fail=1
fi
[[ $fail -eq 0 ]] && echo "setup.sh: quiet when complete, lists its packages, clear without apt"
exit $fail
