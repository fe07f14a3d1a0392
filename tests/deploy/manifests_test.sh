#!/usr/bin/env bash
# What can be checked offline about deploy/: the Kubernetes manifests build with kustomize and say
# what grotto-server does (probe paths, port, drain time, config keys, uid, cache paths, seed
# hashing), both example config files start a real grotto-server (there is no check-only mode: it
# starts on 127.0.0.1 with an ephemeral port and is stopped with SIGTERM), the probe paths and the
# image's HEALTHCHECK command answer 200 from it, the Dockerfile's build stage installs only
# deploy/setup.sh's packages and its runtime stage every package grotto-server's shared libraries
# come from (dpkg -S), the systemd unit passes `systemd-analyze verify`, and docs/OPERATING.md
# names only flags and metrics that exist.
# Not checked here: building the image (no container engine runs on these machines) and applying
# the manifests to a cluster.
#   manifests_test.sh SOURCE_DIR GROTTO_SERVER_BINARY
# Exit 0: pass; 1: a failure (each printed as FAIL: ...).
set -u
src=${1:?usage: manifests_test.sh SOURCE_DIR GROTTO_SERVER_BINARY}
server=${2:?usage: manifests_test.sh SOURCE_DIR GROTTO_SERVER_BINARY}
k8s="$src/deploy/k8s"
failures=0
fail() {
  echo "FAIL: $*"
  failures=$((failures + 1))
}

