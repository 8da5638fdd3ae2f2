#!/usr/bin/env python3
"""Consistency checks of the Kubernetes manifests in deploy/kubernetes/ (needs PyYAML).

    scripts/check_manifests.py [DIR]                      # default: deploy/kubernetes
    REFLECTANCE_BIN=target/release/reflectance scripts/check_manifests.py

A schema validator (scripts/validate_manifests.sh runs one first) says that every field
exists and has the right type; this says that the manifests fit together and fit the
server:

* kustomizations list every manifest of their folder, their files exist, their `images`
  cover every image the resources use;
* the Service, the PodDisruptionBudget and the Deployment's own selector match its pod
  labels, the Service's target port is a container port, which is REFLECTANCE_LISTEN's
  port; the HorizontalPodAutoscaler targets the Deployment, with a CPU request to scale on
  and a minimum the disruption budget leaves serving;
* probes GET paths that openapi.yaml routes, on the served port; the grace period covers
  the drain delay plus the shutdown grace;
* every pod meets the "restricted" Pod Security Standard as deployed here (user 65532,
  read-only root, no privilege escalation, no capabilities, RuntimeDefault seccomp), has
  requests and limits (requests ≤ limits), and references volumes, ConfigMaps and claims
  that exist; reflectance containers use the image's entrypoint (no shell), and every
  $(VAR) in their arguments is defined;
* the Indexed Job's `completions` equals SHARDS, it passes `--shard $(JOB_COMPLETION_INDEX)/
  $(SHARDS)`, and the merge Job lists exactly the partial files the shards write;
* REFLECTANCE_* variables are settings the server has (the binary's `serve --help`, else
  the `env = "…"` attributes in src/cli/).

With REFLECTANCE_BIN (a built binary) also: every subcommand and flag the containers use is
one `reflectance <sub> --help` lists; the training Jobs run for real, offline, in a
temporary folder (the Indexed Job's pods all at once into one folder, then the merge, with
two small synthetic light probes at 72 px), their merged manifest and table must hold the
rows of an unsharded run, and merging the parts in another order must give the same bytes;
the serving container starts with the Deployment's
environment (on a free loopback port) and its probe paths answer 200. Without it, that
part is skipped with a message.

Exit status: 0 when every check passes, 1 otherwise (each problem on its own line).
"""

import concurrent.futures
import math
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

try:
    import yaml
except ImportError:  # pragma: no cover
    sys.exit("check_manifests: PyYAML is needed (scripts/validate_manifests.sh installs it)")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SERVER_USER = 65532
# The image's entrypoint (Dockerfile); a container may name it or leave it to the image.
ENTRYPOINT = "/usr/local/bin/reflectance"
# Settings the server reads with std::env::var rather than through a flag.
EXTRA_SERVER_ENV = {"REFLECTANCE_ADMIN_TOKEN", "REFLECTANCE_PROGRESS_SECONDS"}
# Volume types the restricted Pod Security Standard allows.
RESTRICTED_VOLUMES = {
    "configMap", "csi", "downwardAPI", "emptyDir", "ephemeral",
    "persistentVolumeClaim", "projected", "secret",
}
SIM_SIZE = "72"

problems = []


def problem(where, text):
    problems.append(f"{where}: {text}")


def rel(path):
    path = os.path.abspath(path)
    return os.path.relpath(path, ROOT) if path.startswith(ROOT + os.sep) else path


# ---------------------------------------------------------------- loading


class Doc:
    def __init__(self, path, body):
        self.path, self.body = path, body
        self.kind = body.get("kind", "")
        self.name = (body.get("metadata") or {}).get("name", "")

    def __repr__(self):
        return f"{rel(self.path)} {self.kind}/{self.name}"


def load(root):
    docs, kustomizations = [], []
    for folder, dirs, files in os.walk(root):
        dirs.sort()
        for name in sorted(files):
            if not name.endswith((".yaml", ".yml")):
                continue
            path = os.path.join(folder, name)
            try:
                with open(path, encoding="utf-8") as f:
                    bodies = [b for b in yaml.safe_load_all(f) if b is not None]
            except yaml.YAMLError as e:
                problem(rel(path), f"not YAML: {e}")
                continue
            for body in bodies:
                if not isinstance(body, dict):
                    problem(rel(path), "a document that is not a mapping")
                elif body.get("kind") == "Kustomization":
                    kustomizations.append(Doc(path, body))
                else:
                    docs.append(Doc(path, body))
    return docs, kustomizations


def pod_spec(doc):
    b = doc.body
    if doc.kind == "Pod":
        return b.get("spec") or {}
    if doc.kind in ("Deployment", "StatefulSet", "DaemonSet", "ReplicaSet", "Job"):
        return ((b.get("spec") or {}).get("template") or {}).get("spec") or {}
    if doc.kind == "CronJob":
        return (((b["spec"].get("jobTemplate") or {}).get("spec") or {}).get("template") or {}).get("spec") or {}
    return None


