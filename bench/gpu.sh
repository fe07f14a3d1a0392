#!/usr/bin/env bash
# The thesis's CPU-versus-GPU question on whatever this machine has: builds mesh_bench,
# server_bench and grotto-client (Release, in build-gpu/ unless --build-dir says otherwise), then
# runs
#   - mesh_bench (seed 42's 100-room detail cave) on each OpenCL device it finds (the keywords gpu,
#     accelerator and cpu, each in its own process, one row per distinct device) and on the CPU
#     reference: the deform launch with its device split (upload, kernel, download), the whole
#     cave through RoomBuilder on 1, 2 and every hardware thread;
#   - server_bench (fresh patch rooms, built and encoded, sector cache on) on the CPU reference
#     and on each device found, its workers sharing the device (the server's default) and each
#     with a context of its own; where a GPU is found, again on it with 16, 8 and 4 workers and
#     batches of 128 and 256 rooms, both ways, against the CPU reference;
#   - kernels_tests, where it is built or carried: the kernels against the CPU reference, bit for
#     bit, on the device "auto" picks (a GPU when there is one);
#   - grotto-client --bench (the scripted path, 1920x1080) with MaxTess 8, MaxTess 64 and
#     tessellation off, through EGL and, where DISPLAY is set, GLFW: one row per distinct
#     renderer; then the gallery's three halls held still (--hold: seed 95's hall entrance, seed
#     7's hall across, seed 95's stalactites), each row with its GPU time per pass (passes_ms)
#     and the formations drawn;
# and prints one Markdown table with the machine (CPU model and flags, cores, load average, GPUs
# that nvidia-smi lists). The JSON reports stay in --out.
#
#   bash bench/gpu.sh [--build-dir DIR] [--no-build] [--out DIR] [--quick] [--devices LIST]
#                     [--step-timeout S]
#
# --quick: 3 repetitions, 500 rooms, 4 s of frames (a smoke run); otherwise 5, 2,000 and 10 s.
# --devices: the OpenCL keywords tried, comma-separated (default gpu,accelerator,cpu; a machine
# whose own PoCL is known to abort can leave cpu out). --step-timeout: seconds each run may take
# before it is stopped and reported as failed (default 900).
# A device whose run fails or crashes is reported as such and the others go on (a machine's own
# PoCL has crashed a server before: each device runs in its own process). Exit: 0 when the table
# was printed, 1 when the build failed or nothing could run, 2 on a bad flag.
set -u
cd "$(dirname "$0")/.."

build_dir=build-gpu build=1 out="" quick=0 devices=gpu,accelerator,cpu step_timeout=900
usage() { sed -n '2,/^set -u/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }
while (($#)); do
  case "$1" in
    --build-dir) build_dir=${2:-} && shift ;;
    --no-build) build=0 ;;
    --out) out=${2:-} && shift ;;
    --quick) quick=1 ;;
    --devices) devices=${2:-} && shift ;;
    --step-timeout) step_timeout=${2:-} && shift ;;
    -h | --help) usage && exit 0 ;;
    *) echo "gpu.sh: unknown flag '$1' (--help lists them)" >&2 && exit 2 ;;
  esac
  shift
done
[[ -n "$build_dir" ]] || { echo "gpu.sh: --build-dir needs a directory" >&2; exit 2; }
[[ "$step_timeout" =~ ^[1-9][0-9]*$ ]] || { echo "gpu.sh: --step-timeout must be whole seconds >= 1" >&2; exit 2; }
[[ "$devices" =~ ^(gpu|accelerator|cpu)(,(gpu|accelerator|cpu))*$ ]] ||
  { echo "gpu.sh: --devices takes gpu, accelerator and cpu, comma-separated" >&2; exit 2; }
out=${out:-$build_dir/gpu-report}
mkdir -p "$out" || { echo "gpu.sh: cannot create $out" >&2; exit 1; }
if ((quick)); then reps=3 rooms=500 seconds=4; else reps=5 rooms=2000 seconds=10; fi

if ((build)); then
  echo "gpu.sh: building mesh_bench, server_bench and grotto-client (Release) in $build_dir" >&2
  cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release -DGROTTO_BUILD_TESTS=OFF >"$out/build.log" 2>&1 &&
    cmake --build "$build_dir" -j "$(nproc)" --target mesh_bench server_bench grotto-client \
      >>"$out/build.log" 2>&1 ||
    { echo "gpu.sh: the build failed (see $out/build.log)" >&2; exit 1; }
fi
bin=$build_dir/bin
for b in mesh_bench server_bench grotto-client; do
  [[ -x "$bin/$b" ]] || { echo "gpu.sh: $bin/$b is missing (build it, or drop --no-build)" >&2; exit 1; }
done

