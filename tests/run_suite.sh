#!/usr/bin/env bash
# The whole test suite, then a check that it left nothing running.
#   bash tests/run_suite.sh BUILD_DIR [ctest arguments...]
# Runs ctest in BUILD_DIR with a marker in its environment (GROTTO_SUITE_RUN, a fresh random
# value) that every process a test starts inherits, unless it clears its environment: nginx does
# for its workers, so nginx processes whose command line names a path under BUILD_DIR or /tmp
# count too. After ctest, whatever still runs with the marker (or is such an nginx) after a grace
# of 5 s is listed, killed (its process group first), and fails the run. Exit: ctest's status,
# or 1 when it passed but left processes behind.
set -u
build=${1:?usage: run_suite.sh BUILD_DIR [ctest arguments...]}
shift
build=$(cd "$build" && pwd) || exit 2
marker="grotto-suite-$$-$RANDOM$RANDOM"

GROTTO_SUITE_RUN=$marker ctest --test-dir "$build" --output-on-failure -j 2 "$@"
status=$?

# The processes of this run still alive, other than this script and its own pipeline.
leftovers() {
  local pid cmd
  for dir in /proc/[0-9]*; do
    pid=${dir#/proc/}
    [[ $pid == "$$" || $pid == "$BASHPID" ]] && continue
    cmd=$({ tr '\0' ' ' <"$dir/cmdline"; } 2>/dev/null) || continue
    [[ -z $cmd ]] && continue  # a kernel thread or a zombie
    if grep -qz "^GROTTO_SUITE_RUN=$marker\$" "$dir/environ" 2>/dev/null; then
      echo "$pid $cmd"
    elif [[ $cmd == nginx:* || $cmd == *"/nginx "* || $cmd == "nginx "* ]] &&
         [[ $cmd == *"$build"* || $cmd == *" /tmp/"* || $cmd == *"-p /tmp/"* ]]; then
      echo "$pid $cmd"
    fi
  done
}

left=$(leftovers)
for _ in 1 2 3 4 5 6 7 8 9 10; do
  [[ -z $left ]] && break
  sleep 0.5
  left=$(leftovers)
done
if [[ -n $left ]]; then
  echo "run_suite: the tests left these processes running (stopped now):" >&2
  sed 's/^/  /' <<<"$left" >&2
  while read -r pid _; do
    kill -KILL -- "-$pid" 2>/dev/null
    kill -KILL "$pid" 2>/dev/null
  done <<<"$left"
  [[ $status -eq 0 ]] && status=1
else
  echo "run_suite: no process of the suite is left running"
fi
exit $status