def pod_labels(doc):
    if doc.kind == "Pod":
        return (doc.body.get("metadata") or {}).get("labels") or {}
    return ((doc.body["spec"].get("template") or {}).get("metadata") or {}).get("labels") or {}


def containers(spec):
    return [("initContainer", c) for c in spec.get("initContainers") or []] + [
        ("container", c) for c in spec.get("containers") or []
    ]


def image_name(image):
    """The image reference without tag or digest."""
    name = image.split("@", 1)[0]
    last = name.rsplit("/", 1)[-1]
    if ":" in last:
        name = name[: len(name) - len(last)] + last.split(":", 1)[0]
    return name


def is_reflectance(container):
    return image_name(container.get("image", "")).rsplit("/", 1)[-1] == "reflectance"


# ---------------------------------------------------------------- quantities


QUANTITY = re.compile(r"^([+-]?[0-9.]+)([eE][+-]?[0-9]+)?(Ki|Mi|Gi|Ti|Pi|Ei|m|k|M|G|T|P|E)?$")
SUFFIX = {
    None: 1, "m": 1e-3, "k": 1e3, "M": 1e6, "G": 1e9, "T": 1e12, "P": 1e15, "E": 1e18,
    "Ki": 2**10, "Mi": 2**20, "Gi": 2**30, "Ti": 2**40, "Pi": 2**50, "Ei": 2**60,
}


def quantity(value):
    m = QUANTITY.match(str(value))
    if not m:
        raise ValueError(f"not a quantity: {value!r}")
    number = float(m.group(1) + (m.group(2) or ""))
    return number * SUFFIX[m.group(3)]


# ---------------------------------------------------------------- $(VAR) expansion


def expand(text, env):
    """Kubernetes' expansion of $(VAR) in command, args and env values: defined names are
    replaced, $$ is a literal $, anything else stays as written."""
    out, i = [], 0
    while i < len(text):
        if text.startswith("$$", i):
            out.append("$")
            i += 2
        elif text.startswith("$(", i):
            j = text.find(")", i + 2)
            name = text[i + 2 : j] if j >= 0 else None
            if name is not None and name in env:
                out.append(env[name])
                i = j + 1
            else:
                out.append("$(")
                i += 2
        else:
            out.append(text[i])
            i += 1
    return "".join(out)


def references(text):
    return re.findall(r"(?<!\$)\$\(([^)]*)\)", text)


# ---------------------------------------------------------------- checks


def check_kustomizations(kustomizations, docs):
    by_path = {}
    for d in docs:
        by_path.setdefault(os.path.abspath(d.path), []).append(d)
    namespaces = {d.name for d in docs if d.kind == "Namespace"}
    for k in kustomizations:
        where = rel(k.path)
        folder = os.path.dirname(k.path)
        listed = set()
        for entry in k.body.get("resources") or []:
            target = os.path.normpath(os.path.join(folder, entry))
            if os.path.isdir(target):
                if not os.path.exists(os.path.join(target, "kustomization.yaml")):
                    problem(where, f"resource {entry} is a folder without a kustomization.yaml")
            elif not os.path.isfile(target):
                problem(where, f"resource {entry} does not exist")
            elif os.path.dirname(target) != folder and not target.startswith(folder + os.sep):
                problem(where, f"resource {entry} is outside the kustomization's folder (kustomize refuses it)")
            listed.add(target)
        for name in sorted(os.listdir(folder)):
            path = os.path.join(folder, name)
            if name.endswith((".yaml", ".yml")) and name != "kustomization.yaml" and path not in listed:
                problem(where, f"{name} is in the folder but not in `resources` (it would not be applied)")
        ns = k.body.get("namespace")
        if ns and namespaces and ns not in namespaces:
            problem(where, f"namespace {ns!r} is not the Namespace defined here ({sorted(namespaces)})")
        covered = {i.get("name") for i in k.body.get("images") or []}
        for target in listed:
            for d in by_path.get(target, []):
                spec = pod_spec(d)
                for _, c in containers(spec or {}):
                    if image_name(c.get("image", "")) not in covered:
                        problem(where, f"{d}: image {c.get('image')!r} is not in `images` (it would not be replaced)")


def check_unique(docs, root):
    seen = {}
    for d in docs:
        key = (group_of(d, root), d.kind, d.name)
        if key in seen:
            problem(str(d), f"same kind and name as {seen[key]}")
        seen.setdefault(key, d)


def group_of(doc, root):
    """serving, training, … — the first folder under deploy/kubernetes."""
    parts = os.path.relpath(doc.path, root).split(os.sep)
    return parts[0] if len(parts) > 1 else ""


