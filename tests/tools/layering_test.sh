#!/usr/bin/env bash
# The pipeline has no arrow back up: a folder includes only from its own stage or an earlier one.
# Reads every `#include "..."` under the source folders, resolves it from the one include root (the
# repository root; generated headers resolve to none and are skipped) and fails naming the file
# and the include when it points at a later stage, or at another folder of the same stage
# (siblings stay independent). An include that names a path relative to its own folder instead of
# from the root fails too: one root, so a path reads the same in every file.
#
# Also: the sans-I/O cores (the protocol's, server/conversation.* and
# client/stream/conversation.*, the generator's policy, server/schedule.*, and admission past
# capacity, server/admission.*, where present)
# include no boost/, beast, asio or CL/ header, directly or through the project headers they
# include (followed transitively).
#
# Usage: layering_test.sh <repository root>
set -u
root=${1:?usage: layering_test.sh <repository root>}
cd "$root" || exit 2

# Stages in pipeline order (earlier first). Folders on one line are one stage. shaders/ holds the
# GLSL programs and includes nothing, so every stage may include it (common/relief and
# common/formations compile the relief's and the formations' GLSL as C++). Everything the world
# digest covers lives under common/; the programs and their libraries come after it.
stages=(
  "common/core"
  "shaders"
  "common/png"
  "common/cave"
  "common/mesh"
  "common/kernels"
  "common/codec"
  "common/relief"
  "common/formations"
  "proto"
  "server"
  "client/stream"
  "client/play client/render"
  "client/app client/load client/engine"
  "tools bench tests"
)

# The folder of a path, as named in `stages`, or nothing when the path is in none.
folder_of() {
  local path=$1 line f
  for line in "${stages[@]}"; do
    for f in $line; do
      if [[ $path == "$f"/* ]]; then
        echo "$f"
        return
      fi
    done
  done
}

# The stage number of a folder.
rank_of() {
  local i f
  for i in "${!stages[@]}"; do
    for f in ${stages[$i]}; do
      if [[ $f == "$1" ]]; then
        echo "$i"
        return
      fi
    done
  done
}

# The repository path an include names from the root, or nothing (system or generated headers).
resolve() {
  local name=$1
  [[ -f $name ]] && realpath -m --relative-to=. "$name"
}

# The repository path an include names relative to the including file's folder, or nothing.
resolve_relative() {
  local from_dir=$1 name=$2
  [[ -f $from_dir/$name ]] && realpath -m --relative-to=. "$from_dir/$name"
}

sources() {
  local f
  for f in $(printf '%s\n' "${stages[@]}" | tr ' ' '\n'); do
    [[ -d $f ]] || continue
    find "$f" -type f \( -name '*.c' -o -name '*.h' -o -name '*.cpp' -o -name '*.hpp' \
      -o -name '*.cl' -o -name '*.glsl' \) -not -path '*/seeds/*' -not -path '*/layering_fixture/*'
  done | sort
}

# The quoted includes of a file, one per line.
quoted_includes() {
  sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"\([^"]*\)".*/\1/p' "$1"
}

failures=0
checked=0
while IFS= read -r file; do
  from=$(folder_of "$file")
  [[ -n $from ]] || continue
  from_rank=$(rank_of "$from")
  while IFS= read -r name; do
    [[ -n $name ]] || continue
    target=$(resolve "$name")
    if [[ -z $target ]]; then
      if [[ -n $(resolve_relative "$(dirname "$file")" "$name") ]]; then
        echo "FAIL: $file includes \"$name\" relative to its folder: name it from the root"
        failures=$((failures + 1))
      fi
      continue
    fi
    to=$(folder_of "$target")
    [[ -n $to && $to != "$from" ]] || continue
    checked=$((checked + 1))
    to_rank=$(rank_of "$to")
    if ((to_rank > from_rank)); then
      echo "FAIL: $file includes \"$name\" ($to), a later stage than $from"
      failures=$((failures + 1))
    elif ((to_rank == from_rank)); then
      echo "FAIL: $file includes \"$name\" ($to), a sibling of $from in the same stage"
      failures=$((failures + 1))
    fi
  done < <(quoted_includes "$file")
done < <(sources)

# Every include a file makes, directly or through the project headers it includes, as
# "<name>" or "\"name\"", one per line (each project header visited once).
declare -A visited
all_includes() {
  local file=$1 line name target
  [[ -n ${visited[$file]:-} ]] && return
  visited[$file]=1
  while IFS= read -r line; do
    echo "$line  (in $file)"
    if [[ $line == \"*\" ]]; then
      name=${line#\"}
      name=${name%\"}
      target=$(resolve "$name")
      [[ -n $target ]] && all_includes "$target"
    fi
  done < <(sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*\([<"][^>"]*[>"]\).*/\1/p' "$file")
}

cores=0
for core in server/conversation.hpp server/conversation.cpp server/schedule.hpp \
  server/schedule.cpp server/admission.hpp server/admission.cpp client/stream/conversation.hpp client/stream/conversation.cpp; do
  [[ -f $core ]] || continue
  cores=$((cores + 1))
  visited=()
  while IFS= read -r hit; do
    echo "FAIL: $core reaches an I/O or OpenCL header: $hit"
    failures=$((failures + 1))
  done < <(all_includes "$core" | grep -Ei '^[<"](boost/|CL/)|beast|asio')
done

echo "checked $checked cross-folder includes and $cores sans-I/O core files: $failures failures"
if ((checked == 0 || cores == 0)); then
  echo "FAIL: nothing was checked (wrong repository root?)"
  exit 1
fi
((failures == 0))