# The machine, before anything runs.
{
  echo "cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')"
  echo "cores=$(nproc)"
  echo "flags=$(grep -m1 '^flags' /proc/cpuinfo | tr ' ' '\n' | grep -E '^(avx2|avx512f)$' | tr '\n' ' ')"
  echo "load=$(cut -d' ' -f1-3 /proc/loadavg)"
  command -v nvidia-smi >/dev/null && echo "gpus=$(nvidia-smi -L 2>/dev/null | tr '\n' ';')"
} >"$out/machine.txt"

# The bits before the figures: where kernels_tests is built or carried (bench/gpu_carry.sh packs
# it), the kernels against the CPU reference, bit for bit, on the device "auto" picks (a GPU when
# there is one).
if [[ -x "$bin/kernels_tests" ]]; then
  echo "gpu.sh: kernels_tests (the kernels against the CPU reference)" >&2
  timeout "$step_timeout" "$bin/kernels_tests" --gtest_filter='DeformKernelTest.*:PinnedHost.*' \
    >"$out/bits.log" 2>&1
  echo $? >"$out/bits.rc"
fi

# mesh_bench on each device keyword; the first keyword that reaches a device names it. Seed 42's
# cave, the one BENCHMARKS' figures and history measured (every binary's default is 7).
found=()
for d in ${devices//,/ }; do
  echo "gpu.sh: mesh_bench --seed 42 --device $d" >&2
  timeout "$step_timeout" "$bin/mesh_bench" --seed 42 --device "$d" --repetitions "$reps" --json "$out/mesh-$d.json" \
    >"$out/mesh-$d.log" 2>&1
  rc=$?
  echo "$rc" >"$out/mesh-$d.rc"
  ((rc == 0)) && python3 - "$out/mesh-$d.json" <<'EOF' && found+=("$d")
import json, sys
sys.exit(0 if json.load(open(sys.argv[1]))["opencl"].get("available") else 1)
EOF
done

echo "gpu.sh: server_bench --devices none ${found[*]}" >&2
timeout "$step_timeout" "$bin/server_bench" --rooms "$rooms" --repetitions "$reps" --devices none "${found[@]}" \
  --queues shared per-worker --json "$out/server.json" >"$out/server.log" 2>&1
echo $? >"$out/server.rc"

# Where a GPU was found, the server's share of it against the CPU (the target: 1.4x) with fewer
# workers and bigger batches, the device shared (batches merged into launches) and a context a
# worker: whether the contexts' time slicing or the launches' size holds the GPU back.
sweep=()
if [[ " ${found[*]} " == *" gpu "* ]]; then
  for wb in 16:128 8:128 8:256 4:256; do
    w=${wb%:*} b=${wb#*:}
    echo "gpu.sh: server_bench --devices gpu --workers $w --batch $b" >&2
    timeout "$step_timeout" "$bin/server_bench" --rooms "$rooms" --repetitions "$reps" --devices gpu \
      --workers "$w" --batch "$b" --queues shared per-worker --json "$out/server-gpu-w$w-b$b.json" \
      >"$out/server-gpu-w$w-b$b.log" 2>&1
    echo $? >"$out/server-gpu-w$w-b$b.rc"
    sweep+=("w$w-b$b")
  done
fi
printf '%s\n' "${sweep[@]}" >"$out/sweep.txt"

renderers=(egl)
[[ -n "${DISPLAY:-}" ]] && renderers+=(glfw)
for gl in "${renderers[@]}"; do
  for setting in tess8 tess64 flat; do
    case $setting in
      tess8) flags=(--tess-max 8) ;;
      tess64) flags=(--tess-max 64) ;;
      flat) flags=(--no-tess) ;;
    esac
    echo "gpu.sh: grotto-client --bench $seconds --gl $gl ${flags[*]}" >&2
    timeout "$step_timeout" "$bin/grotto-client" --gl "$gl" --device none --width 1920 --height 1080 \
      --bench "$seconds" "${flags[@]}" --json "$out/client-$gl-$setting.json" \
      >"$out/client-$gl-$setting.log" 2>&1
    echo $? >"$out/client-$gl-$setting.rc"
  done
done

# The gallery's three halls held still: seed 95's hall from its entrance, seed 7's
# across, seed 95's stalactites overhead; the defaults, EGL.
halls=("hall-entrance-95 95 163.91,46.33,123.21,-136.6,5.2"
       "hall-across-7 7 61.20,57.79,40.01,270.0,5.0"
       "stalactites-95 95 55.96,51.14,44.57,200.0,55.0")