def check_pods(docs, root, server_env):
    configmaps = {(group_of(d, root), d.name): d for d in docs if d.kind == "ConfigMap"}
    claims = {(group_of(d, root), d.name): d for d in docs if d.kind == "PersistentVolumeClaim"}
    for d in docs:
        spec = pod_spec(d)
        if spec is None:
            continue
        group = group_of(d, root)
        psc = spec.get("securityContext") or {}
        if spec.get("automountServiceAccountToken") is not False:
            problem(str(d), "automountServiceAccountToken must be false (no pod here talks to the API)")
        if spec.get("enableServiceLinks") is not False:
            problem(str(d), "enableServiceLinks must be false (a Service named reflectance would add REFLECTANCE_* variables)")
        if ((psc.get("seccompProfile") or {}).get("type")) != "RuntimeDefault":
            problem(str(d), "pod securityContext.seccompProfile.type must be RuntimeDefault")
        volumes = {}
        for v in spec.get("volumes") or []:
            volumes[v["name"]] = v
            kinds = set(v) - {"name"}
            if not kinds <= RESTRICTED_VOLUMES:
                problem(str(d), f"volume {v['name']}: {sorted(kinds)} is not allowed by the restricted standard")
            if "configMap" in v and (group, v["configMap"].get("name")) not in configmaps:
                problem(str(d), f"volume {v['name']}: no ConfigMap {v['configMap'].get('name')!r} in {group}/")
            if "persistentVolumeClaim" in v and (group, v["persistentVolumeClaim"].get("claimName")) not in claims:
                problem(str(d), f"volume {v['name']}: no PersistentVolumeClaim {v['persistentVolumeClaim'].get('claimName')!r} in {group}/")
        for role, c in containers(spec):
            where = f"{d} {role} {c.get('name')}"
            csc = c.get("securityContext") or {}
            user = csc.get("runAsUser", psc.get("runAsUser"))
            if csc.get("runAsNonRoot", psc.get("runAsNonRoot")) is not True:
                problem(where, "runAsNonRoot must be true")
            if user != SERVER_USER:
                problem(where, f"runAsUser must be {SERVER_USER} (the image's nonroot user), not {user!r}")
            if csc.get("allowPrivilegeEscalation") is not False:
                problem(where, "allowPrivilegeEscalation must be false")
            if csc.get("readOnlyRootFilesystem") is not True:
                problem(where, "readOnlyRootFilesystem must be true")
            if csc.get("privileged"):
                problem(where, "must not be privileged")
            if "ALL" not in ((csc.get("capabilities") or {}).get("drop") or []):
                problem(where, "capabilities.drop must contain ALL")
            if (csc.get("capabilities") or {}).get("add"):
                problem(where, "must add no capabilities")
            resources = c.get("resources") or {}
            for res in ("cpu", "memory"):
                req = (resources.get("requests") or {}).get(res)
                lim = (resources.get("limits") or {}).get(res)
                if req is None or lim is None:
                    problem(where, f"{res}: both a request and a limit are needed")
                    continue
                try:
                    if quantity(req) > quantity(lim):
                        problem(where, f"{res}: request {req} is above the limit {lim}")
                except ValueError as e:
                    problem(where, f"{res}: {e}")
            for m in c.get("volumeMounts") or []:
                if m.get("name") not in volumes:
                    problem(where, f"volumeMount {m.get('name')!r} has no volume")
            env_names = set()
            for e in c.get("env") or []:
                env_names.add(e["name"])
                ref = (e.get("valueFrom") or {}).get("resourceFieldRef")
                if ref and ref.get("containerName", c.get("name")) != c.get("name"):
                    problem(where, f"env {e['name']}: resourceFieldRef names container {ref.get('containerName')!r}")
                if e["name"].startswith("REFLECTANCE_") and server_env is not None and e["name"] not in server_env[0]:
                    problem(where, f"env {e['name']}: the server has no such setting (checked against {server_env[1]})")
            for src in c.get("envFrom") or []:
                ref = src.get("configMapRef")
                if ref:
                    cm = configmaps.get((group, ref.get("name")))
                    if cm is None:
                        problem(where, f"envFrom: no ConfigMap {ref.get('name')!r} in {group}/")
                    else:
                        env_names |= set((cm.body.get("data") or {}).keys())
            if d.kind == "Job" and d.body["spec"].get("completionMode") == "Indexed":
                env_names.add("JOB_COMPLETION_INDEX")
            if is_reflectance(c):
                command = c.get("command")
                if command not in (None, [ENTRYPOINT]):
                    problem(where, f"command {command!r}: use the image's entrypoint ({ENTRYPOINT}); the image has no shell")
                args = [str(a) for a in c.get("args") or []]
                if not args:
                    problem(where, "no args: name the subcommand (serve, render, …)")
                for a in args:
                    for name in references(a):
                        if name not in env_names:
                            problem(where, f"argument {a!r}: $({name}) is not defined in the container's environment")


def container_port(c, port):
    for p in c.get("ports") or []:
        if port in (p.get("name"), p.get("containerPort")):
            return p.get("containerPort")
    return None


