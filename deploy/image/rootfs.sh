#!/usr/bin/env bash
# The container image without a container engine: a Debian 12 root with the runtime stage's
# packages (read from deploy/Dockerfile, so the two cannot drift), grotto-server copied in, and
# the same user, cache directories, environment and entrypoint, run under chroot in fresh mount,
# PID and network namespaces with the root file system read-only (as Kubernetes'
# readOnlyRootFilesystem would have it). Opt-in: it downloads Debian's packages (the root is
# ~800 MB, PoCL's LLVM and clang most of it) and takes minutes, so CI does not run it; deploy/image/image_test.sh does once GROTTO_IMAGE_ROOT
# names a root built here.
#   deploy/image/rootfs.sh build ROOT SERVER_BINARY [MIRROR]   debootstrap ROOT (as root), add
#                                                             the binary, user and directories
#   deploy/image/rootfs.sh compile ROOT SOURCE_DIR OUTPUT      the build stage: its packages and
#                                                             RUN commands on an overlay over
#                                                             ROOT, SOURCE_DIR's HEAD as the
#                                                             context; the binary to OUTPUT
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

# A stage's apt-get install list: stage 1 is the build stage, 2 the runtime stage.
stage_packages() {
  awk -v want="$1" '/^FROM / {stage++}
    /apt-get install/ {take = stage == want; next}
    take && /rm -rf/ {take = 0}
    take {for (i = 1; i <= NF; i++) if ($i != "\\") print $i}' "$dockerfile"
}

# The build stage's RUN commands after `COPY . .`, continuation lines joined, one per line.
build_commands() {
  awk '/^FROM / {stage++}
    stage == 1 && /^COPY \. \./ {copied = 1; next}
    copied && stage == 1 && /^RUN / {cmd = ""; run = 1; sub(/^RUN /, "")}
    run {line = $0; more = sub(/\\$/, "", line); cmd = cmd line; if (!more) {print cmd; run = 0}}' \
    "$dockerfile"
}

# The image's entrypoint flags (after the binary).
entrypoint_flags() {
  sed -n 's/^ENTRYPOINT \["\/usr\/local\/bin\/grotto-server", \(.*\)\]$/\1/p' "$dockerfile" |
    tr -d '",'
}

# Debian 12 minbase in ROOT with the runtime stage's packages, unless ROOT already holds one.
bootstrap() {
  local root=$1 mirror=${2:-http://deb.debian.org/debian}
  [[ -x "$root/usr/bin/apt-get" ]] && return 0
  command -v debootstrap >/dev/null || die "debootstrap is missing (apt-get install debootstrap)"
  local packages
  packages=$(stage_packages 2 | paste -sd, -)
  [[ -n "$packages" ]] || die "found no runtime packages in $dockerfile"
  echo "rootfs: debootstrap bookworm into $root with $packages"
  debootstrap --variant=minbase --include="$packages" bookworm "$root" "$mirror" >"$root.log" 2>&1 ||
    die "debootstrap failed (log: $root.log)"
  rm -rf "$root"/var/cache/apt/archives/*.deb
}

# The runtime stage: its user and directories, and BINARY as /usr/local/bin/grotto-server.
build() {
  local root=$1 binary=$2
  [[ -x "$binary" ]] || die "no grotto-server binary at $binary"
  bootstrap "$root" "${3:-}"
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

# The build stage: on a throw-away overlay over ROOT, the build stage's packages, the committed
# sources of SRC as the build context (git archive: no build trees, no .git), the stage's RUN
# commands; the binary is copied to OUT. ROOT itself is left as it was.
compile() {
  local root=$1 src=$2 out=$3
  bootstrap "$root" "${4:-}"
  command -v git >/dev/null || die "git is missing"
  local scratch
  scratch=$(mktemp -d)
  mkdir -p "$scratch/upper" "$scratch/work" "$scratch/merged"
  git -C "$src" archive --prefix=src/ HEAD | tar -x -C "$scratch/upper" ||
    die "cannot archive the sources of $src"
  unshare --mount bash "$here/rootfs.sh" compile-inside "$(realpath "$root")" "$scratch" "$out"
  local rc=$?
  rm -rf "$scratch"
  return $rc
}

compile_inside() {
  local root=$1 scratch=$2 out=$3 merged=$2/merged
  mount --make-rprivate /
  mount -t overlay overlay -o "lowerdir=$root,upperdir=$scratch/upper,workdir=$scratch/work" "$merged"
  mount -t proc proc "$merged/proc"
  mount --rbind /dev "$merged/dev"
  cp /etc/resolv.conf "$merged/etc/resolv.conf"
  local packages started=$SECONDS
  packages=$(stage_packages 1 | tr '\n' ' ')
  chroot "$merged" sh -c "apt-get update -qq && DEBIAN_FRONTEND=noninteractive \
    apt-get install -y -qq --no-install-recommends $packages >/dev/null" ||
    die "apt-get install of the build stage's packages failed"
  echo "rootfs: build stage packages installed in $((SECONDS - started)) s"
  started=$SECONDS
  local command
  while IFS= read -r command; do
    echo "rootfs: RUN $command"
    # WORKDIR /src, as in the Dockerfile.
    chroot "$merged" nice -n 10 sh -c "cd /src && $command" >"$scratch/build.log" 2>&1 ||
      die "the build stage's RUN failed (last lines below)
$(tail -n 30 "$scratch/build.log")"
  done < <(build_commands)
  echo "rootfs: built in $((SECONDS - started)) s"
  install -m 0755 "$merged/build/bin/grotto-server" "$out"
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
  compile) compile "${2:?ROOT}" "${3:?SOURCE_DIR}" "${4:?OUTPUT}" "${5:-}" ;;
  compile-inside) compile_inside "$2" "$3" "$4" ;;
  smoke | run) in_namespaces "${2:?ROOT}" "$1" "${@:3}" ;;
  inside)
    root=$(realpath "$2")
    mount_root "$root"
    if [[ $3 == smoke ]]; then smoke_inside "$root"; else start_server "$root" "${@:4}"; fi
    ;;
  *) die "usage: rootfs.sh build ROOT SERVER_BINARY [MIRROR] | compile ROOT SOURCE_DIR OUTPUT [MIRROR] | smoke ROOT | run ROOT [FLAGS...]" ;;
esac
