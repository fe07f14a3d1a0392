#!/usr/bin/env bash
# The image without a container engine (deploy/image/rootfs.sh): grotto-server in a Debian 12
# root with the Dockerfile's runtime packages, user, environment and entrypoint, read-only root,
# in its own namespaces; its HEALTHCHECK passes, /readyz, /metrics and /version answer 200, and
# SIGTERM stops it with exit 0. Opt-in, because making the root downloads Debian 12 and takes
# minutes: set GROTTO_IMAGE_ROOT to a directory (made on first use, reused after).
#   image_test.sh GROTTO_SERVER_BINARY
# Exit 0: pass; 1: failure; 77: skipped (not opted in, or not root, or a tool missing).
set -u
server=${1:?usage: image_test.sh GROTTO_SERVER_BINARY}
script="$(dirname "$0")/rootfs.sh"
skip() {
  echo "SKIP: $*"
  exit 77
}
[[ -n "${GROTTO_IMAGE_ROOT:-}" ]] ||
  skip "opt-in: set GROTTO_IMAGE_ROOT=DIR (deploy/image/rootfs.sh debootstraps Debian 12 there" \
    "from deb.debian.org on first use: ~800 MB installed, a few minutes)"
[[ $(id -u) -eq 0 ]] || skip "needs root (chroot, mounts, namespaces)"
for tool in unshare chroot ip; do
  command -v "$tool" >/dev/null || skip "$tool is missing"
done
if [[ ! -x "$GROTTO_IMAGE_ROOT/usr/bin/apt-get" ]] && ! command -v debootstrap >/dev/null; then
  skip "debootstrap is missing (apt-get install debootstrap) and $GROTTO_IMAGE_ROOT holds no root"
fi
bash "$script" build "$GROTTO_IMAGE_ROOT" "$server" || exit 1
bash "$script" smoke "$GROTTO_IMAGE_ROOT"