def env_value(c, name, default=None):
    for e in c.get("env") or []:
        if e["name"] == name and "value" in e:
            return str(e["value"])
    return default


def openapi_get_paths():
    with open(os.path.join(ROOT, "openapi.yaml"), encoding="utf-8") as f:
        api = yaml.safe_load(f)
    return {p for p, ops in (api.get("paths") or {}).items() if "get" in (ops or {})}


def check_serving(docs):
    deployments = [d for d in docs if d.kind == "Deployment"]
    if len(deployments) != 1:
        problem("serving", f"expected one Deployment, found {len(deployments)}")
        return
    dep = deployments[0]
    spec = pod_spec(dep)
    labels = pod_labels(dep)
    selector = (dep.body["spec"].get("selector") or {}).get("matchLabels") or {}

    def matches(sel):
        return bool(sel) and all(labels.get(k) == v for k, v in sel.items())

    if not matches(selector):
        problem(str(dep), f"selector {selector} does not match the pod labels {labels}")
    server = [c for c in spec.get("containers") or [] if is_reflectance(c)]
    if len(server) != 1:
        problem(str(dep), "expected one reflectance container")
        return
    c = server[0]
    if (c.get("args") or [None])[0] != "serve":
        problem(str(dep), f"the container's args must start with serve, not {c.get('args')}")
    listen = env_value(c, "REFLECTANCE_LISTEN", "0.0.0.0:8080")
    listen_port = int(listen.rsplit(":", 1)[1])
    if not any(p.get("containerPort") == listen_port for p in c.get("ports") or []):
        problem(str(dep), f"no container port is REFLECTANCE_LISTEN's port {listen_port}")
    paths = openapi_get_paths()
    expected = {"livenessProbe": "/health/live", "readinessProbe": "/health/ready"}
    for probe in ("livenessProbe", "readinessProbe", "startupProbe"):
        p = c.get(probe)
        if p is None:
            if probe in expected:
                problem(str(dep), f"no {probe}")
            continue
        get = p.get("httpGet")
        if not get:
            problem(str(dep), f"{probe}: use httpGet")
            continue
        if get.get("path") not in paths:
            problem(str(dep), f"{probe}: GET {get.get('path')} is not a route of openapi.yaml")
        if probe in expected and get.get("path") != expected[probe]:
            problem(str(dep), f"{probe}: the path is {get.get('path')}, the server's is {expected[probe]}")
        if container_port(c, get.get("port")) != listen_port:
            problem(str(dep), f"{probe}: port {get.get('port')!r} is not the served port {listen_port}")
    drain = float(env_value(c, "REFLECTANCE_DRAIN_DELAY", "0"))
    grace = float(env_value(c, "REFLECTANCE_SHUTDOWN_GRACE", "30"))
    period = spec.get("terminationGracePeriodSeconds", 30)
    if period <= drain + grace:
        problem(str(dep), f"terminationGracePeriodSeconds {period} must exceed drain delay + shutdown grace ({drain:g} + {grace:g} s)")
    if drain <= 0:
        problem(str(dep), "REFLECTANCE_DRAIN_DELAY should be a few seconds so endpoints drop the pod before it closes")

    services = [d for d in docs if d.kind == "Service"]
    if not services:
        problem("serving", "no Service")
    for s in services:
        if not matches(s.body["spec"].get("selector") or {}):
            problem(str(s), f"selector {s.body['spec'].get('selector')} does not match the Deployment's pod labels {labels}")
        for p in s.body["spec"].get("ports") or []:
            target = p.get("targetPort", p.get("port"))
            if container_port(c, target) != listen_port:
                problem(str(s), f"targetPort {target!r} is not the served port {listen_port}")

    pdbs = [d for d in docs if d.kind == "PodDisruptionBudget"]
    if not pdbs:
        problem("serving", "no PodDisruptionBudget")
    hpas = [d for d in docs if d.kind == "HorizontalPodAutoscaler"]
    if not hpas:
        problem("serving", "no HorizontalPodAutoscaler")
    for h in hpas:
        ref = h.body["spec"].get("scaleTargetRef") or {}
        if (ref.get("apiVersion"), ref.get("kind"), ref.get("name")) != ("apps/v1", "Deployment", dep.name):
            problem(str(h), f"scaleTargetRef {ref} is not the Deployment apps/v1 {dep.name}")
        minimum = h.body["spec"].get("minReplicas", 1)
        for m in h.body["spec"].get("metrics") or []:
            res = (m.get("resource") or {})
            if res.get("name") == "cpu" and (res.get("target") or {}).get("type") == "Utilization":
                for _, cc in containers(spec):
                    if not ((cc.get("resources") or {}).get("requests") or {}).get("cpu"):
                        problem(str(h), f"CPU utilization needs a CPU request on container {cc.get('name')}")
        for p in pdbs:
            ps = p.body["spec"]
            if "maxUnavailable" in ps and isinstance(ps["maxUnavailable"], int) and minimum - ps["maxUnavailable"] < 1:
                problem(str(p), f"maxUnavailable {ps['maxUnavailable']} leaves no pod at the autoscaler's minimum {minimum}")
            if "minAvailable" in ps and isinstance(ps["minAvailable"], int) and ps["minAvailable"] >= minimum:
                problem(str(p), f"minAvailable {ps['minAvailable']} blocks every eviction at the autoscaler's minimum {minimum}")
    if "replicas" in dep.body["spec"] and hpas:
        problem(str(dep), "spec.replicas is set while an autoscaler owns it (re-applying would reset the scale)")
    for p in pdbs:
        if not matches(((p.body["spec"].get("selector") or {}).get("matchLabels")) or {}):
            problem(str(p), f"selector does not match the Deployment's pod labels {labels}")
    threads = [e for e in c.get("env") or [] if e["name"] == "REFLECTANCE_CPU_THREADS"]
    for e in threads:
        ref = (e.get("valueFrom") or {}).get("resourceFieldRef")
        if ref and ref.get("resource") != "limits.cpu":
            problem(str(dep), "REFLECTANCE_CPU_THREADS should follow limits.cpu")


