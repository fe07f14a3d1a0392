#!/usr/bin/env bash
# Installs the Debian 12 packages Grotto needs to build, test and run, and nothing else.
# Idempotent and quiet when nothing is missing; works as root or through sudo.
#   deploy/setup.sh           the build, run and test dependencies
#   deploy/setup.sh --list    print the package list and exit
set -euo pipefail

packages=(
  cmake g++ make pkg-config
  libboost-dev libdraco-dev libglfw3-dev libglm-dev nlohmann-json3-dev
  pocl-opencl-icd ocl-icd-opencl-dev opencl-headers opencl-clhpp-headers
  libepoxy-dev libgtest-dev libgmock-dev libbenchmark-dev libspdlog-dev libcli11-dev
  libmeshoptimizer-dev
  zlib1g-dev  # PNG compression (screenshots, layout previews)
  xvfb xauth libgl1-mesa-dri  # grotto-client tests: Mesa llvmpipe under Xvfb (xvfb-run needs xauth)
  libegl-dev libegl-mesa0  # grotto-client --screenshot/--bench without X: EGL headers, Mesa's EGL
  clang libclang-rt-14-dev  # libFuzzer (tests/fuzz); its runtime is in libclang-rt-14-dev
  nginx  # tests/deploy: the load balancer in front of grotto-server replicas
  python3-yaml systemd  # tests/deploy/manifests_test.sh: YAML checks, systemd-analyze verify
)
# kubectl (kustomize builds of deploy/k8s in tests/deploy): Debian's kubernetes-client, unless a
# kubectl is already installed (another package owning /usr/bin/kubectl would clash with it).
command -v kubectl >/dev/null 2>&1 || packages+=(kubernetes-client)

if [[ "${1:-}" == "--list" ]]; then
  printf '%s\n' "${packages[@]}"
  exit 0
fi

if ! command -v dpkg-query >/dev/null 2>&1 || ! command -v apt-get >/dev/null 2>&1; then
  echo "setup: this script needs Debian's dpkg and apt-get (Debian 12 'bookworm')." >&2
  echo "setup: install these packages with your system's package manager instead:" >&2
  printf '  %s\n' "${packages[@]}" >&2
  exit 1
fi

missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done
[[ ${#missing[@]} -eq 0 ]] && exit 0

if [[ $(id -u) -eq 0 ]]; then
  sudo=()
elif command -v sudo >/dev/null 2>&1; then
  sudo=(sudo)
else
  echo "setup: missing packages and neither root nor sudo: ${missing[*]}" >&2
  exit 1
fi

echo "setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update -qq
"${sudo[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "setup: done"
