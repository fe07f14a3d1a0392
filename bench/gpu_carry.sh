#!/usr/bin/env bash
# Packs what a bare GPU machine (no Debian packages: a driver, and nothing of ours) needs to run
# bench/gpu.sh, capacity rows and the client: stripped Release binaries from BUILD_DIR/bin and the
# shared libraries they link (ldd's list, less the C runtime, which the machine has newer, and
# the GL libraries, which come from the machine's driver), plus glvnd's EGL dispatcher (the
# machine has the driver's vendor library but not the dispatcher), into DEST
# (default .gpu, which .git/info/exclude should ignore so that it travels only when carried).
# On that machine:
#   mkdir -p /etc/OpenCL/vendors && echo libnvidia-opencl.so.1 >/etc/OpenCL/vendors/nvidia.icd
#   export LD_LIBRARY_PATH=$PWD/.gpu/lib
#   bash bench/gpu.sh --build-dir .gpu --no-build --devices gpu --step-timeout 120
# (name the GPU: a machine's own PoCL may abort with several threads; OPERATING's platform table).
#
#   bash bench/gpu_carry.sh [BUILD_DIR] [DEST]
# Exit: 0 when packed, 1 when a binary is missing, 2 on a bad argument.
set -u
cd "$(dirname "$0")/.."
[[ "${1:-}" == -h || "${1:-}" == --help ]] && { sed -n '2,/^set -u/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; exit 0; }
(($# <= 2)) || { echo "gpu_carry.sh: at most two arguments (--help)" >&2; exit 2; }
for a in "$@"; do
  [[ "$a" != -* ]] || { echo "gpu_carry.sh: unknown flag '$a' (--help)" >&2; exit 2; }
done
build=${1:-build} dest=${2:-.gpu}
bins=(mesh_bench server_bench grotto-client grotto-server grotto-load kernels_tests)
for b in "${bins[@]}"; do
  [[ -x "$build/bin/$b" ]] || { echo "gpu_carry.sh: $build/bin/$b is missing (build Release first)" >&2; exit 1; }
done
mkdir -p "$dest/bin" "$dest/lib" || exit 1
for b in "${bins[@]}"; do
  strip -o "$dest/bin/$b" "$build/bin/$b" || exit 1
done
skip='^(libc|libm|libdl|libpthread|librt|libgcc_s|libstdc\+\+|ld-linux.*|libGL.*|libEGL|libGLX.*|libGLdispatch|libOpenGL)\.so'
while read -r name path; do
  [[ "$name" =~ $skip ]] && continue
  cp -L "$path" "$dest/lib/$name" || exit 1
done < <(for b in "${bins[@]}"; do ldd "$build/bin/$b"; done | awk '/=> \// { print $1, $3 }' | sort -u)
# glvnd's EGL dispatcher, which libepoxy loads at run time (so ldd does not list it): the lent
# NVIDIA machine has the driver's vendor library (libEGL_nvidia.so.0 and its glvnd JSON) but not
# the dispatcher, and grotto-client's EGL path fails without it (2026-11-27).
for lib in libEGL.so.1 libGLdispatch.so.0 libOpenGL.so.0; do
  for dir in /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib; do
    if [[ -e "$dir/$lib" ]]; then
      cp -L "$dir/$lib" "$dest/lib/$lib" || exit 1
      break
    fi
  done
done
echo "gpu_carry.sh: $(du -sh "$dest" | cut -f1) in $dest ($(ls "$dest/lib" | wc -l) libraries)"