def training_parts(docs):
    """(render job, merge job, params dict) of the training group, or None."""
    indexed = [d for d in docs if d.kind == "Job" and d.body["spec"].get("completionMode") == "Indexed"]
    others = [d for d in docs if d.kind == "Job" and d not in indexed]
    params = {}
    for d in docs:
        if d.kind == "ConfigMap" and "SHARDS" in (d.body.get("data") or {}):
            params = {k: str(v) for k, v in d.body["data"].items()}
    return indexed, others, params


def job_env(container, params, index=None):
    env = dict(params)
    for e in container.get("env") or []:
        if "value" in e:
            env[e["name"]] = expand(str(e["value"]), env)
    if index is not None:
        env["JOB_COMPLETION_INDEX"] = str(index)
    return env


def check_training(docs):
    indexed, others, params = training_parts(docs)
    if len(indexed) != 1:
        problem("training", f"expected one Indexed Job, found {len(indexed)}")
        return
    job = indexed[0]
    if "SHARDS" not in params:
        problem("training", "no ConfigMap with SHARDS")
        return
    try:
        shards = int(params["SHARDS"])
    except ValueError:
        problem("training", f"SHARDS {params['SHARDS']!r} is not a number")
        return
    spec = job.body["spec"]
    if spec.get("completions") != shards:
        problem(str(job), f"completions {spec.get('completions')} differs from SHARDS {shards}")
    if spec.get("parallelism", 1) > spec.get("completions", 1):
        problem(str(job), "parallelism above completions")
    pod = pod_spec(job)
    if pod.get("restartPolicy") != "Never" and spec.get("podFailurePolicy"):
        problem(str(job), "podFailurePolicy needs restartPolicy Never")
    outputs = {"manifest": [], "table": []}
    for i in range(shards):
        for role, c in containers(pod):
            args = [expand(str(a), job_env(c, params, i)) for a in c.get("args") or []]
            if args[:1] == ["render"]:
                if "--shard" not in args:
                    problem(str(job), f"{c['name']}: render without --shard")
                elif args[args.index("--shard") + 1] != f"{i}/{shards}":
                    problem(str(job), f"{c['name']}: --shard is {args[args.index('--shard') + 1]!r} for index {i}, not {i}/{shards}")
            if args[:1] == ["features"]:
                outputs["manifest"].append(args[args.index("--manifest") + 1] if "--manifest" in args else None)
                outputs["table"].append(args[args.index("--out") + 1] if "--out" in args else None)
    if not outputs["table"]:
        problem(str(job), "no features container: the shards write no feature tables")
    merges = []
    for d in others:
        for role, c in containers(pod_spec(d)):
            args = [expand(str(a), job_env(c, params)) for a in c.get("args") or []]
            if args[:1] == ["merge"]:
                merges.append((d, c, args))
    if not merges:
        problem("training", "no merge Job")
    for what in ("manifest", "table"):
        parts = outputs[what]
        found = [m for m in merges if m[2][3:] and set(m[2][3:]) & set(parts)]
        if len(found) != 1:
            problem("training", f"expected one merge of the shards' partial {what}s {parts}, found {len(found)}")
            continue
        d, c, args = found[0]
        if args[1] != "--out":
            problem(str(d), f"{c['name']}: merge's arguments should be --out FILE PART…")
        if args[3:] != parts:
            problem(str(d), f"{c['name']}: merges {args[3:]}, but the {shards} shards write {parts}")


# ---------------------------------------------------------------- the server's settings


def server_env_from_source():
    names = set(EXTRA_SERVER_ENV)
    folder = os.path.join(ROOT, "src", "cli")
    if not os.path.isdir(folder):
        return None
    for name in os.listdir(folder):
        if name.endswith(".rs"):
            with open(os.path.join(folder, name), encoding="utf-8") as f:
                text = f.read()
            names |= set(re.findall(r'env\s*=\s*"(REFLECTANCE_[A-Z0-9_]+)"', text))
            names |= set(re.findall(r'env::var\("(REFLECTANCE_[A-Z0-9_]+)"\)', text))
    return names, "the env attributes of src/cli/"