work=$(mktemp -d)
pid=
cleanup() {
  [[ -n "$pid" ]] && kill -KILL "$pid" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT

# Every tool here is a Debian 12 package (deploy/setup.sh installs them), so a missing one is a
# failure, not a skip.
python=/usr/bin/python3
[[ -x $python ]] || python=python3
missing=()
command -v kubectl >/dev/null || missing+=("kubectl (Debian package kubernetes-client)")
"$python" -c 'import yaml' 2>/dev/null || missing+=("python3 with PyYAML (python3-yaml)")
command -v systemd-analyze >/dev/null || missing+=("systemd-analyze (systemd)")
[[ -x "$server" ]] || missing+=("grotto-server at $server (build the grotto-server target)")
if [[ ${#missing[@]} -gt 0 ]]; then
  printf 'FAIL: missing %s\n' "${missing[@]}"
  exit 1
fi

# ---- 1. kustomize builds, and the result says what grotto-server does ----
if ! kubectl kustomize "$k8s" >"$work/built.yaml" 2>"$work/kustomize.err"; then
  fail "kubectl kustomize $k8s: $(cat "$work/kustomize.err")"
fi
# The facts the checks below compare against: the image's port and user (deploy/Dockerfile).
image_port=$(sed -n 's/^EXPOSE \([0-9]*\).*/\1/p' "$src/deploy/Dockerfile")
image_uid=$(sed -n 's/^USER \([0-9]*\).*/\1/p' "$src/deploy/Dockerfile")
grep -q "\"--port\", \"$image_port\"" "$src/deploy/Dockerfile" ||
  fail "deploy/Dockerfile: ENTRYPOINT's --port is not EXPOSE's $image_port"

"$python" - "$k8s" "$work" "$image_port" "$image_uid" <<'EOF' || failures=$((failures + 1))
import glob, json, os, sys, yaml

k8s, work, image_port, image_uid = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
errors = []
def check(ok, what):
    if not ok:
        errors.append(what)

for path in sorted(glob.glob(os.path.join(k8s, "*.yaml"))):
    try:
        list(yaml.safe_load_all(open(path)))
    except yaml.YAMLError as e:
        errors.append(f"{path} is not valid YAML: {e}")
docs = [d for d in yaml.safe_load_all(open(os.path.join(work, "built.yaml"))) if d]
by_kind = {}
for d in docs:
    by_kind.setdefault(d["kind"], []).append(d)
for kind in ["Deployment", "Service", "HorizontalPodAutoscaler", "PodDisruptionBudget",
             "ConfigMap", "Ingress"]:
    check(len(by_kind.get(kind, [])) == 1, f"kustomize output: expected one {kind}, got "
          f"{len(by_kind.get(kind, []))}")
if errors:
    print("\n".join("FAIL: " + e for e in errors))
    sys.exit(1)

dep, svc = by_kind["Deployment"][0], by_kind["Service"][0]
hpa, pdb = by_kind["HorizontalPodAutoscaler"][0], by_kind["PodDisruptionBudget"][0]
cm, ing = by_kind["ConfigMap"][0], by_kind["Ingress"][0]
pod = dep["spec"]["template"]["spec"]
pod_labels = dep["spec"]["template"]["metadata"]["labels"]
(c,) = pod["containers"]

# The config file grotto-server will read: the ConfigMap mounted where --config points.
(config_key,) = cm["data"].keys()
config = json.loads(cm["data"][config_key])
open(os.path.join(work, "configmap.json"), "w").write(cm["data"][config_key])
args = c.get("args", [])
check("--config" in args, "the container's args do not pass --config")
config_path = args[args.index("--config") + 1] if "--config" in args else ""
mounts = {m["mountPath"]: m for m in c.get("volumeMounts", [])}
volumes = {v["name"]: v for v in pod.get("volumes", [])}
config_dir, config_file = os.path.split(config_path)
m = mounts.get(config_dir)
check(m is not None and volumes[m["name"]].get("configMap", {}).get("name") == cm["metadata"]["name"]
      and config_file == config_key,
      f"--config {config_path} is not the ConfigMap's key {config_key} mounted at its directory")

# Probes on the real paths and port.
ports = {p["name"]: p["containerPort"] for p in c.get("ports", [])}
probes = {"readinessProbe": "/readyz", "livenessProbe": "/healthz", "startupProbe": "/healthz"}
for probe, path in probes.items():
    get = c.get(probe, {}).get("httpGet", {})
    check(get.get("path") == path, f"{probe} must GET {path} (got {get.get('path')})")
    port = get.get("port")
    check(ports.get(port, port) == image_port, f"{probe} port {port} is not the server's {image_port}")
check(ports.get("http") == image_port, f"containerPort http must be {image_port} (the image's port)")
check(svc["spec"]["ports"][0]["targetPort"] in ("http", image_port), "Service targets another port")

# Graceful termination: the grace period covers preStop and the server's drain.
drain_ms = config.get("drain-timeout-ms", 5000)
pre_stop = c.get("lifecycle", {}).get("preStop", {}).get("exec", {}).get("command", [])
pre_stop_s = int(pre_stop[1]) if len(pre_stop) == 2 and pre_stop[0] == "sleep" else 0
grace_s = pod.get("terminationGracePeriodSeconds", 30)
check(grace_s * 1000 > pre_stop_s * 1000 + drain_ms + 2000,
      f"terminationGracePeriodSeconds {grace_s} must exceed preStop {pre_stop_s} s + "
      f"drain-timeout-ms {drain_ms} + 2 s")

# Threads sized to the CPU limit: 0 would mean one per core of the node, not of the pod.
for key in ("workers", "io-threads"):
    check(config.get(key, 0) > 0, f"the ConfigMap must set {key} > 0 (0 means the node's cores)")
def cpu(v):
    v = str(v)
    return float(v[:-1]) / 1000 if v.endswith("m") else float(v)
res = c.get("resources", {})
check(cpu(res["limits"]["cpu"]) >= config.get("workers", 0),
      f"CPU limit {res['limits']['cpu']} is below workers {config.get('workers')}")
check(cpu(res["requests"]["cpu"]) <= cpu(res["limits"]["cpu"]), "CPU request above its limit")

# Non-root with a read-only root; the kernel caches on a writable volume.
sc, psc = c.get("securityContext", {}), pod.get("securityContext", {})
check(sc.get("readOnlyRootFilesystem") is True, "readOnlyRootFilesystem must be true")
check(sc.get("allowPrivilegeEscalation") is False, "allowPrivilegeEscalation must be false")
check(psc.get("runAsNonRoot") is True, "runAsNonRoot must be true")
check(psc.get("runAsUser") == image_uid, f"runAsUser must be the image's uid {image_uid}")
env = {e["name"]: e for e in c.get("env", [])}
for var in ("GROTTO_CACHE_DIR", "POCL_CACHE_DIR"):
    value = env.get(var, {}).get("value", "")
    under = [p for p in mounts if value.startswith(p + "/") and "emptyDir" in volumes[mounts[p]["name"]]]
    check(under, f"{var}={value!r} is not on an emptyDir volume")

# The token: from a Secret, optional (off by default), into the variable that the bash part
# below shows grotto-server reading.
secret_env = [n for n, e in env.items() if "secretKeyRef" in e.get("valueFrom", {})]
check(len(secret_env) == 1, f"expected one variable from a Secret (the token), got {secret_env}")
for name in secret_env:
    check(env[name]["valueFrom"]["secretKeyRef"].get("optional") is True,
          f"{name} must come from an optional Secret (the token is off by default)")
    open(os.path.join(work, "token_env"), "w").write(name)

# Selectors and references agree.
def selects(sel):
    return all(pod_labels.get(k) == v for k, v in sel.items())
check(selects(dep["spec"]["selector"]["matchLabels"]), "Deployment selector misses its pods")
check(selects(svc["spec"]["selector"]), "Service selector misses the pods")
check(selects(pdb["spec"]["selector"]["matchLabels"]), "PodDisruptionBudget selector misses the pods")
check(hpa["spec"]["scaleTargetRef"]["name"] == dep["metadata"]["name"], "HPA targets another Deployment")
check("replicas" not in dep["spec"], "Deployment sets replicas although the HPA owns them")
ann = ing["metadata"].get("annotations", {})
check(ann.get("nginx.ingress.kubernetes.io/upstream-hash-by") == "$arg_seed",
      "the Ingress must hash on $arg_seed (the client's /ws?seed=)")
backends = [p["backend"]["service"] for r in ing["spec"]["rules"] for p in r["http"]["paths"]]
check(all(b["name"] == svc["metadata"]["name"] for b in backends), "Ingress backend is not the Service")
paths = [p["path"] for r in ing["spec"]["rules"] for p in r["http"]["paths"]]
check(paths == ["/ws"], f"the Ingress should route /ws only (got {paths})")

for e in errors:
    print("FAIL: " + e)
sys.exit(1 if errors else 0)
EOF

# ---- 2. the example config files start grotto-server; probes and HEALTHCHECK answer 200 ----
# GET PATH from 127.0.0.1:PORT with bash alone; prints the status line.
http_status() {
  local port=$1 path=$2
  (exec 3<>"/dev/tcp/127.0.0.1/$port" && printf 'GET %s HTTP/1.0\r\n\r\n' "$path" >&3 &&
    timeout 5 head -n 1 <&3 | tr -d '\r') 2>/dev/null
}

# Starts grotto-server with FILE as --config, on loopback and an ephemeral port (flags win over
# the file), with the CPU reference to keep the start quick; sets pid and port.
start_server() {
  local config=$1 log=$2
  port=
  env "${server_env[@]}" "$server" --config "$config" --bind 127.0.0.1 --port 0 \
    --opencl-device none --workers 1 --io-threads 1 >"$log" 2>"$log.err" &
  pid=$!
  for _ in $(seq 1 300); do
    port=$(sed -n 's|.*listening on http://127.0.0.1:\([0-9]*\).*|\1|p' "$log" 2>/dev/null)  # the file may not exist yet
    [[ -n "$port" ]] && return 0
    kill -0 "$pid" 2>/dev/null || break
    sleep 0.1
  done
  return 1
}

stop_server() {
  kill -TERM "$pid" 2>/dev/null
  local rc=0
  timeout 30 tail --pid="$pid" -f /dev/null || rc=$?
  wait "$pid" 2>/dev/null || rc=$?
  pid=
  return $rc
}

# The Dockerfile's HEALTHCHECK command, pointed at this server's port.
healthcheck=$("$python" - "$src/deploy/Dockerfile" <<'EOF'
import json, re, sys
text = open(sys.argv[1]).read().replace("\\\n", " ")
m = re.search(r"^HEALTHCHECK .*?CMD (\[.*\])$", text, re.M)
cmd = json.loads(m.group(1)) if m else []
print(cmd[2] if cmd[:2] == ["/bin/bash", "-c"] else "")
EOF
)
[[ "$healthcheck" == *"/healthz"* ]] || fail "deploy/Dockerfile: no HEALTHCHECK against /healthz"

# The variable the Deployment fills from the token's Secret (written by the Python part).
token_env=$(cat "$work/token_env" 2>/dev/null)
token_env=${token_env:-GROTTO_TOKEN}
server_env=(-u "$token_env")
for config in "$work/configmap.json" "$src/deploy/systemd/grotto-server.json"; do
  [[ -f "$config" ]] || { fail "$config missing"; continue; }
  if ! start_server "$config" "$work/server.out"; then
    fail "grotto-server --config $config did not start: $(cat "$work/server.out.err")"
    kill -KILL "$pid" 2>/dev/null
    pid=
    continue
  fi
  for path in /healthz /readyz /metrics; do
    status=$(http_status "$port" "$path")
    [[ "$status" == *" 200 "* ]] || fail "GET $path with $config answered '$status', not 200"
  done
  if [[ "$config" == "$work/configmap.json" ]]; then
    bash -c "${healthcheck//7878/$port}" ||
      fail "the image's HEALTHCHECK command fails against a running server: $healthcheck"
    (exec 3<>"/dev/tcp/127.0.0.1/$port" && printf 'GET /metrics HTTP/1.0\r\n\r\n' >&3 &&
      timeout 5 cat <&3) >"$work/metrics.txt" 2>/dev/null
    "$server" --help >"$work/help.txt"
  fi
  grep -q "event=listening.* token=off" "$work/server.out.err" ||
    fail "grotto-server with $config and no $token_env does not log token=off"
  stop_server || fail "grotto-server with $config did not exit 0 after SIGTERM"
done

# The Deployment's token variable turns the token on (what creating the Secret does).
server_env=("$token_env=manifests-test-token")
if start_server "$work/configmap.json" "$work/token.out"; then
  grep -q "event=listening.* token=required" "$work/token.out.err" ||
    fail "grotto-server with $token_env set does not require a token (log: $(cat "$work/token.out.err"))"
  stop_server || fail "grotto-server with $token_env set did not exit 0 after SIGTERM"
else
  fail "grotto-server with $token_env set did not start: $(cat "$work/token.out.err")"
fi

# The check above can fail: a config file with an unknown key is refused (exit 2).
printf '{"workerz": 2}\n' >"$work/bad.json"
"$server" --config "$work/bad.json" --port 0 >/dev/null 2>"$work/bad.err"
rc=$?
if [[ $rc -ne 2 ]] || ! grep -q "unknown setting 'workerz'" "$work/bad.err"; then
  fail "grotto-server accepted a config file with an unknown key (rc=$rc): $(cat "$work/bad.err")"
fi

# ---- 3. the Dockerfile's package lists ----
# Its stages' apt-get lists: "build" (the first) and "runtime" (the second).
stage_packages() {
  awk -v want="$1" '/^FROM / {stage++}
    /apt-get install/ {take = (want == "build" && stage == 1) || (want == "runtime" && stage == 2); next}
    take && /rm -rf/ {take = 0}
    take {for (i = 1; i <= NF; i++) if ($i != "\\" && $i != "&&") print $i}' "$src/deploy/Dockerfile"
}
# Build dependencies are the ones deploy/setup.sh installs for a build (no others).
setup_list=$(bash "$src/deploy/setup.sh" --list)
for p in $(stage_packages build); do
  grep -qx "$p" <<<"$setup_list" || fail "deploy/Dockerfile builds with $p, which deploy/setup.sh does not list"
done
# Every shared library grotto-server loads comes from a runtime package (or from the base
# image's libc6, libstdc++6, libgcc-s1), as dpkg on this Debian machine says.
runtime=" $(stage_packages runtime | tr '\n' ' ') libc6 libstdc++6 libgcc-s1 "
[[ "$runtime" == *" pocl-opencl-icd "* ]] || fail "deploy/Dockerfile's runtime stage lacks pocl-opencl-icd"
for lib in $(ldd "$server" | awk '$3 ~ /^\// {print $3}'); do
  owner=$(dpkg -S "$(realpath "$lib")" 2>/dev/null | head -n 1 | cut -d: -f1)
  [[ -z "$owner" ]] && owner=$(dpkg -S "$lib" 2>/dev/null | head -n 1 | cut -d: -f1)
  [[ -n "$owner" && "$runtime" == *" $owner "* ]] ||
    fail "grotto-server loads $lib (package '${owner:-unknown}'), which the runtime stage does not install"
done

# ---- 4. the systemd unit verifies, and stops after the drain ----
unit="$src/deploy/systemd/grotto-server.service"
mkdir -p "$work/unit"
# verify checks that ExecStart's program exists: point it at the binary under test.
sed "s|^ExecStart=[^ ]*|ExecStart=$(realpath "$server")|" "$unit" >"$work/unit/grotto-server.service"
# Unknown keys and unparsable values are only warnings (exit 0): any output is a failure.
out=$(cd "$work/unit" && systemd-analyze verify grotto-server.service 2>&1)
rc=$?
[[ $rc -eq 0 && -z "$out" ]] || fail "systemd-analyze verify $unit (rc=$rc): $out"
stop_s=$(sed -n 's/^TimeoutStopSec=\([0-9]*\)$/\1/p' "$unit")
unit_drain_ms=$("$python" -c 'import json,sys; print(json.load(open(sys.argv[1])).get("drain-timeout-ms", 5000))' \
  "$src/deploy/systemd/grotto-server.json")
if [[ -z "$stop_s" ]] || ((stop_s * 1000 <= unit_drain_ms + 2000)); then
  fail "TimeoutStopSec=${stop_s:-unset} must exceed the drain (${unit_drain_ms} ms) + 2 s"
fi
grep -q "^ExecStart=.*--config /etc/grotto/grotto-server.json" "$unit" ||
  fail "the unit does not read /etc/grotto/grotto-server.json"

# ---- 5. docs/OPERATING.md names only metrics and flags that exist ----
guide="$src/docs/OPERATING.md"
if [[ ! -f "$guide" ]]; then
  fail "docs/OPERATING.md missing"
elif [[ -s "$work/metrics.txt" ]]; then
  for name in $(grep -o 'grotto_[a-z_]*' "$guide" | sort -u); do
    grep -q "^\(# TYPE \)\?${name}[ {]" "$work/metrics.txt" ||
      grep -q "^${name}" "$work/metrics.txt" ||
      fail "OPERATING.md names metric $name, which /metrics does not expose"
  done
  # grotto-server's flags from its --help; other Grotto programs' flags from their sources
  # (CLI11 options) and deploy/nginx/render.sh's usage text; the few flags of other tools the
  # guide uses are listed here.
  others=" --now --from-literal --rm --test-dir --build --target --offline "
  for flag in $(grep -o -- '--[a-z][a-z0-9-]*' "$guide" | sort -u); do
    grep -q -- "${flag}[ ,=]" "$work/help.txt" && continue
    grep -rqF -- "\"$flag\"" "$src/client" "$src/bench" "$src/common" 2>/dev/null && continue
    grep -qE -- "^  $flag( |$)" "$src/deploy/nginx/render.sh" 2>/dev/null && continue
    [[ "$others" == *" $flag "* ]] && continue
    fail "OPERATING.md names flag $flag, which neither grotto-server --help nor Grotto's sources define"
  done
fi

if [[ $failures -eq 0 ]]; then
  echo "deploy: manifests build and match grotto-server; configs start it; unit verifies; guide accurate"
fi
exit $((failures > 0))
