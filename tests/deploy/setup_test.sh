#!/usr/bin/env bash
# deploy/setup.sh as a newcomer meets it: quiet when nothing is missing, a clear message without
# apt, Draco's source downloaded when it is not there. Run by CTest after the set-up step has
# installed everything (so nothing is missing).
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
grep -qx dpkg-dev <<<"$list" || { echo "FAIL: --list lacks dpkg-dev (dpkg-source, tests/fuzz)"; fail=1; }

# Draco's source package (tests/fuzz builds it): downloaded into GROTTO_DRACO_SOURCE_DIR when
# missing, complete or not at all, and quiet once there. apt-cache, apt-get and sudo are stubs
# that log their calls (the real ones would write /etc/apt and need the network); dpkg-query is
# the real one, so the version is the installed libdraco-dev's.
version=$(dpkg-query -W -f='${source:Version}' libdraco-dev 2>/dev/null)
version=${version#*:}
tmp=$(mktemp -d) || exit 1
trap 'rm -rf "$tmp"' EXIT
mkdir "$tmp/bin" "$tmp/src" || exit 1
printf '%s\n' '#!/bin/bash' 'echo "apt-cache $*" >>"$STUB_DIR/calls"' \
  '[[ "$1" == showsrc ]] && printf "Package: draco\nVersion: %s\n" "$STUB_VERSION"' 'exit 0' \
  >"$tmp/bin/apt-cache"
printf '%s\n' '#!/bin/bash' 'echo "apt-get $*" >>"$STUB_DIR/calls"' \
  'if [[ " $* " == *" source "* ]]; then' \
  '  [[ -e "$STUB_DIR/fail_download" ]] && exit 100' \
  '  touch "draco_$STUB_VERSION.dsc" "draco_$STUB_VERSION.debian.tar.xz" draco.orig.tar.xz' \
  'fi' 'exit 0' >"$tmp/bin/apt-get"
printf '%s\n' '#!/bin/bash' '"$@"' >"$tmp/bin/sudo"
chmod +x "$tmp/bin/apt-cache" "$tmp/bin/apt-get" "$tmp/bin/sudo"
stubbed() {
  STUB_DIR="$tmp" STUB_VERSION="$version" GROTTO_DRACO_SOURCE_DIR="$tmp/src" \
    PATH="$tmp/bin:$PATH" bash "$script" 2>&1
}

touch "$tmp/fail_download"
out=$(stubbed); rc=$?
if [[ $rc -eq 0 || -e "$tmp/src/draco_$version" ]]; then
  echo "FAIL: a failed download must fail setup.sh and leave no source directory (rc=$rc): $out"
  fail=1
fi
rm -f "$tmp/fail_download" "$tmp/calls"
out=$(stubbed); rc=$?
if [[ $rc -ne 0 || "$out" != *"downloading Debian's source of draco"* ||
      ! -f "$tmp/src/draco_$version/draco_$version.dsc" || -e "$tmp/src/draco_$version.partial" ]] ||
   ! grep -qx "apt-get source -qq --download-only draco=$version" "$tmp/calls"; then
  echo "FAIL: without Draco's source, setup.sh must download version $version into" \
    "$tmp/src/draco_$version (rc=$rc): $out; calls: $(cat "$tmp/calls" 2>&1)"
  fail=1
fi
rm -f "$tmp/calls"
out=$(stubbed); rc=$?
if [[ $rc -ne 0 || -n "$out" || -e "$tmp/calls" ]]; then
  echo "FAIL: with Draco's source there, setup.sh must be quiet and call no apt (rc=$rc): $out"
  fail=1
fi

[[ $fail -eq 0 ]] &&
  echo "setup.sh: quiet when complete, lists its packages, clear without apt, downloads Draco's source"
exit $fail