def run_help(binary, *sub):
    out = subprocess.run([binary, *sub, "--help"], capture_output=True, text=True, timeout=30)
    if out.returncode != 0:
        return None
    return out.stdout


def subcommands(help_text):
    names, inside = set(), False
    for line in help_text.splitlines():
        if line.startswith("Commands:"):
            inside = True
            continue
        if inside:
            if not line.startswith("  "):
                break
            names.add(line.split()[0])
    return names


def flags(help_text):
    return set(re.findall(r"(?<![\w-])(--[a-z0-9][a-z0-9-]*)", help_text))


# ---------------------------------------------------------------- with the binary


def check_cli(docs, binary):
    top = run_help(binary)
    if top is None:
        problem(binary, "`--help` failed")
        return
    subs = subcommands(top)
    helps = {}
    for d in docs:
        spec = pod_spec(d)
        for role, c in containers(spec or {}):
            if not is_reflectance(c):
                continue
            args = [str(a) for a in c.get("args") or []]
            if not args:
                continue
            where = f"{d} {role} {c.get('name')}"
            if args[0] not in subs:
                problem(where, f"`reflectance {args[0]}` is not a subcommand of this binary (it has: {', '.join(sorted(subs))})")
                continue
            if args[0] not in helps:
                helps[args[0]] = flags(run_help(binary, args[0]) or "")
            for a in args[1:]:
                flag = a.split("=", 1)[0]
                if flag.startswith("--") and flag not in helps[args[0]]:
                    problem(where, f"`reflectance {args[0]}` has no flag {flag}")


def write_hdr(path, width, height, radiance):
    """A flat (uncompressed) Radiance RGBE light probe."""
    out = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {height} +X {width}\n".encode())
    for y in range(height):
        for x in range(width):
            v = radiance(x / width, y / height)
            if v < 1e-32:
                out += bytes(4)
                continue
            e = math.frexp(v)[1]
            m = int(v * 256.0 / 2.0**e)
            out += bytes([m, m, m, e + 128])
    with open(path, "wb") as f:
        f.write(out)


def csv_rows(path):
    with open(path, encoding="utf-8") as f:
        lines = f.read().splitlines()
    return lines[0], lines[1:]