for h in "${halls[@]}"; do
  read -r name seed pose <<<"$h"
  echo "gpu.sh: grotto-client --bench $seconds --hold --pose $pose (seed $seed)" >&2
  timeout "$step_timeout" "$bin/grotto-client" --gl egl --device none --width 1920 --height 1080 \
    --seed "$seed" --pose "$pose" --mode fly --hold --bench "$seconds" \
    --json "$out/hall-$name.json" >"$out/hall-$name.log" 2>&1
  echo $? >"$out/hall-$name.rc"
done

python3 - "$out" <<'EOF'
import json, os, sys
out = sys.argv[1]
def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None
def rc(path):
    try:
        return open(path).read().strip()
    except OSError:
        return "?"
machine = dict(l.rstrip("\n").split("=", 1) for l in open(os.path.join(out, "machine.txt")) if "=" in l)
print(f"Machine: {machine.get('cpu', '?')}, {machine.get('cores', '?')} cores, flags: "
      f"{machine.get('flags', '').strip() or 'no avx2/avx512f'}, load average {machine.get('load', '?')}"
      + (f"; GPUs: {machine['gpus']}" if machine.get("gpus") else "; no nvidia-smi"))
print()
print("| measure | device or renderer | result |")
print("| --- | --- | --- |")
def whole(w):
    parts = f"layout {w['layout_ms']:.1f}, build {w['build_ms']:.1f}" if "layout_ms" in w else f"build {w['build_ms']:.1f}"
    region = w.get("region")
    if region:  # the region's every room, build_region's pipeline against layout then build
        parts += (f"; region of {region['rooms']} rooms: pipeline {region['pipeline_ms']:.1f}, "
                  f"laid out then built {region['layout_then_build_ms']:.1f}")
    return f"{w['whole_cave_ms']:.1f} ms ({parts})"
seen, ran = set(), 0
bits = os.path.join(out, "bits.log")
if os.path.exists(bits):
    log = open(bits, errors="replace").read()
    device = log.split('device="')[1].split('"')[0] if 'device="' in log else "?"
    passed = [l for l in log.splitlines() if l.startswith("[  PASSED  ]")]
    failed = sorted({l.split()[3] for l in log.splitlines()
                     if l.startswith("[  FAILED  ]") and len(l.split()) > 3 and "." in l.split()[3]})
    if rc(os.path.join(out, "bits.rc")) == "0" and passed:
        result = "passed: " + passed[-1][len("[  PASSED  ] "):].rstrip(".")
    else:
        result = f"FAILED (exit {rc(os.path.join(out, 'bits.rc'))}): " + (", ".join(failed) or "see bits.log")
    print(f"| kernels_tests: the deformation (with the detail channels) against the CPU, bit for bit | {device} | {result} |")
else:
    print("| kernels_tests | - | not built (a test build, or bench/gpu_carry.sh's pack, has it) |")
cpu_rows = None
for d in ("gpu", "accelerator", "cpu"):
    if not os.path.exists(os.path.join(out, f"mesh-{d}.rc")):
        continue
    report = load(os.path.join(out, f"mesh-{d}.json"))
    if report is None:
        print(f"| mesh_bench --device {d} | - | failed (exit {rc(os.path.join(out, f'mesh-{d}.rc'))}) |")
        continue
    ran += 1
    cl = report["opencl"]
    cave = f"{report['rooms']} rooms, {report['donor_vertices']:,} vertices"
    if cpu_rows is None:
        cpu_rows = [w for w in report["whole_cave"] if w["device"] == "none"]
        print(f"| deform, {cave}, CPU reference, 1 thread | CPU | {report['stages_ms']['deform_cpu']:.2f} ms |")
    if not cl.get("available"):
        print(f"| mesh_bench --device {d} | none found | {cl.get('reason', '')[:90]} |")
        continue
    if cl["device"] in seen:
        continue
    seen.add(cl["device"])
    name = cl["device"].split('device="')[-1].split('"')[0]
    split = cl["device_stages"]["deform"]
    print(f"| deform, {cave}, one batched launch | {name} | {cl['deform_ms']:.2f} ms "
          f"(upload {split['upload_ms']:.2f}, kernel {split['kernel_ms']:.2f}, download "
          f"{split['download_ms']:.2f}; {cl['deform_speedup_vs_cpu']:.1f}x the CPU) |")
    fused = cl["device_stages"].get("deform_with_channels")
    if isinstance(fused, dict):  # RoomBuilder's launch on GPUs: the channels computed with it
        print(f"| deform with the detail channels, {cave}, one launch, one lane | {name} | "
              f"{fused['run_ms']:.2f} ms (upload {fused['upload_ms']:.2f}, kernel {fused['kernel_ms']:.2f}, "
              f"download {fused['download_ms']:.2f}) |")
    for w in report["whole_cave"]:
        if w["device"] != "none":
            print(f"| whole cave, {w['threads']} thread(s) | {name} | {whole(w)} |")
