#!/usr/bin/env bash
# What can be checked offline about deploy/: the Kubernetes manifests build with kustomize and say
# what grotto-server does (probe paths, port, drain time, config keys, uid, cache paths, players
# spread by round robin, not hashed by seed), the owner ring (a headless Service over
# the Deployment's ready pods) and the room tier (nginx hashing $uri over the ring with
# proxy_cache_lock, its /rooms/ block the same as deploy/nginx's; its run.sh and nginx.conf run
# offline against a real grotto-server with a fake getent as the ring's DNS: a miss then a hit,
# a reload when the addresses change, the last ring kept when there are none, a clean SIGTERM),
# the Kubernetes config's keys are grotto-server flags, both example config files start a real
# grotto-server (there is no check-only mode: it starts on 127.0.0.1 with an ephemeral port and is
# stopped with SIGTERM), the probe paths and the
# image's HEALTHCHECK command answer 200 from it, the HPA scales on CPU and on a queue gauge that
# grotto-server exposes (grotto_sessions_queued), the Dockerfile's build stage installs only
# deploy/setup.sh's packages and its runtime stage every package grotto-server's shared libraries
# come from (dpkg -S), the systemd unit passes `systemd-analyze verify`, and docs/OPERATING.md
# names only flags and metrics that exist.
# Not checked here: building the image (no container engine runs on these machines) and applying
# the manifests to a cluster.
#   manifests_test.sh SOURCE_DIR GROTTO_SERVER_BINARY
# Exit 0: pass; 1: a failure (each printed as FAIL: ...). KEEP_WORK=1 keeps the scratch directory.
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
pid='' tier_pid=''
cleanup() {
  [[ -n "$pid" ]] && kill -KILL "$pid" 2>/dev/null
  if [[ -n "$tier_pid" ]]; then  # the room tier test did not finish: its nginx, then run.sh
    [[ -f "$work/tier/nginx.pid" ]] && kill -KILL "$(cat "$work/tier/nginx.pid")" 2>/dev/null
    kill -KILL "$tier_pid" 2>/dev/null
  fi
  [[ -n "${KEEP_WORK:-}" ]] || rm -rf "$work"
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
nginx_bin=$(command -v nginx || echo /usr/sbin/nginx)
[[ -x "$nginx_bin" ]] || missing+=("nginx (Debian package nginx)")
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
import glob, json, os, re, sys, yaml

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
expected = {"Deployment": 2, "Service": 3, "HorizontalPodAutoscaler": 1, "PodDisruptionBudget": 2,
            "ConfigMap": 2, "Ingress": 1}
for kind, n in expected.items():
    check(len(by_kind.get(kind, [])) == n, f"kustomize output: expected {n} {kind}, got "
          f"{len(by_kind.get(kind, []))}")
def named(kind, name):
    # Generated ConfigMaps carry a hash suffix (name-<hash>).
    found = [d for d in by_kind.get(kind, []) if d["metadata"]["name"] == name
             or (kind == "ConfigMap" and d["metadata"]["name"].startswith(name + "-"))]
    check(len(found) == 1, f"kustomize output: expected one {kind} named {name}")
    return found[0] if found else None
dep, svc = named("Deployment", "grotto-server"), named("Service", "grotto-server")
ring = named("Service", "grotto-server-ring")
tier, tier_svc = named("Deployment", "grotto-room-tier"), named("Service", "grotto-room-tier")
tier_cm = named("ConfigMap", "grotto-room-tier-config")
hpa, pdb = named("HorizontalPodAutoscaler", "grotto-server"), named("PodDisruptionBudget", "grotto-server")
tier_pdb = named("PodDisruptionBudget", "grotto-room-tier")
cm, ing = named("ConfigMap", "grotto-server-config"), named("Ingress", "grotto-server")
if errors:
    print("\n".join("FAIL: " + e for e in errors))
    sys.exit(1)

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
# The HPA follows CPU and the admission queue; the Pods metrics it names must be gauges that
# grotto-server exposes (checked against a real /metrics below).
hpa_metrics = hpa["spec"].get("metrics", [])
check(any(m.get("type") == "Resource" and m["resource"]["name"] == "cpu" for m in hpa_metrics),
      "the HPA no longer scales on CPU")
pods_metrics = [m["pods"]["metric"]["name"] for m in hpa_metrics if m.get("type") == "Pods"]
check("grotto_sessions_queued" in pods_metrics,
      "the HPA does not scale on the admission queue (Pods metric grotto_sessions_queued)")
open(os.path.join(work, "hpa_metrics.txt"), "w").write("".join(n + "\n" for n in pods_metrics))
check("replicas" not in dep["spec"], "Deployment sets replicas although the HPA owns them")
# Players are spread by load, not hashed by world: no upstream-hash-by, and round
# robin set explicitly (ingress.yaml says why not ewma).
ann = ing["metadata"].get("annotations", {})
check("nginx.ingress.kubernetes.io/upstream-hash-by" not in ann,
      "the Ingress still hashes players (upstream-hash-by); any replica serves any world now")
check(ann.get("nginx.ingress.kubernetes.io/load-balance") == "round_robin",
      "the Ingress must set load-balance: round_robin (ewma scores WebSockets by session length)")
routes = {p["path"]: p["backend"]["service"] for r in ing["spec"]["rules"] for p in r["http"]["paths"]}
check(routes.get("/ws", {}).get("name") == svc["metadata"]["name"], "Ingress /ws is not the Service")
# The browser viewer: its page, files and room extras, from the replicas too.
check(set(routes) <= {"/ws", "/rooms/", "/", "/viewer/", "/extras/"},
      f"the Ingress should route /ws, the viewer's paths (and /rooms/) only (got {list(routes)})")
for path in ("/", "/viewer/", "/extras/"):
    check(routes.get(path, {}).get("name") == svc["metadata"]["name"],
          f"Ingress {path} (the browser viewer) is not the Service")
if "/rooms/" in routes:
    check(routes["/rooms/"].get("name") == tier_svc["metadata"]["name"],
          "Ingress /rooms/ must go to the room tier's Service (its cache), not to the replicas")

# ---- the owner ring: a headless Service over the ready grotto-server pods ----
rs = ring["spec"]
check(rs.get("clusterIP") == "None", "grotto-server-ring must be headless (clusterIP: None)")
check(rs.get("publishNotReadyAddresses") is False,
      "grotto-server-ring must set publishNotReadyAddresses: false (only ready pods own rooms)")
check(rs.get("selector") == dep["spec"]["selector"]["matchLabels"],
      f"grotto-server-ring selects {rs.get('selector')}, not the Deployment's labels "
      f"{dep['spec']['selector']['matchLabels']}")
check(rs["ports"][0]["targetPort"] in ("http", image_port), "grotto-server-ring targets another port")
check(c.get("readinessProbe", {}).get("httpGet", {}).get("path") == "/readyz",
      "without a readinessProbe on /readyz the ring would hold pods that cannot serve")

# ---- the room tier: nginx over the ring, its ConfigMap, its Service ----
tpod = tier["spec"]["template"]["spec"]
tier_labels = tier["spec"]["template"]["metadata"]["labels"]
(tc,) = tpod["containers"]
check(tier["spec"].get("replicas", 1) >= 2, "the room tier should run 2 pods or more")
check(all(tier_labels.get(k) == v for k, v in tier["spec"]["selector"]["matchLabels"].items()),
      "room tier Deployment selector misses its pods")
check(all(tier_labels.get(k) == v for k, v in tier_svc["spec"]["selector"].items()),
      "grotto-room-tier Service misses the tier's pods")
check(not selects(tier_svc["spec"]["selector"]) and
      not all(tier_labels.get(k) == v for k, v in rs["selector"].items()),
      "the tier's and the replicas' selectors overlap")
check(all(tier_labels.get(k) == v for k, v in tier_pdb["spec"]["selector"]["matchLabels"].items()),
      "room tier PodDisruptionBudget misses its pods")
check(tc["image"] not in ("nginx", "nginx:latest") and (":" in tc["image"] or "@" in tc["image"]),
      f"the tier's image {tc['image']} must be named with a tag or digest (kustomization images:)")
tenv = {e["name"]: e.get("value") for e in tc.get("env", [])}
check(tenv.get("GROTTO_RING_NAME") == ring["metadata"]["name"],
      f"GROTTO_RING_NAME {tenv.get('GROTTO_RING_NAME')} is not the headless Service's name")
check(str(tenv.get("GROTTO_RING_PORT")) == str(image_port),
      f"GROTTO_RING_PORT {tenv.get('GROTTO_RING_PORT')} is not grotto-server's port {image_port}")
tmounts = {m["mountPath"]: m for m in tc.get("volumeMounts", [])}
tvolumes = {v["name"]: v for v in tpod.get("volumes", [])}
cmd = tc.get("command", [])
script_dir = os.path.dirname(cmd[-1]) if cmd else ""
check(cmd[-1:] and os.path.basename(cmd[-1]) == "run.sh" and script_dir in tmounts and
      tvolumes[tmounts[script_dir]["name"]].get("configMap", {}).get("name") == tier_cm["metadata"]["name"],
      f"the tier's command {cmd} does not run run.sh from its ConfigMap")
prefix = tenv.get("GROTTO_TIER_PREFIX") or ""
cache_vol = tvolumes.get(tmounts.get(prefix, {}).get("name"), {})
check("sizeLimit" in cache_vol.get("emptyDir", {}),
      f"GROTTO_TIER_PREFIX {prefix!r} (the room cache) must be an emptyDir with a sizeLimit")
tsc, tpsc = tc.get("securityContext", {}), tpod.get("securityContext", {})
check(tsc.get("readOnlyRootFilesystem") is True and tpsc.get("runAsNonRoot") is True,
      "the tier must run non-root on a read-only root")
check(all(k in tc.get("resources", {}).get("requests", {}) for k in ("cpu", "memory")),
      "the tier's container needs cpu and memory requests")
tports = {p["name"]: p["containerPort"] for p in tc.get("ports", [])}
for probe in ("readinessProbe", "livenessProbe"):
    get = tc.get(probe, {}).get("httpGet", {})
    check(get.get("path") == "/healthz" and get.get("port") in ("http", tports.get("http")),
          f"the tier's {probe} must GET /healthz on its http port")
check(tier_svc["spec"]["ports"][0]["targetPort"] in ("http", tports.get("http")),
      "grotto-room-tier targets another port")

# Its nginx.conf: listens on the container port, hashes $uri over the ring, keeps rooms with the
# cache lock on, and its /rooms/ block is deploy/nginx's, directive for directive.
check(set(tier_cm["data"]) == {"nginx.conf", "run.sh"},
      f"the tier's ConfigMap should hold nginx.conf and run.sh (got {sorted(tier_cm['data'])})")
conf = tier_cm["data"].get("nginx.conf", "")
os.makedirs(os.path.join(work, "tier-src"), exist_ok=True)
for key, text in tier_cm["data"].items():
    open(os.path.join(work, "tier-src", key), "w").write(text)
def directives(block):
    return [" ".join(line.split("#")[0].split()) for line in block.splitlines()
            if line.split("#")[0].strip()]
def block(text, opening):
    # The text between `opening {` and its closing brace, comments dropped.
    lines = [l.split("#")[0] for l in text.splitlines()]
    text = "\n".join(lines)
    start = text.find(opening)
    if start < 0:
        return None
    i, depth = text.index("{", start) + 1, 1
    j = i
    while depth and j < len(text):
        depth += {"{": 1, "}": -1}.get(text[j], 0)
        j += 1
    return text[i:j - 1]
check(f"listen {tports.get('http')};" in conf, f"the tier's nginx.conf does not listen on {tports.get('http')}")
rooms_loc = block(conf, "location /rooms/")
upstream_name = next((d.split()[1] for d in directives(rooms_loc or "") if d.startswith("proxy_pass ")), "")
upstream_name = upstream_name.replace("http://", "").rstrip(";")
ring_up = directives(block(conf, f"upstream {upstream_name} ") or "")
check("hash $uri consistent;" in ring_up, f"the tier's upstream {upstream_name} must hash $uri consistent")
check("include ring.conf;" in ring_up,
      f"the tier's upstream {upstream_name} must take its servers from ring.conf (run.sh writes it)")
check("proxy_cache_lock on;" in directives(rooms_loc or ""), "the tier's /rooms/ must set proxy_cache_lock on")
lb = open(os.path.join(k8s, "..", "nginx", "grotto.conf.in")).read()
lb_rooms = block(lb, "location /rooms/")
check(rooms_loc is not None and directives(rooms_loc) == directives(lb_rooms or ""),
      "the tier's location /rooms/ differs from deploy/nginx/grotto.conf.in's: "
      f"{sorted(set(directives(rooms_loc or '')) ^ set(directives(lb_rooms or '')))}")
m = re.search(r"max_size=(\d+)([kmg])", conf)
limit = cache_vol.get("emptyDir", {}).get("sizeLimit", "0")
def size(v, unit):
    return int(v) * {"k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "Ki": 1 << 10, "Mi": 1 << 20, "Gi": 1 << 30, "": 1}[unit]
lm = re.fullmatch(r"(\d+)(Ki|Mi|Gi|)", str(limit))
check(m and lm and size(*m.groups()) <= 0.8 * size(*lm.groups()),
      f"the tier's proxy_cache_path max_size must stay under 80 % of the emptyDir's sizeLimit {limit} "
      "(temp files and the cache manager's lag; a pod over it is evicted)")

# grotto-server asks the tier's Service for rooms.
tier_url = f"http://{tier_svc['metadata']['name']}:{tier_svc['spec']['ports'][0]['port']}"
check(config.get("room-tier") == tier_url,
      f"grotto-server.json's room-tier is {config.get('room-tier')!r}, not the tier's Service {tier_url}")
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
  # Emptied here, not by the redirection below: that runs in the child, and until it does, the
  # loop would read the port of the previous server from the same file.
  : >"$log"
  : >"$log.err"
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

# Every key of the Kubernetes config file is a grotto-server flag (CLI11 flags and config keys are
# one table, server/config.cpp), so --help documents what the ConfigMap sets.
if [[ -s "$work/help.txt" ]]; then
  for key in $("$python" -c 'import json, sys; print(" ".join(json.load(open(sys.argv[1]))))' "$work/configmap.json"); do
    grep -q -- "--${key}[ ,=]" "$work/help.txt" ||
      fail "deploy/k8s/grotto-server.json sets '$key', which grotto-server --help does not list"
  done
fi

# ---- 3. the room tier: its ConfigMap's run.sh and nginx.conf, run offline ----
# The files the Python part wrote from the ConfigMap, nginx on a free loopback port instead of
# the container port, a grotto-server from the Kubernetes config as the ring's one pod, and a
# fake getent first on PATH playing the headless Service's DNS: it answers `getent ahostsv4
# grotto-server-ring` as glibc does, with the addresses in $work/ring-ips. run.sh itself runs
# `nginx -t` before starting nginx and before each reload.
# The status line and headers of GET PATH from 127.0.0.1:PORT; with a third argument, the body too
# (text only: rooms are binary).
http_get() {
  local port=$1 path=$2 body=${3:-}
  (exec 3<>"/dev/tcp/127.0.0.1/$port" && printf 'GET %s HTTP/1.0\r\nHost: grotto-room-tier\r\n\r\n' "$path" >&3 &&
    if [[ -n "$body" ]]; then timeout 10 cat <&3 | tr -d '\r\0'; else timeout 10 cat <&3 | sed -n '1,/^\r$/p' | tr -d '\r\0'; fi) 2>/dev/null
}
wait_for() {  # wait_for SECONDS COMMAND...: until COMMAND succeeds, at most SECONDS
  local deadline=$((SECONDS + $1))
  shift
  until "$@"; do
    ((SECONDS < deadline)) || return 1
    sleep 0.2
  done
}
tier_src="$work/tier-src" tier="$work/tier"
if [[ -f "$tier_src/nginx.conf" && -f "$tier_src/run.sh" ]]; then
  tier_port=$("$python" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  sed -i "s/^\( *\)listen [0-9]*;/\1listen 127.0.0.1:$tier_port;/" "$tier_src/nginx.conf"
  mkdir -p "$work/fakebin"
  cat >"$work/fakebin/getent" <<FAKE
#!/bin/sh
[ "\$1" = ahostsv4 ] && [ "\$2" = grotto-server-ring ] || exit 2
while read -r ip; do printf '%-15s STREAM %s\n%-15s DGRAM\n%-15s RAW\n' "\$ip" "\$2" "\$ip" "\$ip"; done <"$work/ring-ips"
FAKE
  chmod +x "$work/fakebin/getent"
  server_env=(-u "$token_env")
  if start_server "$work/configmap.json" "$work/tier-server.out"; then
    echo 127.0.0.1 >"$work/ring-ips"
    # As in the pod, not as root: as root, nginx's workers would become nobody and could not
    # write the cache the master created. Its stdout and stderr belong to that user too, as
    # runc gives a container's user its stdio (nginx reopens /dev/stdout for the access log).
    as_user=()
    if [[ $EUID -eq 0 ]]; then
      as_user=(setpriv --reuid=nobody --regid=nogroup --clear-groups)
      mkdir -p "$tier" && touch "$work/tier.out" "$work/tier.err" &&
        chown nobody:nogroup "$tier" "$work/tier.out" "$work/tier.err" &&
        chmod a+rx "$work" "$work/fakebin" "$tier_src"
    fi
    PATH="$work/fakebin:$PATH" GROTTO_RING_INTERVAL=1 GROTTO_RING_PORT=$port GROTTO_TIER_PREFIX="$tier" \
      GROTTO_NGINX="$nginx_bin" "${as_user[@]}" sh "$tier_src/run.sh" >"$work/tier.out" 2>"$work/tier.err" &
    tier_pid=$!
    tier_up() { [[ "$(http_get "$tier_port" /healthz)" == *" 200 "* ]]; }
    if ! wait_for 15 tier_up; then
      fail "the room tier (run.sh + nginx.conf) did not answer /healthz: $(cat "$work/tier.err")"
    else
      grep -qx "server 127.0.0.1:$port max_fails=1 fail_timeout=5s;" "$tier/conf/ring.conf" ||
        fail "run.sh's ring.conf does not list the ring's address: $(cat "$tier/conf/ring.conf")"
      # A room through the tier: its URL's parameter digest is the one the server names when
      # refusing another (PROTOCOL.md, "Rooms over HTTP", 404).
      version=$(http_get "$port" /version body | sed -n 's/.*"protocol":\([0-9]*\).*/\1/p')
      seed=$("$python" -c 'import json, sys; print(json.load(open(sys.argv[1])).get("seed", "0"))' "$work/configmap.json")
      params=$(http_get "$tier_port" "/rooms/v$version/$seed/0000000000000000/0/0.0.0.r0" body | grep -o '([0-9a-f]\{16\})' | tr -d '()')
      room="/rooms/v$version/$seed/$params/0/0.0.0.r0"
      first=$(http_get "$tier_port" "$room") second=$(http_get "$tier_port" "$room")
      [[ "$first" == *" 200 "* && "$first" == *"X-Cache-Status: MISS"* ]] ||
        fail "GET $room through the tier: expected 200 from the owner and X-Cache-Status: MISS, got: $first"
      [[ "$second" == *" 200 "* && "$second" == *"X-Cache-Status: HIT"* ]] ||
        fail "GET $room again through the tier: expected 200 and X-Cache-Status: HIT, got: $second"
      # The ring follows the DNS answer: the only pod is now 127.0.0.2, where nothing listens.
      # A cached room stays a hit; another room goes to the new owner, which refuses (502).
      echo 127.0.0.2 >"$work/ring-ips"
      ring_moved() { grep -q "event=ring_changed servers=1 addresses=127.0.0.2" "$work/tier.err"; }
      if ! wait_for 10 ring_moved; then
        fail "run.sh did not reload nginx when the ring's addresses changed: $(cat "$work/tier.err")"
      else
        sleep 0.5  # the reloaded workers take over
        [[ "$(http_get "$tier_port" "$room")" == *"X-Cache-Status: HIT"* ]] ||
          fail "a cached room is no longer a hit after the ring changed"
        other=$(http_get "$tier_port" "/rooms/v$version/$seed/$params/0/0.0.0.r1")
        [[ "$other" == *" 502 "* ]] ||
          fail "after the ring moved to 127.0.0.2 (nothing there), a new room should get 502, got: $other"
      fi
      # No address (every pod unready, or DNS down): the last ring stays.
      : >"$work/ring-ips"
      ring_kept() { grep -q "event=ring_empty" "$work/tier.err"; }
      wait_for 10 ring_kept && grep -q "server 127.0.0.2:" "$tier/conf/ring.conf" ||
        fail "run.sh did not keep the last ring when the name resolved to nothing: $(cat "$tier/conf/ring.conf")"
    fi
    kill -TERM "$tier_pid" 2>/dev/null
    rc=0
    timeout 15 tail --pid="$tier_pid" -f /dev/null || rc=$?
    wait "$tier_pid" 2>/dev/null || rc=$?
    tier_pid=
    [[ $rc -eq 0 ]] || fail "run.sh did not exit 0 within 15 s of SIGTERM (rc=$rc): $(tail -n 5 "$work/tier.err")"
    nginx_left=$(cat "$tier/nginx.pid" 2>/dev/null)
    if [[ -n "$nginx_left" ]] && kill -0 "$nginx_left" 2>/dev/null; then
      fail "nginx (pid $nginx_left) still runs after run.sh stopped"
      kill -KILL "$nginx_left"
    fi
    stop_server || fail "grotto-server for the room tier test did not exit 0 after SIGTERM"
  else
    fail "grotto-server --config $work/configmap.json did not start: $(cat "$work/tier-server.out.err")"
    kill -KILL "$pid" 2>/dev/null
    pid=
  fi
fi

# ---- 4. the Dockerfile's package lists ----
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

# ---- 5. the systemd unit verifies, and stops after the drain ----
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

# The HPA's Pods metrics are gauges grotto-server exposes (a metrics adapter serves them as
# they are, averaged over the pods).
if [[ -s "$work/metrics.txt" && -f "$work/hpa_metrics.txt" ]]; then
  while read -r name; do
    grep -q "^# TYPE $name gauge$" "$work/metrics.txt" ||
      fail "the HPA scales on $name, which grotto-server's /metrics does not expose as a gauge"
  done <"$work/hpa_metrics.txt"
fi

# ---- 6. docs/OPERATING.md names only metrics and flags that exist ----
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
  # (CLI11 options), deploy/nginx/render.sh's usage text and the bench scripts' option parsing;
  # the few flags of other tools the guide uses are listed here.
  others=" --now --from-literal --rm --test-dir --build --target --offline "
  for flag in $(grep -o -- '--[a-z][a-z0-9-]*' "$guide" | sort -u); do
    grep -q -- "${flag}[ ,=]" "$work/help.txt" && continue
    grep -rqF -- "\"$flag\"" "$src/client" "$src/bench" "$src/common" 2>/dev/null && continue
    grep -qE -- "^  $flag( |$)" "$src/deploy/nginx/render.sh" 2>/dev/null && continue
    grep -qE -- "^ +$flag( \|.*)?\)" "$src"/bench/*.sh 2>/dev/null && continue
    [[ "$others" == *" $flag "* ]] && continue
    fail "OPERATING.md names flag $flag, which neither grotto-server --help nor Grotto's sources define"
  done
fi

if [[ $failures -eq 0 ]]; then
  echo "deploy: manifests build and match grotto-server; configs start it; unit verifies; guide accurate"
fi
exit $((failures > 0))
