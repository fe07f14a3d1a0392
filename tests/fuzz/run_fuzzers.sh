#!/usr/bin/env bash
# Builds Grotto's libFuzzer targets with clang in a build directory of their own and runs each
# for a bounded time, seeded from tests/fuzz/seeds/<name>/. Fails on any crash, leak, sanitizer
# report, timeout or single allocation over 64 MB; exits 77 (CTest's skip) when clang or
# libFuzzer's runtime is missing.
# Draco is fuzzed with the room decoder, not beside it: the script builds Debian's source package
# of Draco (the version libdraco-dev has, Debian's patches applied; deploy/setup.sh downloads it)
# with the same sanitizers and coverage as Grotto, once per build directory, and links that into
# room_decoder_fuzz instead of the system's libdraco; it fails if the fuzzer ends up with the
# system's uninstrumented Draco after all.
#   tests/fuzz/run_fuzzers.sh [SOURCE_DIR] [BUILD_DIR]
# Environment: GROTTO_FUZZ_SECONDS per fuzzer (default 30), GROTTO_FUZZ_JOBS build jobs
# (default 2), GROTTO_FUZZERS a space-separated subset to run, GROTTO_DRACO_SOURCE_DIR where
# Draco's source packages are (default /var/cache/grotto/src, where setup.sh puts them).
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
build=$(cd "$build" && pwd)  # draco_DIR below must not depend on where cmake runs

# Instrumented Draco. Only room_decoder_fuzz links Draco, so a run of other fuzzers alone
# (GROTTO_FUZZERS) neither needs nor builds it.
draco_args=()
if [[ -z "${GROTTO_FUZZERS:-}" || " $GROTTO_FUZZERS " == *" room_decoder_fuzz "* ]]; then
  version=$(dpkg-query -W -f='${source:Version}' libdraco-dev 2>/dev/null || true)
  if [[ -z "$version" ]]; then
    echo "fuzz: libdraco-dev is not installed, so which Draco to build is unknown; run deploy/setup.sh"
    exit 1
  fi
  version=${version#*:}  # file names carry no epoch
  dsc="${GROTTO_DRACO_SOURCE_DIR:-/var/cache/grotto/src}/draco_$version/draco_$version.dsc"
  if [[ ! -f "$dsc" ]]; then
    echo "fuzz: Draco's Debian source ($dsc) is missing; run deploy/setup.sh, which adds a deb-src entry and downloads it"
    exit 1
  fi
  # What Debian's build does (debian/rules: dh's CMAKE_BUILD_TYPE=None, so -O2 and assert() on,
  # Draco's default codec options) but static, with the sanitizers and coverage of Grotto's fuzz
  # build, and without the glTF transcoder (file formats and scenes, nothing that decodes a
  # Draco bitstream; it would need Eigen, stb and tinygltf installed). -gline-tables-only:
  # file:line in reports without full debug information.
  # -fno-sanitize=enum: Draco 1.5.5 loads an unchecked prediction-method byte as an enum; the
  # decoder checks the byte that opens each attribute decoder's data, but the others are reachable
  # only through Draco (common/codec/room_codec.cpp, LayoutCheckingDecoder), and an out-of-range
  # value there fails the decode in Draco's switch. Every other UBSan check stays on.
  draco_flags="-O2 -gline-tables-only -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize=enum"
  draco_flags+=" -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
  draco="$build/draco"
  draco_cmake=(-DCMAKE_BUILD_TYPE=None -DCMAKE_C_COMPILER="$(dirname "$cxx")/clang"
    -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_C_FLAGS="$draco_flags" -DCMAKE_CXX_FLAGS="$draco_flags"
    -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" -DBUILD_SHARED_LIBS=OFF
    -DDRACO_TESTS=OFF -DDRACO_TRANSCODER_SUPPORTED=OFF
    -DCMAKE_INSTALL_PREFIX="$draco/install" -DCMAKE_INSTALL_LIBDIR=lib)
  # The build is kept while the source version, the compiler and these options stay the same.
  draco_key="draco $version; $("$cxx" --version | head -1); ${draco_cmake[*]}"
  if [[ "$(cat "$draco/stamp" 2>/dev/null)" != "$draco_key" ]]; then
    echo "fuzz: building Draco $version from Debian's source with sanitizers (once per build directory)"
    start=$SECONDS
    rm -rf "$draco"
    mkdir -p "$draco"
    # Draco installs its decoder and encoder programs too, so they are built (~20% of the time);
    # the install tree is what find_package(draco) reads. The sources stay (reports name their
    # lines); the objects (~100 MB) do not.
    if ! { dpkg-source --no-copy -x "$dsc" "$draco/src" &&
           cmake -S "$draco/src" -B "$draco/build" "${draco_cmake[@]}" &&
           cmake --build "$draco/build" -j "$jobs" &&
           cmake --install "$draco/build"; } >"$draco/build.log" 2>&1; then
      echo "fuzz: building Draco from $dsc failed:"; tail -20 "$draco/build.log"; exit 1
    fi
    rm -rf "$draco/build"
    echo "$draco_key" >"$draco/stamp"
    echo "fuzz: built Draco in $((SECONDS - start)) s"
  fi
  draco_args=(-Ddraco_DIR="$draco/install/lib/cmake/draco")
fi

if ! cmake -S "$src" -B "$build" -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
     -DGROTTO_FUZZ=ON -DGROTTO_BUILD_TESTS=OFF -DGROTTO_BUILD_BENCH=OFF "${draco_args[@]}" \
     >"$build/configure.log" 2>&1; then
  echo "fuzz: configuring the clang build failed:"; tail -20 "$build/configure.log"; exit 1
fi
mapfile -t fuzzers <"$build/fuzzers.txt"
[[ -n "${GROTTO_FUZZERS:-}" ]] && read -ra fuzzers <<<"$GROTTO_FUZZERS"
if ! cmake --build "$build" -j "$jobs" --target "${fuzzers[@]}" >"$build/build.log" 2>&1; then
  echo "fuzz: building ${fuzzers[*]} failed:"; grep -E "error|Error" "$build/build.log" | head -20
  exit 1
fi

# The guard against fuzzing Draco blind: Draco's header parser, which every input reaches, must
# be inside room_decoder_fuzz and carry ASan's checks and libFuzzer's comparison hooks. With the
# system's libdraco it is either not in the binary (libdraco.so) or has neither (libdraco.a).
if [[ " ${fuzzers[*]} " == *" room_decoder_fuzz "* ]]; then
  bin="$build/bin/room_decoder_fuzz"
  fn=$(nm "$bin" | awk '$2 == "T" && $3 ~ /^_ZN5draco17PointCloudDecoder12DecodeHeader/ { print $3; exit }')
  code=$([[ -n "$fn" ]] && objdump -d --no-show-raw-insn --disassemble="$fn" "$bin")
  if ! grep -q 'call.*<__asan_report_' <<<"$code" || ! grep -q 'call.*<__sanitizer_cov_trace_' <<<"$code"; then
    what="is not in it"
    [[ -n "$fn" ]] && what="has no ASan checks or coverage hooks"
    echo "FAIL: room_decoder_fuzz does not link the instrumented Draco (draco::PointCloudDecoder::DecodeHeader" \
      "$what; libdraco in ldd: $(ldd "$bin" | awk '/libdraco/ { print $1 }' | grep . || echo none))"
    exit 1
  fi
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
