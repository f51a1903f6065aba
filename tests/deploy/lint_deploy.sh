#!/usr/bin/env bash
# Checks the deployment files and scripts: shellcheck, yamllint, the Kubernetes manifests'
# structure (what a Deployment/Service/PVC must hold, and that they refer to each other
# consistently), and that every file the Dockerfile copies exists.
set -euo pipefail
cd "$(dirname "$0")/../.."
shellcheck -x deploy/run-server.sh deploy/debian-deps.sh tests/run-tests.sh tests/bench/run.sh tests/bench/gpu.sh \
  tests/deploy/lint_deploy.sh tests/sanitizers/run.sh tests/smoke-server.sh tests/gallery/make.sh tests/server/small_disk.sh tests/soak.sh \
  tests/deploy/container_test.sh tests/deploy/compose_replicas_test.sh tests/deploy/image.sh .ci/run \
  tests/server/install_test.sh tests/client/package_test.sh tests/support/server.sh
yamllint -s -c deploy/.yamllint deploy/compose.yaml deploy/k8s/*.yaml
python3 - deploy/k8s/*.yaml <<'PY'
import sys
import yaml

problems = []
docs = [d for path in sys.argv[1:] for d in yaml.safe_load_all(open(path)) if d]
by_kind = {}
for d in docs:
    for key in ("apiVersion", "kind", "metadata"):
        if key not in d:
            problems.append(f"a document lacks {key}")
    by_kind.setdefault(d.get("kind"), []).append(d)
for dep in by_kind.get("Deployment", []):
    spec = dep["spec"]
    labels = spec["template"]["metadata"]["labels"]
    for k, v in spec["selector"]["matchLabels"].items():
        if labels.get(k) != v:
            problems.append(f"Deployment {dep['metadata']['name']}: selector {k}={v} misses the pod labels")
    claims = {c["metadata"]["name"] for c in by_kind.get("PersistentVolumeClaim", [])}
    volumes = {v["name"]: v for v in spec["template"]["spec"].get("volumes", [])}
    for c in spec["template"]["spec"]["containers"]:
        ports = {p["name"]: p["containerPort"] for p in c.get("ports", [])}
        for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
            p = c.get(probe)
            if not p or "grpc" not in p or p["grpc"]["port"] not in ports.values():
                problems.append(f"container {c['name']}: {probe} is not a gRPC probe on a declared port")
        for m in c.get("volumeMounts", []):
            v = volumes.get(m["name"])
            if v is None:
                problems.append(f"container {c['name']}: mounts unknown volume {m['name']}")
            elif "persistentVolumeClaim" in v and v["persistentVolumeClaim"]["claimName"] not in claims:
                problems.append(f"volume {m['name']}: claim {v['persistentVolumeClaim']['claimName']} is not defined")
        if "nvidia.com/gpu" not in c.get("resources", {}).get("limits", {}):
            problems.append(f"container {c['name']}: no nvidia.com/gpu limit")
        # The image listens on all of the pod's interfaces: the API needs tokens.
        args = c.get("args", [])
        if "--tokens" not in args or args[args.index("--tokens") + 1:][:1] == []:
            problems.append(f"Deployment {dep['metadata']['name']}: the server runs without --tokens")
# Each Service selects the pods of a Deployment or StatefulSet, on ports they declare.
workloads = by_kind.get("Deployment", []) + by_kind.get("StatefulSet", [])
for svc in by_kind.get("Service", []):
    matched = [w for w in workloads
               if all(w["spec"]["template"]["metadata"]["labels"].get(k) == v
                      for k, v in svc["spec"]["selector"].items())]
    if not matched:
        problems.append(f"Service {svc['metadata']['name']}: its selector matches no pod")
        continue
    named = {p["name"] for w in matched for c in w["spec"]["template"]["spec"]["containers"]
             for p in c.get("ports", [])}
    for p in svc["spec"]["ports"]:
        if isinstance(p.get("targetPort"), str) and p["targetPort"] not in named:
            problems.append(f"Service {svc['metadata']['name']}: targetPort {p['targetPort']} is not a container port")
# A Secret a container reads is defined, with the key it reads.
secrets = {s["metadata"]["name"]: s for s in by_kind.get("Secret", [])}
for w in workloads:
    for c in w["spec"]["template"]["spec"]["containers"]:
        for e in c.get("env", []):
            ref = e.get("valueFrom", {}).get("secretKeyRef")
            if ref and ref["key"] not in secrets.get(ref["name"], {}).get("stringData", {}):
                problems.append(f"container {c['name']}: secret {ref['name']} has no key {ref['key']}")
for kind in ("Deployment", "Service", "PersistentVolumeClaim"):
    if kind not in by_kind:
        problems.append(f"no {kind}")
if problems:
    print("\n".join(problems))
    sys.exit(1)
print(f"{len(docs)} manifests consistent")
PY
# compose: a server with no --tokens publishes its ports on the host's loopback alone.
python3 - deploy/compose.yaml <<'PY'
import sys
import yaml

problems = []
services = yaml.safe_load(open(sys.argv[1]))["services"]
for name, svc in services.items():
    if "deploy/Dockerfile" not in str(svc.get("build", {}).get("dockerfile", "")):
        continue
    if "--tokens" in svc.get("command", []):
        continue
    for port in svc.get("ports", []):
        if not str(port).startswith("127.0.0.1:"):
            problems.append(f"compose service {name}: publishes {port} beyond loopback without --tokens")
if problems:
    print("\n".join(problems))
    sys.exit(1)
print("compose: every server without tokens is published on loopback only")
PY
# Every COPY source of the Dockerfile (context: the repository root) exists.
grep -E '^COPY [^-]' deploy/Dockerfile | while read -r _ src _; do
  [ -e "$src" ] || { echo "Dockerfile copies missing $src"; exit 1; }
done
# The image's build stage gets every directory the Release build reads: each add_subdirectory
# of the top CMakeLists.txt (tests aside: the image builds with GVD_BUILD_TESTS=OFF) and each
# top-level directory a CMakeLists.txt outside tests/ names through PROJECT_SOURCE_DIR (the
# web app's files, say).
needed=$( { sed -n 's/^add_subdirectory(\([a-z_]*\))$/\1/p' CMakeLists.txt
            find . -name CMakeLists.txt -not -path './tests/*' -not -path './build/*' -print0 |
              xargs -0 grep -ohE 'PROJECT_SOURCE_DIR\}/[a-z_]+/' | sed -E 's|.*\}/([a-z_]+)/|\1|'
          } | sort -u)
for dir in $needed; do
  grep -qE "^COPY $dir $dir\$" deploy/Dockerfile ||
    { echo "Dockerfile does not copy $dir/, which the build reads"; exit 1; }
done
echo "deploy files pass"
