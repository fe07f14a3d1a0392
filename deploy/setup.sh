#!/usr/bin/env bash
# Installs the Debian 12 packages Grotto needs to build, test and run, and nothing else.
# Idempotent and quiet when nothing is missing; works as root or through sudo.
#   deploy/setup.sh           the build, run and test dependencies
#   deploy/setup.sh --list    print the package list and exit
#   deploy/setup.sh --help    this text
# It also installs the browser viewer's npm packages (three.js, Draco's decoder, playwright-core:
# web/package-lock.json pins them) into web/node_modules with `npm ci`, again only when they are
# missing or the lockfile changed.
# Besides packages it keeps Debian's source package of Draco (the version libdraco-dev has) in
# /var/cache/grotto/src (GROTTO_DRACO_SOURCE_DIR): tests/fuzz builds it with sanitizers, and
# downloading it here means the fuzz test needs no network. For that it adds a deb-src entry
# (/etc/apt/sources.list.d/grotto-deb-src.sources) where apt knows no source for that version.
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
  dpkg-dev  # dpkg-source: unpacks Draco's source package with Debian's patches (tests/fuzz)
  nginx  # tests/deploy: the load balancer in front of grotto-server replicas
  curl  # tests/deploy/cluster_test.sh: room URLs through the cache (headers, ETag, 304)
  python3-yaml systemd  # tests/deploy/manifests_test.sh: YAML checks, systemd-analyze verify
  gltfpack  # tests/tools: a second, independent reader of grotto-layout --glb files
  chromium  # web/e2e: the viewer in a real browser (headless, SwiftShader's WebGL2)
)
# kubectl (kustomize builds of deploy/k8s in tests/deploy): Debian's kubernetes-client, unless a
# kubectl is already installed (another package owning /usr/bin/kubectl would clash with it).
command -v kubectl >/dev/null 2>&1 || packages+=(kubernetes-client)
# Node.js and npm (the browser viewer, web/: bundled at build time, its unit tests under node
# --test): Debian's, unless a node and an npm are already installed (NodeSource's nodejs package
# carries npm and conflicts with Debian's).
# --list names them always: they are what a fresh Debian machine gets.
if [[ "${1:-}" == --list ]] || ! command -v node >/dev/null 2>&1; then packages+=(nodejs); fi
if [[ "${1:-}" == --list ]] || ! command -v npm >/dev/null 2>&1; then packages+=(npm); fi

case "${1:-}" in
  "") ;;
  --list) printf '%s\n' "${packages[@]}"; exit 0 ;;
  -h | --help) sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; exit 0 ;;
  *) echo "setup: unknown argument '$1' (--help)" >&2; exit 2 ;;
esac

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

# Draco's source: one directory per version, named as tests/fuzz/run_fuzzers.sh looks for it. It
# is only there once complete (downloaded beside it, then renamed). Without libdraco-dev yet the
# version is unknown, so it is checked again after installing.
draco_cache=${GROTTO_DRACO_SOURCE_DIR:-/var/cache/grotto/src}
draco_source_missing() {
  local version
  version=$(dpkg-query -W -f='${source:Version}' libdraco-dev 2>/dev/null) || return 0
  [[ ! -d "$draco_cache/draco_${version#*:}" ]]
}

# The viewer's npm packages: installed for the lockfile that a stamp in node_modules names.
web=$(cd "$(dirname "$0")/../web" && pwd)
npm_stamp() { sha256sum <"$web/package-lock.json" | cut -d' ' -f1; }
npm_missing() { [[ "$(cat "$web/node_modules/.grotto-lock" 2>/dev/null)" != "$(npm_stamp)" ]]; }

[[ ${#missing[@]} -eq 0 ]] && ! draco_source_missing && ! npm_missing && exit 0

if [[ $(id -u) -eq 0 ]]; then
  sudo=()
elif command -v sudo >/dev/null 2>&1; then
  sudo=(sudo)
else
  draco_source_missing && missing+=("(Draco's source in $draco_cache)")
  echo "setup: missing and neither root nor sudo: ${missing[*]}" >&2
  exit 1
fi

export DEBIAN_FRONTEND=noninteractive
if [[ ${#missing[@]} -gt 0 ]]; then
  echo "setup: installing ${missing[*]}"
  "${sudo[@]}" apt-get update -qq
  "${sudo[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

if draco_source_missing; then
  version=$(dpkg-query -W -f='${source:Version}' libdraco-dev)
  echo "setup: downloading Debian's source of draco $version to $draco_cache"
  # A deb-src entry of our own only where apt knows no source for this version of draco: a
  # machine whose deb-src lines have it already keeps its own.
  if ! apt-cache showsrc draco 2>/dev/null | grep -qx "Version: $version"; then
    codename=$(. /etc/os-release && echo "${VERSION_CODENAME:-bookworm}")
    list=/etc/apt/sources.list.d/grotto-deb-src.sources
    # Same archive and key as Debian's own entries; the security suite because libdraco-dev may
    # come from a security update, and apt-get source fetches the version asked for only.
    printf '%s\n' "# deploy/setup.sh (Grotto): Draco's source package for tests/fuzz" \
      "Types: deb-src" "URIs: http://deb.debian.org/debian" \
      "Suites: $codename $codename-updates" "Components: main" \
      "Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg" "" \
      "Types: deb-src" "URIs: http://deb.debian.org/debian-security" \
      "Suites: $codename-security" "Components: main" \
      "Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg" |
      "${sudo[@]}" tee "$list" >/dev/null
    "${sudo[@]}" apt-get update -qq
  fi
  target="$draco_cache/draco_${version#*:}"
  "${sudo[@]}" rm -rf "$target.partial"
  "${sudo[@]}" mkdir -p "$target.partial"
  # apt-get source checks what it downloads against the signed Sources index. As root it
  # downloads as _apt, who may not write a root-owned directory: chown it for the download.
  "${sudo[@]}" chown _apt "$target.partial" 2>/dev/null || true
  (cd "$target.partial" && "${sudo[@]}" apt-get source -qq --download-only "draco=$version" >/dev/null)
  "${sudo[@]}" chown -R --reference="$draco_cache" "$target.partial"
  "${sudo[@]}" chmod -R a+rX "$draco_cache"
  "${sudo[@]}" mv "$target.partial" "$target"
fi
if npm_missing; then
  echo "setup: installing the viewer's npm packages (web/package-lock.json) into $web/node_modules"
  (cd "$web" && npm ci --no-audit --no-fund --loglevel=error >/dev/null)
  npm_stamp >"$web/node_modules/.grotto-lock"
fi
echo "setup: done"
