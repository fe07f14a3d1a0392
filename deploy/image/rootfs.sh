#!/usr/bin/env bash
# The container image without a container engine: a Debian 12 root with the runtime stage's
# packages (read from deploy/Dockerfile, so the two cannot drift), grotto-server copied in, and
# the same user, cache directories, environment and entrypoint, run under chroot in fresh mount,
# PID and network namespaces with the root file system read-only (as Kubernetes'
# readOnlyRootFilesystem would have it). Opt-in: it downloads Debian's packages (the root is
# ~800 MB, PoCL's LLVM and clang most of it) and takes minutes, so CI does not run it; deploy/image/image_test.sh does once GROTTO_IMAGE_ROOT
# names a root built here.
#   deploy/image/rootfs.sh build ROOT SERVER_BINARY [MIRROR]   debootstrap ROOT (as root)
#   deploy/image/rootfs.sh smoke ROOT                        start it, wait for the image's
#                                                             HEALTHCHECK, GET /readyz, /metrics
#                                                             and /version, SIGTERM it: exit 0
#   deploy/image/rootfs.sh run ROOT [FLAGS...]                run it in the foreground (ports in
#                                                             its own network namespace)
# Needs root (debootstrap, chroot, mount), debootstrap, unshare and ip (iproute2).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
dockerfile="$here/../Dockerfile"
uid=10001
cache=/var/cache/grotto

die() {
  echo "rootfs: $*" >&2
  exit 1
}

# The runtime stage's apt-get install list.
runtime_packages() {
  awk '/^FROM debian:bookworm-slim/ {stage = 1}
       stage && /apt-get install/ {take = 1; next}
       take && /rm -rf/ {exit}
       take {for (i = 1; i <= NF; i++) if ($i != "\\") print $i}' "$dockerfile"
}

# The image's entrypoint flags (after the binary).
entrypoint_flags() {
  sed -n 's/^ENTRYPOINT \["\/usr\/local\/bin\/grotto-server", \(.*\)\]$/\1/p' "$dockerfile" |
    tr -d '",'
}