def simulate_training(docs, root, binary):
    """Run the Indexed Job's pods (all indexes at once, each its containers in order), then
    the merge Job, with the pods' mount paths mapped into a temporary folder; compare the
    merged files with an unsharded run of the same render and features commands."""
    indexed, others, params = training_parts(docs)
    if len(indexed) != 1 or "SHARDS" not in params:
        return
    job = indexed[0]
    shards = int(params["SHARDS"])
    before = len(problems)
    configmaps = {d.name: d for d in docs if d.kind == "ConfigMap" and group_of(d, root) == group_of(job, root)}
    with tempfile.TemporaryDirectory(prefix="check_manifests.") as tmp:
        def mounts_of(pod):
            """mountPath → host folder for the pod's volumes."""
            table = {}
            volumes = {v["name"]: v for v in pod.get("volumes") or []}
            for _, c in containers(pod):
                for m in c.get("volumeMounts") or []:
                    v = volumes.get(m["name"], {})
                    host = os.path.join(tmp, "volumes", m["name"])
                    if not os.path.isdir(host):
                        os.makedirs(host)
                        if "configMap" in v:
                            cm = configmaps.get(v["configMap"]["name"])
                            for key, text in ((cm.body.get("data") if cm else None) or {}).items():
                                with open(os.path.join(host, key), "w", encoding="utf-8") as f:
                                    f.write(text)
                    table[m["mountPath"].rstrip("/")] = host
            return table

        def host_path(arg, table):
            for mount, host in sorted(table.items(), key=lambda kv: -len(kv[0])):
                if arg == mount or arg.startswith(mount + "/"):
                    return host + arg[len(mount):]
            return arg

        sim_params = dict(params, SIZE=SIM_SIZE)

        def run(job_doc, c, index, table, label):
            env = job_env(c, sim_params, index)
            args = [host_path(expand(str(a), env), table) for a in c.get("args") or []]
            out = subprocess.run([binary, *args], capture_output=True, text=True, timeout=300,
                                 env={"PATH": os.environ.get("PATH", "/usr/bin:/bin")})
            if out.returncode != 0:
                hint = ""
                if "--manifest" in args and not os.path.exists(args[args.index("--manifest") + 1]):
                    folder = os.path.dirname(args[args.index("--manifest") + 1])
                    csvs = sorted(n for n in os.listdir(folder) if n.endswith(".csv")) if os.path.isdir(folder) else []
                    hint = f" (the CSV files in that folder: {csvs})"
                problem(f"{job_doc} {c.get('name')} ({label})",
                        f"`reflectance {' '.join(args)}` exited {out.returncode}: {out.stderr.strip()[-500:]}{hint}")
                return None
            return args

        pod = pod_spec(job)
        table = mounts_of(pod)
        # The light probes the user copies to the volume: two small synthetic ones.
        for role, c in containers(pod):
            args = [host_path(expand(str(a), job_env(c, sim_params, 0)), table) for a in c.get("args") or []]
            if args[:1] == ["render"] and "--probes" in args:
                probes = args[args.index("--probes") + 1]
                os.makedirs(probes, exist_ok=True)
                write_hdr(os.path.join(probes, "sky.hdr"), 64, 32,
                          lambda u, v: 0.2 + 3 * max(0.0, math.cos(6.283 * u)) * (1 - v))
                write_hdr(os.path.join(probes, "lamp.hdr"), 64, 32,
                          lambda u, v: 50.0 if abs(u - 0.3) < 0.04 and abs(v - 0.3) < 0.06 else 0.1 + 0.3 * v)

        def index_pod(i):
            """One pod of the Indexed Job: its init containers, then its containers."""
            done = []
            for role, c in containers(pod):
                args = run(job, c, i, table, f"index {i}")
                if args is None:
                    return None
                done.append(args)
            return done

        # All indexes at once, as with parallelism = completions, into the same folder.
        with concurrent.futures.ThreadPoolExecutor(max_workers=shards) as pool:
            pods = list(pool.map(index_pod, range(shards)))
        if any(p is None for p in pods):
            return
        produced = [args for p in pods for args in p]
        merged = {}
        for d in others:
            mpod = pod_spec(d)
            mtable = mounts_of(mpod)
            for role, c in containers(mpod):
                args = run(d, c, None, mtable, "merge")
                if args is None:
                    return
                merged[args[args.index("--out") + 1]] = args
        # The same data set unsharded, in a folder of its own.
        render = next(a for a in produced if a[0] == "render")
        whole = os.path.join(tmp, "whole")
        ref = [binary] + render[:render.index("--out") + 1] + [whole] + [
            a for j, a in enumerate(render) if j > render.index("--out") + 1
        ]
        cut = ref.index("--shard")
        ref = ref[:cut] + ref[cut + 2:]
        for cmd in (ref, [binary, "features", "--manifest", os.path.join(whole, "manifest.csv"),
                          "--out", os.path.join(whole, "features.csv")]):
            out = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
            if out.returncode != 0:
                problem("training simulation", f"the unsharded reference `{' '.join(cmd[1:])}` failed: {out.stderr.strip()[-300:]}")
                return
        unsharded = {kind: csv_rows(os.path.join(whole, kind)) for kind in ("manifest.csv", "features.csv")}
        for path, args in merged.items():
            head, rows = csv_rows(path)
            kind = next((k for k, (h, _) in unsharded.items() if h == head), None)
            if kind is None:
                problem("training simulation", f"{os.path.basename(path)} (merged) has the columns of neither "
                        f"the manifest nor the feature table: {head[:80]}")
                continue
            ref_rows = unsharded[kind][1]
            if sorted(rows) != sorted(ref_rows):
                problem("training simulation", f"{os.path.basename(path)} (merged) holds {len(rows)} rows, the unsharded "
                        f"{kind} {len(ref_rows)}, and they differ")
            # Deterministic: the parts in another order give the same bytes.
            again = path + ".again"
            out = subprocess.run([binary, "merge", "--out", again, *reversed(args[3:])], capture_output=True, text=True)
            if out.returncode != 0 or open(again, "rb").read() != open(path, "rb").read():
                problem("training simulation", f"merging the parts of {os.path.basename(path)} in reverse order gives another file")
        if len(problems) == before:
            print(f"check_manifests: training Jobs run offline: {shards} shards and the merge, "
                  f"{len(unsharded['manifest.csv'][1])} images at {SIM_SIZE} px, same rows as unsharded")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def image_copies():
    """{path in the image: repository folder} for the Dockerfile's plain COPY lines."""
    copies = {}
    try:
        with open(os.path.join(ROOT, "Dockerfile"), encoding="utf-8") as f:
            for line in f:
                m = re.match(r"^COPY\s+([^-\s]\S*)\s+(/\S+)\s*$", line.strip())
                if m:
                    copies[m.group(2).rstrip("/")] = os.path.join(ROOT, m.group(1))
    except OSError:
        pass
    return copies