for w in cpu_rows or []:
    print(f"| whole cave, {w['threads']} thread(s) | CPU reference | {whole(w)} |")
def queue(p):  # how the workers used the device (the CPU reference has none)
    return f", {p['queue']}" if p.get("queue") and p["device"] != "none" else ""
def launches(p):  # a shared device's launches and the workers' batches they carried
    if not p.get("device_launches"):
        return ""
    return f"; {p['device_batches']:,} batches in {p['device_launches']:,} launches"
server = load(os.path.join(out, "server.json"))
if server is None:
    print(f"| server_bench | - | failed (exit {rc(os.path.join(out, 'server.rc'))}) |")
else:
    ran += 1
    for p in server["pipeline"]:
        if p.get("sector_cache_entries", 0) == 0:
            continue
        path = p["path"].split('device="')[-1].split('"')[0] if p["path"].startswith("opencl") else "CPU reference"
        print(f"| server_bench, fresh patch rooms, cache on (--devices {p['device'] or 'auto'}{queue(p)}) | {path} | "
              f"{p['rooms_per_second']:,.0f} rooms/s (build {p['build_ms_per_room']:.3f}, "
              f"encode {p['encode_ms_per_room']:.3f} ms a room{launches(p)}) |")
cpu_rate = None
for p in (server or {}).get("pipeline", []):
    if p.get("sector_cache_entries", 0) and p["device"] == "none":
        cpu_rate = p["rooms_per_second"]
sweep_file = os.path.join(out, "sweep.txt")
for stem in (l.strip() for l in (open(sweep_file) if os.path.exists(sweep_file) else []) if l.strip()):
    w, b = stem[1:].split("-b")
    r = load(os.path.join(out, f"server-gpu-{stem}.json"))
    if r is None:
        print(f"| server_bench --devices gpu --workers {w} --batch {b} | - | failed (exit "
              f"{rc(os.path.join(out, f'server-gpu-{stem}.rc'))}) |")
        continue
    ran += 1
    for p in r["pipeline"]:
        if not p.get("sector_cache_entries", 0):
            continue
        path = p["path"].split('device="')[-1].split('"')[0] if p["path"].startswith("opencl") else "CPU reference"
        ratio = f"; {p['rooms_per_second'] / cpu_rate:.2f}x the CPU reference's default workers" if cpu_rate else ""
        print(f"| server_bench, cache on, --workers {w} --batch {b}{queue(p)} | {path} | "
              f"{p['rooms_per_second']:,.0f} rooms/s (build {p['build_ms_per_room']:.3f}, encode "
              f"{p['encode_ms_per_room']:.3f} ms a room{launches(p)}{ratio}) |")
def passes(r):
    p = r.get("passes_ms") or {}
    if not p:
        return ""
    parts = ", ".join(f"{k} {v:.1f}" for k, v in p.items())
    return f"; GPU ms per pass: {parts}; {r.get('formations', 0):.0f} formations"
renderers = {}
clients = [os.path.join(out, f"client-{gl}-{setting}.json") for gl in ("egl", "glfw")
           for setting in ("tess8", "tess64", "flat")]
for path in (p for p in clients if os.path.exists(p[:-5] + ".rc")):
    r = load(path)
    stem = os.path.basename(path)[len("client-"):-len(".json")]
    if r is None:
        print(f"| grotto-client --bench, {stem} | - | failed (exit {rc(path[:-5] + '.rc')}) |")
        continue
    ran += 1
    gl, setting = stem.split("-", 1)
    key = (r["gl_renderer"], setting)
    if key in renderers:
        continue
    renderers[key] = r
    what = {"tess8": "MaxTess 8", "tess64": "MaxTess 64", "flat": "tessellation off"}[setting]
    print(f"| grotto-client 1920x1080, {what} ({gl}) | {r['gl_renderer']} | median {r['median_ms']:.1f} ms, "
          f"p99 {r['p99_ms']:.1f} ms, {r['fps']:.1f} fps, {r['frames']} frames{passes(r)} |")
for name in ("hall-entrance-95", "hall-across-7", "stalactites-95"):
    path = os.path.join(out, f"hall-{name}.json")
    if not os.path.exists(path[:-5] + ".rc"):
        continue
    r = load(path)
    if r is None:
        print(f"| grotto-client --bench --hold, {name} | - | failed (exit {rc(path[:-5] + '.rc')}) |")
        continue
    ran += 1
    print(f"| grotto-client 1920x1080, {name} held (egl) | {r['gl_renderer']} | median {r['median_ms']:.1f} ms, "
          f"p99 {r['p99_ms']:.1f} ms, {r['fps']:.1f} fps, {r['frames']} frames{passes(r)} |")
print()
print(f"Reports: {out}")
sys.exit(0 if ran else 1)
EOF