build() {
  local root=$1 binary=$2 mirror=${3:-http://deb.debian.org/debian}
  [[ -x "$binary" ]] || die "no grotto-server binary at $binary"
  command -v debootstrap >/dev/null || die "debootstrap is missing (apt-get install debootstrap)"
  local packages
  packages=$(runtime_packages | paste -sd, -)
  [[ -n "$packages" ]] || die "found no runtime packages in $dockerfile"
  if [[ ! -x "$root/usr/bin/apt-get" ]]; then
    echo "rootfs: debootstrap bookworm into $root with $packages"
    debootstrap --variant=minbase --include="$packages" bookworm "$root" "$mirror" >"$root.log" 2>&1 ||
      die "debootstrap failed (log: $root.log)"
  fi
  rm -rf "$root"/var/cache/apt/archives/*.deb
  chroot "$root" sh -c "getent passwd $uid >/dev/null ||
    { groupadd --gid $uid grotto &&
      useradd --uid $uid --gid grotto --home-dir $cache --no-create-home \
        --shell /usr/sbin/nologin grotto; }"
  install -d -o "$uid" -g "$uid" -m 0750 "$root$cache" "$root$cache/cl" "$root$cache/pocl"
  install -m 0755 "$binary" "$root/usr/local/bin/grotto-server"
  # Every shared library resolves inside the root (what the runtime stage's list must cover).
  local missing
  missing=$(chroot "$root" ldd /usr/local/bin/grotto-server | grep 'not found' || true)
  [[ -z "$missing" ]] || die "libraries missing from the runtime packages: $missing"
  echo "rootfs: $root ready ($(du -sh "$root" | cut -f1))"
}

# Re-runs this script as `inside ROOT ACTION ...` in fresh mount, PID and network namespaces.
in_namespaces() {
  command -v unshare >/dev/null || die "unshare is missing (util-linux)"
  command -v ip >/dev/null || die "ip is missing (iproute2)"
  [[ -x "$1/usr/local/bin/grotto-server" ]] || die "$1 has no grotto-server (run build first)"
  unshare --mount --pid --net --fork --kill-child bash "$here/rootfs.sh" inside "$@"
}

# In the namespaces: the loopback up; ROOT read-only, with a writable cache (tmpfs owned by the
# image's user, standing in for the volume), /tmp, /proc and /dev.
mount_root() {
  local root=$1
  ip link set lo up
  mount --make-rprivate /
  mount --bind "$root" "$root"
  mount -t proc proc "$root/proc"
  mount --rbind /dev "$root/dev"
  mount --rbind /sys "$root/sys"  # PoCL reads the CPU topology (hwloc)
  mount -t tmpfs -o "uid=$uid,gid=$uid,mode=0750" tmpfs "$root$cache"
  install -d -o "$uid" -g "$uid" "$root$cache/cl" "$root$cache/pocl"
  mount -t tmpfs -o mode=1777 tmpfs "$root/tmp"
  mount -o remount,bind,ro "$root"
}

# The image's user, environment and entrypoint, then FLAGS; replaces the calling shell, so that
# SIGTERM reaches grotto-server itself (as PID 1 of a container it blocks and sigwaits for it).
start_server() {
  local root=$1
  shift
  local flags
  read -ra flags <<<"$(entrypoint_flags)"
  exec chroot --userspec="$uid:$uid" "$root" env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME="$cache" \
    GROTTO_CACHE_DIR="$cache/cl" POCL_CACHE_DIR="$cache/pocl" \
    /usr/local/bin/grotto-server "${flags[@]}" "$@"
}

# GET PATH from the server with the image's bash; prints the response.
get() {
  chroot "$1" /bin/bash -c \
    "exec 3<>/dev/tcp/127.0.0.1/7878 && printf 'GET $2 HTTP/1.0\r\n\r\n' >&3 && cat <&3"
}

smoke_inside() {
  local root=$1 health
  # The image's HEALTHCHECK command (JSON exec form), run in the image's root with its bash.
  health=$(grep -A1 '^HEALTHCHECK' "$dockerfile" | sed -n 's/.*"-c", "\(.*\)"\]$/\1/p' |
    sed 's/\\\\/\\/g')
  [[ -n "$health" ]] || die "no HEALTHCHECK command in $dockerfile"
  start_server "$root" >/tmp/server.out 2>/tmp/server.err &
  local pid=$! started=$SECONDS
  until chroot "$root" /bin/bash -c "$health" 2>/dev/null; do
    kill -0 "$pid" 2>/dev/null || die "grotto-server exited: $(cat /tmp/server.err)"
    ((SECONDS - started < 300)) || die "HEALTHCHECK did not pass within 300 s"
    sleep 0.2
  done
  echo "rootfs: HEALTHCHECK passed $((SECONDS - started)) s after the start"
  local path
  for path in /readyz /metrics /version; do
    get "$root" "$path" | head -n 1 | grep -q ' 200 ' || die "GET $path did not answer 200"
  done
  get "$root" /metrics | grep '^grotto_compute_path_info' | sed 's/^/rootfs: /'
  kill -TERM "$pid"
  local rc=0
  wait "$pid" || rc=$?
  [[ $rc -eq 0 ]] || die "grotto-server exited $rc after SIGTERM: $(cat /tmp/server.err)"
  echo "rootfs: /readyz, /metrics and /version answered 200; exit 0 after SIGTERM"
}

[[ $(id -u) -eq 0 ]] || die "needs root (debootstrap, chroot and mounts)"
case "${1:-}" in
  build) build "${2:?ROOT}" "${3:?SERVER_BINARY}" "${4:-}" ;;
  smoke | run) in_namespaces "${2:?ROOT}" "$1" "${@:3}" ;;
  inside)
    root=$(realpath "$2")
    mount_root "$root"
    if [[ $3 == smoke ]]; then smoke_inside "$root"; else start_server "$root" "${@:4}"; fi
    ;;
  *) die "usage: rootfs.sh build ROOT SERVER_BINARY [MIRROR] | smoke ROOT | run ROOT [FLAGS...]" ;;
esac