def simulate_serving(docs, binary):
    deps = [d for d in docs if d.kind == "Deployment"]
    if len(deps) != 1:
        return
    dep = deps[0]
    c = next((c for c in pod_spec(dep).get("containers") or [] if is_reflectance(c)), None)
    if c is None:
        return
    env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin")}
    limits = (c.get("resources") or {}).get("limits") or {}
    for e in c.get("env") or []:
        if "value" in e:
            env[e["name"]] = expand(str(e["value"]), env)
        ref = (e.get("valueFrom") or {}).get("resourceFieldRef")
        if ref:
            value = quantity(limits.get(ref["resource"].split(".", 1)[1], "1")) / quantity(ref.get("divisor", "1"))
            env[e["name"]] = str(math.ceil(value))
    # The image's models are the repository's (Dockerfile: COPY models /srv/models).
    models = env.get("REFLECTANCE_MODELS", "models").rstrip("/")
    if models in image_copies():
        env["REFLECTANCE_MODELS"] = image_copies()[models]
    elif models.startswith("/"):
        print(f"check_manifests: REFLECTANCE_MODELS={models} is not in the image; the local run uses models/",
              file=sys.stderr)
        env["REFLECTANCE_MODELS"] = os.path.join(ROOT, "models")
    port = free_port()
    served = int(env.get("REFLECTANCE_LISTEN", "0.0.0.0:8080").rsplit(":", 1)[1])
    env["REFLECTANCE_LISTEN"] = f"127.0.0.1:{port}"
    env["REFLECTANCE_DRAIN_DELAY"] = "0"
    args = [str(a) for a in c.get("args") or []]
    with tempfile.TemporaryDirectory(prefix="check_manifests.") as tmp:
        log = open(os.path.join(tmp, "server.log"), "w+")
        server = subprocess.Popen([binary, *args], env=env, stdout=log, stderr=log, cwd=tmp)
        try:
            probes = {k: c[k]["httpGet"] for k in ("startupProbe", "livenessProbe", "readinessProbe") if k in c}
            deadline = time.time() + 30
            status = {}
            while time.time() < deadline and server.poll() is None:
                for name, get in probes.items():
                    try:
                        with urllib.request.urlopen(f"http://127.0.0.1:{port}{get['path']}", timeout=2) as r:
                            status[name] = r.status
                    except urllib.error.HTTPError as e:
                        status[name] = e.code
                    except OSError:
                        status[name] = None
                if all(s == 200 for s in status.values()) and len(status) == len(probes):
                    break
                time.sleep(0.1)
            if server.poll() is not None:
                log.seek(0)
                problem(str(dep), f"the server exited ({server.returncode}) with the Deployment's environment: {log.read()[-500:]}")
            elif not all(s == 200 for s in status.values()):
                problem(str(dep), f"probes did not all answer 200 within 30 s: {status}")
            else:
                print(f"check_manifests: the Deployment's container serves (its port {served} moved to {port}); "
                      + ", ".join(f"{k} GET {g['path']} 200" for k, g in probes.items()))
        finally:
            if server.poll() is None:
                server.send_signal(signal.SIGTERM)
                try:
                    server.wait(timeout=40)
                except subprocess.TimeoutExpired:
                    server.kill()
                    server.wait()
            log.close()


# ---------------------------------------------------------------- main


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "deploy", "kubernetes"))
    docs, kustomizations = load(root)
    if not docs:
        sys.exit(f"check_manifests: no manifests under {rel(root)}")
    binary = os.environ.get("REFLECTANCE_BIN")
    if binary:
        binary = os.path.abspath(binary)
        if not os.access(binary, os.X_OK):
            sys.exit(f"check_manifests: REFLECTANCE_BIN={binary} is not an executable")
    server_env = None
    if binary:
        text = run_help(binary, "serve")
        if text is not None:
            server_env = (set(re.findall(r"\[env: (REFLECTANCE_[A-Z0-9_]+)=", text)) | EXTRA_SERVER_ENV,
                          "`reflectance serve --help`")
    if server_env is None:
        server_env = server_env_from_source()

    check_kustomizations(kustomizations, docs)
    check_unique(docs, root)
    check_pods(docs, root, server_env)
    groups = {}
    for d in docs:
        groups.setdefault(group_of(d, root), []).append(d)
    check_serving(groups.get("serving", []))
    check_training(groups.get("training", []))
    static = len(problems)
    if binary and not static:
        check_cli(docs, binary)
        if not problems:
            simulate_serving(groups.get("serving", []), binary)
            simulate_training(groups.get("training", []), root, binary)
    elif binary:
        print("check_manifests: the runs with the binary are skipped until the checks above pass", file=sys.stderr)
    else:
        print("check_manifests: REFLECTANCE_BIN is not set: the subcommands and flags of the containers, "
              "and the offline runs of the Jobs and the server, are not checked", file=sys.stderr)

    for p in problems:
        print(f"check_manifests: {p}", file=sys.stderr)
    n = len(docs) + len(kustomizations)
    if problems:
        print(f"check_manifests: {len(problems)} problem(s) in {n} documents under {rel(root)}", file=sys.stderr)
        return 1
    print(f"check_manifests: {n} documents under {rel(root)}: consistent")
    return 0


if __name__ == "__main__":
    sys.exit(main())
