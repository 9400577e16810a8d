#!/usr/bin/env python3
"""Checks of the deployment files in deploy/ (run by ctest, tests/deploy).

    check_deploy.py KIND --source DIR [--coordinator BIN --worker BIN --cli BIN]

KIND is one of systemd, compose, k8s, dockerfile, sbatch. Every flag that a
deployment file passes to totalgrad-coordinator, totalgrad-worker or totalgrad
is checked against the real binary's --help, so a renamed flag breaks the test
and not a user's cluster. Exit 0: passed; 1: failed (every problem printed);
77: skipped (the reason printed).
"""
import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile

SKIP = 77
PROBLEMS = []


def problem(message):
    PROBLEMS.append(message)
    print("FAIL: " + message)


def note(message):
    print("ok: " + message)


def load_yaml_documents(path):
    try:
        import yaml  # python3-yaml (deploy/install-deps.sh)
    except ImportError:
        print("python3-yaml is missing: run deploy/install-deps.sh")
        sys.exit(1)
    with open(path, encoding="utf-8") as f:
        try:
            return [d for d in yaml.safe_load_all(f) if d is not None]
        except yaml.YAMLError as error:
            problem(f"{path}: not valid YAML: {error}")
            return []


def yamllint(paths):
    if not shutil.which("yamllint"):
        print("note: yamllint not installed; YAML syntax checked by python3-yaml only")
        return
    config = ("{extends: default, rules: {line-length: {max: 120}, document-start: disable, "
              "truthy: {check-keys: false}, comments: {min-spaces-from-content: 1}}}")
    result = subprocess.run(["yamllint", "-f", "parsable", "-d", config] + paths,
                            capture_output=True, text=True)
    if result.returncode != 0 or result.stdout.strip():
        problem("yamllint:\n" + result.stdout + result.stderr)
    else:
        note("yamllint: " + ", ".join(os.path.basename(p) for p in paths))


# ---- flags of the real binaries ------------------------------------------------

_help_cache = {}


def flags_of(argv):
    """The long options the program's --help lists (None without the binary)."""
    key = tuple(argv)
    if key not in _help_cache:
        if not argv[0] or not os.access(argv[0], os.X_OK):
            _help_cache[key] = None
        else:
            out = subprocess.run(argv + ["--help"], capture_output=True, text=True).stdout
            _help_cache[key] = set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", out))
    return _help_cache[key]


def check_flags(where, program_argv, words):
    """Every --flag in `words` must be an option of the program."""
    known = flags_of(program_argv)
    if known is None:
        print(f"note: {where}: no binary given, flags not checked")
        return
    used = []
    for word in words:
        match = re.match(r"^(--[a-z][a-z0-9-]*)(=.*)?$", word)
        if match:
            used.append(match.group(1))
    unknown = sorted(set(used) - known)
    if unknown:
        problem(f"{where}: flags unknown to {os.path.basename(program_argv[0])}: {unknown}")
    elif used:
        note(f"{where}: {len(set(used))} flags known to {' '.join(os.path.basename(a) for a in program_argv)}")


def program_for(words, args):
    """Maps a command line to the binary (and subcommand) whose flags it uses."""
    if not words:
        return None
    name = os.path.basename(words[0])
    if name == "totalgrad-coordinator":
        return [args.coordinator]
    if name == "totalgrad-worker":
        return [args.worker]
    if name == "totalgrad":
        sub = [w for w in words[1:] if not w.startswith("-")][:2]
        return [args.cli] + sub
    return None


def flag_value(words, flag):
    for i, word in enumerate(words):
        if word == flag and i + 1 < len(words):
            return words[i + 1]
        if word.startswith(flag + "="):
            return word.split("=", 1)[1]
    return None


def duration_seconds(text):
    match = re.fullmatch(r"\s*(\d+)\s*(s|m|min)?\s*", str(text))
    if not match:
        return None
    value = int(match.group(1))
    return value * 60 if match.group(2) in ("m", "min") else value


# ---- systemd ---------------------------------------------------------------------

def parse_unit(path):
    """Sections -> list of (key, value); continuation lines joined."""
    sections, current, pending = {}, None, ""
    with open(path, encoding="utf-8") as f:
        for raw in f:
            line = raw.rstrip("\n")
            if pending:
                line = pending + " " + line.strip()
                pending = ""
            if line.endswith("\\"):
                pending = line[:-1].rstrip()
                continue
            stripped = line.strip()
            if not stripped or stripped.startswith(("#", ";")):
                continue
            if stripped.startswith("[") and stripped.endswith("]"):
                current = stripped[1:-1]
                sections.setdefault(current, [])
                continue
            key, _, value = stripped.partition("=")
            sections.setdefault(current, []).append((key.strip(), value.strip()))
    return sections


def unit_get(sections, section, key):
    return [v for k, v in sections.get(section, []) if k == key]


def check_systemd(args):
    unit_dir = os.path.join(args.source, "deploy", "systemd")
    units = sorted(os.path.join(unit_dir, f) for f in os.listdir(unit_dir) if f.endswith(".service"))
    names = [os.path.basename(u) for u in units]
    for required in ("totalgrad-coordinator.service", "totalgrad-worker.service"):
        if required not in names:
            problem(f"deploy/systemd/{required} is missing")

    for unit in units:
        name = os.path.basename(unit)
        s = parse_unit(unit)
        service = dict(s.get("Service", []))
        for key, expected in (("Restart", "on-failure"), ("KillSignal", "SIGTERM")):
            if service.get(key) != expected:
                problem(f"{name}: {key}={service.get(key)} (expected {expected})")
        if not unit_get(s, "Install", "WantedBy"):
            problem(f"{name}: no [Install] WantedBy=")
        credentials = unit_get(s, "Service", "LoadCredential")
        if not any(c.endswith(".token") for c in credentials):
            problem(f"{name}: tokens are not passed with LoadCredential= (0600 files)")
        exec_start = unit_get(s, "Service", "ExecStart")
        if len(exec_start) != 1:
            problem(f"{name}: expected one ExecStart=, found {len(exec_start)}")
            continue
        words = shlex.split(exec_start[0])
        program = program_for(words, args)
        if program is None:
            problem(f"{name}: ExecStart runs {words[0]}, not a totalgrad binary")
            continue
        check_flags(f"{name} ExecStart", program, words)
        for credential in credentials:
            ident = credential.split(":", 1)[0]
            if f"%d/{ident}" not in exec_start[0]:
                problem(f"{name}: credential {ident} is loaded but not used in ExecStart")
        if "coordinator" in name:
            if not unit_get(s, "Service", "StateDirectory"):
                problem(f"{name}: no StateDirectory= for the SQLite file")
            db = flag_value(words, "--db") or ""
            if not db.startswith("%S/"):
                problem(f"{name}: --db {db} is not inside the state directory (%S/...)")
        if "worker" in name:
            if "OPENBLAS_NUM_THREADS=1" not in unit_get(s, "Service", "Environment"):
                problem(f"{name}: Environment=OPENBLAS_NUM_THREADS=1 missing (one BLAS thread per trial)")
            drain = duration_seconds(flag_value(words, "--drain-timeout") or "60")
            stop = duration_seconds(service.get("TimeoutStopSec", "90"))
            if drain is None or stop is None or stop <= drain + 15:
                problem(f"{name}: TimeoutStopSec={service.get('TimeoutStopSec')} leaves no room "
                        f"after --drain-timeout {drain} for the final reports")
            else:
                note(f"{name}: stop timeout {stop} s > drain timeout {drain} s + reports")

    analyze = shutil.which("systemd-analyze")
    if not analyze:
        print("SKIP: systemd-analyze is not installed (deploy/install-deps.sh installs systemd); "
              "the units were parsed and checked above")
        return SKIP if not PROBLEMS else 1
    # verify checks that ExecStart's binary exists: point it at the built ones.
    with tempfile.TemporaryDirectory() as tmp:
        copies = []
        for unit in units:
            text = open(unit, encoding="utf-8").read()
            for binary in (args.coordinator, args.worker, args.cli):
                if binary:
                    text = text.replace("/usr/local/bin/" + os.path.basename(binary), binary)
            copy = os.path.join(tmp, os.path.basename(unit))
            with open(copy, "w", encoding="utf-8") as f:
                f.write(text)
            copies.append(copy)
        result = subprocess.run([analyze, "verify"] + copies, capture_output=True, text=True)
        output = (result.stdout + result.stderr).strip()
        if result.returncode != 0 or output:
            if "Failed to" in output and ("bus" in output.lower() or "connect" in output.lower()):
                print("SKIP: systemd-analyze verify cannot run in this sandbox:\n" + output)
                return SKIP if not PROBLEMS else 1
            problem("systemd-analyze verify:\n" + output)
        else:
            note("systemd-analyze verify: " + ", ".join(names) + " (no warnings)")
    return 1 if PROBLEMS else 0


# ---- Kubernetes ------------------------------------------------------------------

def containers_of(pod_spec):
    return list(pod_spec.get("initContainers", [])) + list(pod_spec.get("containers", []))


def check_pod_template(where, workload, doc_names, secrets, args):
    spec = workload.get("spec", {})
    selector = (spec.get("selector") or {}).get("matchLabels") or {}
    template = spec.get("template") or {}
    labels = (template.get("metadata") or {}).get("labels") or {}
    if not selector:
        problem(f"{where}: spec.selector.matchLabels is required")
    for key, value in selector.items():
        if labels.get(key) != value:
            problem(f"{where}: selector {key}={value} does not match the pod template labels")
    pod = template.get("spec") or {}
    if not pod.get("containers"):
        problem(f"{where}: spec.template.spec.containers is required")
        return pod
    volumes = {v.get("name"): v for v in pod.get("volumes", [])}
    claim_names = {c.get("metadata", {}).get("name") for c in spec.get("volumeClaimTemplates", [])}
    for volume in volumes.values():
        secret = volume.get("secret")
        if secret and secret.get("secretName") not in secrets:
            problem(f"{where}: volume {volume['name']} uses secret {secret.get('secretName')}, "
                    f"which nothing defines")
    ctx = pod.get("securityContext") or {}
    if not ctx.get("runAsNonRoot"):
        problem(f"{where}: pods should set securityContext.runAsNonRoot")
    for container in containers_of(pod):
        cname = container.get("name")
        if not cname or not container.get("image"):
            problem(f"{where}: every container needs name and image")
            continue
        for mount in container.get("volumeMounts", []):
            if mount.get("name") not in volumes and mount.get("name") not in claim_names:
                problem(f"{where}/{cname}: volumeMount {mount.get('name')} has no volume")
            if not str(mount.get("mountPath", "")).startswith("/"):
                problem(f"{where}/{cname}: mountPath must be absolute")
        port_names = {p.get("name") for p in container.get("ports", [])}
        for probe_name in ("startupProbe", "livenessProbe", "readinessProbe"):
            probe = container.get(probe_name)
            if not probe:
                continue
            kinds = [k for k in ("exec", "httpGet", "tcpSocket", "grpc") if k in probe]
            if len(kinds) != 1:
                problem(f"{where}/{cname}: {probe_name} needs exactly one handler")
                continue
            handler = probe[kinds[0]]
            port = handler.get("port") if isinstance(handler, dict) else None
            if isinstance(port, str) and port not in port_names:
                problem(f"{where}/{cname}: {probe_name} names port {port}, which is not declared")
            if kinds[0] == "exec":
                command = handler.get("command") or []
                program = program_for(command, args)
                if program:
                    check_flags(f"{where}/{cname} {probe_name}", program, command)
        words = list(container.get("command", [])) + list(container.get("args", []))
        program = program_for(words, args)
        if program:
            check_flags(f"{where}/{cname}", program, words)
        for env in container.get("env", []):
            if "name" not in env:
                problem(f"{where}/{cname}: env entry without name")
    return pod


def check_k8s(args):
    k8s = os.path.join(args.source, "deploy", "k8s")
    kustomization_path = os.path.join(k8s, "kustomization.yaml")
    kustomization = (load_yaml_documents(kustomization_path) or [{}])[0]
    files = [os.path.join(k8s, r) for r in kustomization.get("resources", [])]
    for f in files:
        if not os.path.exists(f):
            problem(f"kustomization.yaml: resource {f} does not exist")
    files = [f for f in files if os.path.exists(f)]
    yamllint([kustomization_path] + files)

    # Secrets come from the kustomization's generator; their source files are
    # what deploy/make-dev-certs.sh writes.
    cert_outputs = {"ca.pem", "server.pem", "server.key", "client.pem", "client.key",
                    "worker.token", "user.token"}
    secrets = {}
    for generator in kustomization.get("secretGenerator", []):
        keys = set()
        for entry in generator.get("files", []):
            key, _, source = entry.partition("=")
            source = source or key
            keys.add(key if "=" in entry else os.path.basename(source))
            if os.path.dirname(source) != "secrets" or os.path.basename(source) not in cert_outputs:
                problem(f"secretGenerator {generator.get('name')}: {source} is not a "
                        f"make-dev-certs.sh output in deploy/k8s/secrets/")
        if generator.get("type") == "kubernetes.io/tls" and not {"tls.crt", "tls.key"} <= keys:
            problem(f"secret {generator.get('name')}: type kubernetes.io/tls needs tls.crt and tls.key")
        secrets[generator.get("name")] = keys
    for wanted in ("token", "tls"):
        if not any(wanted in name for name in secrets):
            problem(f"no Secret for {wanted}s in kustomization.yaml")

    docs = []
    for f in files:
        for doc in load_yaml_documents(f):
            docs.append((os.path.basename(f), doc))
    by_kind = {}
    for fname, doc in docs:
        for field in ("apiVersion", "kind"):
            if field not in doc:
                problem(f"{fname}: a document lacks {field}")
        name = (doc.get("metadata") or {}).get("name")
        if not name:
            problem(f"{fname}: {doc.get('kind')} lacks metadata.name")
        by_kind.setdefault(doc.get("kind"), []).append(doc)

    expected_api = {"Namespace": "v1", "Service": "v1", "StatefulSet": "apps/v1",
                    "Deployment": "apps/v1"}
    for kind, api in expected_api.items():
        if kind not in by_kind:
            problem(f"no {kind} in the manifests")
        for doc in by_kind.get(kind, []):
            if doc.get("apiVersion") != api:
                problem(f"{kind} {doc['metadata']['name']}: apiVersion {doc.get('apiVersion')} "
                        f"(expected {api})")

    services = {d["metadata"]["name"]: d for d in by_kind.get("Service", [])}
    for name, service in services.items():
        ports = (service.get("spec") or {}).get("ports") or []
        if not ports or any("port" not in p for p in ports):
            problem(f"Service {name}: spec.ports[].port is required")

    for sts in by_kind.get("StatefulSet", []):
        where = f"StatefulSet {sts['metadata']['name']}"
        spec = sts.get("spec", {})
        if spec.get("replicas") != 1:
            problem(f"{where}: the coordinator must have exactly one replica (owns the SQLite file)")
        if spec.get("serviceName") not in services:
            problem(f"{where}: serviceName {spec.get('serviceName')} is not a Service here")
        claims = spec.get("volumeClaimTemplates") or []
        if not claims:
            problem(f"{where}: no volumeClaimTemplates (persistent volume for the database)")
        for claim in claims:
            cspec = claim.get("spec", {})
            if not cspec.get("accessModes") or not (cspec.get("resources") or {}).get("requests", {}).get("storage"):
                problem(f"{where}: claim {claim.get('metadata', {}).get('name')} needs accessModes "
                        f"and resources.requests.storage")
        pod = check_pod_template(where, sts, docs, secrets, args)
        coordinator = [c for c in pod.get("containers", []) if
                       program_for(list(c.get("command", [])) + list(c.get("args", [])), args) == [args.coordinator]]
        if not coordinator:
            problem(f"{where}: no container runs totalgrad-coordinator")
        for c in coordinator:
            words = list(c.get("command", [])) + list(c.get("args", []))
            db = flag_value(words, "--db") or ""
            mounts = [m["mountPath"] for m in c.get("volumeMounts", [])
                      if m.get("name") in {cl["metadata"]["name"] for cl in claims}]
            if not any(db.startswith(m.rstrip("/") + "/") for m in mounts):
                problem(f"{where}: --db {db} is not on the persistent volume ({mounts})")
            if not c.get("readinessProbe") or not c.get("livenessProbe"):
                problem(f"{where}: the coordinator needs readiness and liveness probes")
            if "--insecure" in words:
                problem(f"{where}: --insecure off loopback")
        # Every Service selects some pod.
        labels = (sts.get("spec", {}).get("template", {}).get("metadata", {}) or {}).get("labels", {})
        selected = services.get(spec.get("serviceName"), {}).get("spec", {}).get("selector", {})
        if any(labels.get(k) != v for k, v in selected.items()):
            problem(f"{where}: its Service's selector does not select its pods")

    for deployment in by_kind.get("Deployment", []):
        where = f"Deployment {deployment['metadata']['name']}"
        pod = check_pod_template(where, deployment, docs, secrets, args)
        grace = pod.get("terminationGracePeriodSeconds", 30)
        for c in pod.get("containers", []):
            words = list(c.get("command", [])) + list(c.get("args", []))
            if program_for(words, args) != [args.worker]:
                continue
            drain = duration_seconds(flag_value(words, "--drain-timeout") or "60")
            if drain is None or grace <= drain + 15:
                problem(f"{where}: terminationGracePeriodSeconds {grace} must exceed "
                        f"--drain-timeout {drain} plus time for the final reports")
            else:
                note(f"{where}: grace period {grace} s > drain timeout {drain} s + reports")
            target = flag_value(words, "--coordinator") or ""
            if target.split(":")[0] not in services:
                problem(f"{where}: --coordinator {target} is not a Service here")
            if "--insecure" in words:
                problem(f"{where}: --insecure off loopback")
            if not flag_value(words, "--ca-cert") or not flag_value(words, "--token-file"):
                problem(f"{where}: workers need --ca-cert and --token-file")
            env = {e.get("name"): e.get("value") for e in c.get("env", [])}
            if env.get("OPENBLAS_NUM_THREADS") != "1":
                problem(f"{where}: env OPENBLAS_NUM_THREADS=1 missing (one BLAS thread per trial)")

    images = {c.get("image") for _, d in docs if d.get("kind") in ("StatefulSet", "Deployment")
              for c in containers_of(d["spec"]["template"]["spec"])}
    tags = {i.split(":")[-1] for i in images}
    kimages = {i.get("name"): i for i in kustomization.get("images", [])}
    if len(images) != 1:
        problem(f"every pod should run the one totalgrad image; found {sorted(images)}")
    elif "totalgrad" in kimages and kimages["totalgrad"].get("newTag") not in tags:
        problem("kustomization images.newTag differs from the manifests' tag")

    # Optional: render with kustomize (kubectl kustomize needs no cluster).
    kubectl = shutil.which("kubectl")
    if kubectl:
        with tempfile.TemporaryDirectory() as tmp:
            copy = os.path.join(tmp, "k8s")
            shutil.copytree(k8s, copy, ignore=shutil.ignore_patterns("secrets"))
            os.makedirs(os.path.join(copy, "secrets"))
            for name in cert_outputs:
                with open(os.path.join(copy, "secrets", name), "w") as f:
                    f.write("placeholder\n")
            result = subprocess.run([kubectl, "kustomize", copy], capture_output=True, text=True,
                                    timeout=120)
            if result.returncode != 0:
                problem("kubectl kustomize deploy/k8s:\n" + result.stderr)
            else:
                kinds = re.findall(r"^kind: (\w+)$", result.stdout, re.M)
                note(f"kubectl kustomize renders {len(kinds)} objects: {', '.join(sorted(kinds))}")
    else:
        print("note: kubectl not installed; kustomization rendered by this script's checks only")
    return 1 if PROBLEMS else 0


# ---- compose ----------------------------------------------------------------------

def check_compose(args):
    path = os.path.join(args.source, "deploy", "docker", "compose.yaml")
    yamllint([path])
    docs = load_yaml_documents(path)
    if len(docs) != 1 or not isinstance(docs[0], dict):
        problem("compose.yaml: expected one mapping")
        return 1
    compose = docs[0]
    services = compose.get("services") or {}
    volumes = compose.get("volumes") or {}
    for required in ("coordinator", "worker"):
        if required not in services:
            problem(f"compose.yaml: no service {required}")
    compose_dir = os.path.dirname(path)
    for name, service in services.items():
        if not isinstance(service, dict):
            problem(f"service {name}: not a mapping")
            continue
        if "image" not in service and "build" not in service:
            problem(f"service {name}: needs image or build")
        build = service.get("build")
        if isinstance(build, dict):
            context = os.path.normpath(os.path.join(compose_dir, build.get("context", ".")))
            dockerfile = os.path.join(context, build.get("dockerfile", "Dockerfile"))
            if not os.path.isfile(dockerfile):
                problem(f"service {name}: build.dockerfile {dockerfile} does not exist")
            if os.path.realpath(context) != os.path.realpath(args.source):
                problem(f"service {name}: build context {context} is not the repository root")
        for volume in service.get("volumes", []):
            source = str(volume).split(":")[0]
            if not source.startswith((".", "/")) and source not in volumes:
                problem(f"service {name}: volume {source} is not declared under volumes:")
        depends = service.get("depends_on") or {}
        for dependency in (depends if isinstance(depends, (list, dict)) else []):
            if dependency not in services:
                problem(f"service {name}: depends_on unknown service {dependency}")
        command = service.get("command")
        if isinstance(command, list):
            program = program_for([str(w) for w in command], args)
            if program:
                check_flags(f"compose {name}", program, [str(w) for w in command])
        health = (service.get("healthcheck") or {}).get("test")
        if isinstance(health, list) and health[:1] == ["CMD"]:
            program = program_for(health[1:], args)
            if program:
                check_flags(f"compose {name} healthcheck", program, health[1:])
    coordinator = services.get("coordinator", {})
    words = [str(w) for w in coordinator.get("command", [])]
    db = flag_value(words, "--db") or ""
    mounts = [str(v).split(":") for v in coordinator.get("volumes", [])]
    if not any(m[0] in volumes and db.startswith(m[1].rstrip("/") + "/") for m in mounts if len(m) >= 2):
        problem(f"coordinator: --db {db} is not on a named volume")
    if "--insecure" in words:
        problem("coordinator: --insecure off loopback")
    worker = services.get("worker", {})
    words = [str(w) for w in worker.get("command", [])]
    drain = duration_seconds(flag_value(words, "--drain-timeout") or "60")
    grace = duration_seconds(str(worker.get("stop_grace_period", "10s")).rstrip("s") or "10")
    if drain is None or grace is None or grace <= drain + 15:
        problem(f"worker: stop_grace_period {worker.get('stop_grace_period')} must exceed "
                f"--drain-timeout {drain} plus time for the final reports")
    else:
        note(f"worker: stop grace {grace} s > drain timeout {drain} s + reports")
    if "--insecure" in words or not flag_value(words, "--ca-cert"):
        problem("worker: must use TLS (--ca-cert), never --insecure")
    environment = worker.get("environment") or {}
    if isinstance(environment, list):
        environment = dict(str(e).split("=", 1) for e in environment)
    if str(environment.get("OPENBLAS_NUM_THREADS")) != "1":
        problem("worker: environment OPENBLAS_NUM_THREADS=1 missing (one BLAS thread per trial)")
    replicas = (worker.get("deploy") or {}).get("replicas")
    if not isinstance(replicas, int) or replicas < 1:
        problem("worker: deploy.replicas (N workers) is missing")
    return 1 if PROBLEMS else 0


# ---- Dockerfile ------------------------------------------------------------------

def dockerfile_instructions(path):
    lines, current = [], ""
    with open(path, encoding="utf-8") as f:
        for raw in f:
            line = raw.rstrip("\n")
            if not current and (not line.strip() or line.lstrip().startswith("#")):
                continue
            if line.endswith("\\"):
                current += line[:-1] + " "
                continue
            current += line
            instruction, _, rest = current.strip().partition(" ")
            lines.append((instruction.upper(), rest.strip()))
            current = ""
    return lines


def check_dockerfile(args):
    path = os.path.join(args.source, "deploy", "docker", "Dockerfile")
    instructions = dockerfile_instructions(path)
    known = {"FROM", "RUN", "COPY", "ARG", "ENV", "WORKDIR", "USER", "VOLUME", "EXPOSE", "CMD",
             "ENTRYPOINT", "LABEL", "HEALTHCHECK", "STOPSIGNAL", "SHELL", "ONBUILD", "ADD"}
    for instruction, _ in instructions:
        if instruction not in known:
            problem(f"Dockerfile: unknown instruction {instruction}")
    stages = []
    for instruction, rest in instructions:
        if instruction == "FROM":
            stages.append({"from": rest, "lines": []})
        elif stages:
            stages[-1]["lines"].append((instruction, rest))
        elif instruction != "ARG":
            problem(f"Dockerfile: {instruction} before the first FROM")
    if len(stages) < 2:
        problem("Dockerfile: expected a build stage and a runtime stage")
        return 1
    build, runtime = stages[0], stages[-1]
    if not re.fullmatch(r"debian:12 AS build", build["from"], re.I):
        problem(f"Dockerfile: build stage is FROM {build['from']} (expected debian:12 AS build)")
    if not re.match(r"debian:12(-slim)?( |$)", runtime["from"]):
        problem(f"Dockerfile: runtime stage is FROM {runtime['from']} (expected debian:12[-slim])")
    build_runs = " ".join(rest for i, rest in build["lines"] if i == "RUN")

    # The commands the README and the Makefile document for a developer machine.
    readme = open(os.path.join(args.source, "README.md"), encoding="utf-8").read()
    makefile = open(os.path.join(args.source, "Makefile"), encoding="utf-8").read()
    if "deploy/install-deps.sh" not in readme:
        problem("README.md no longer documents deploy/install-deps.sh")
    if "bash deploy/install-deps.sh" not in build_runs:
        problem("Dockerfile: the build stage does not run bash deploy/install-deps.sh")
    configure = re.search(r"^configure:.*\n\t(.+)$", makefile, re.M)
    build_rule = re.search(r"^build:.*\n\t(.+)$", makefile, re.M)
    if not configure or "cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=Release" not in configure.group(1):
        problem("Makefile: the configure rule is not the cmake invocation this check knows")
    if not build_rule or "cmake --build $(BUILD_DIR)" not in build_rule.group(1):
        problem("Makefile: the build rule is not `cmake --build $(BUILD_DIR)`")
    make = re.search(r"\bmake build\b([^&;]*)", build_runs)
    if not make:
        problem("Dockerfile: the build stage does not build with `make build` (the Makefile's cmake invocation)")
    else:
        note("Dockerfile builds with `make build` = deploy/install-deps.sh + "
             f"`{configure.group(1).strip() if configure else '?'}` + `{build_rule.group(1).strip() if build_rule else '?'}`")
        flags = re.search(r'CMAKE_FLAGS="([^"]*)"', make.group(1))
        for flag in (flags.group(1).split() if flags else []):
            if flag.startswith("-DCMAKE_BUILD_TYPE") or flag.startswith("-DCMAKE_CXX_FLAGS"):
                problem(f"Dockerfile: {flag} changes the documented Release build")
            option = re.match(r"-D(TOTALGRAD_\w+)=", flag)
            if option and option.group(1) not in readme:
                problem(f"Dockerfile: {option.group(1)} is not an option the README documents")
    build_dir = re.search(r"BUILD_DIR=(\S+)", make.group(1)).group(1) if make and "BUILD_DIR=" in make.group(1) else "build"
    # The binaries are copied from where the CMake targets put them.
    for binary in (args.coordinator, args.worker, args.cli):
        if not binary:
            continue
        relative = os.path.relpath(binary, args.build) if args.build else None
        if relative and f"{build_dir.rstrip('/')}/{relative}" not in build_runs:
            problem(f"Dockerfile: does not copy {build_dir}/{relative} (where the build puts "
                    f"{os.path.basename(binary)})")
    for instruction, rest in build["lines"] + runtime["lines"]:
        if instruction == "ADD":
            problem("Dockerfile: use COPY, not ADD")
        if instruction == "COPY" and "--from=" not in rest:
            for source in shlex.split(rest)[:-1]:
                if not source.startswith("--") and source != "." and \
                        not os.path.exists(os.path.join(args.source, source)):
                    problem(f"Dockerfile: COPY source {source} does not exist")
        if instruction == "RUN" and re.search(r"\b(curl|wget)\b", rest):
            problem("Dockerfile: downloads outside Debian packages")
    runtime_text = " ".join(rest for _, rest in runtime["lines"])
    user = [rest for i, rest in runtime["lines"] if i == "USER"]
    if not user or user[-1].split(":")[0] in ("0", "root"):
        problem("Dockerfile: the runtime stage must run as a non-root USER")
    for name in ("totalgrad-coordinator", "totalgrad-worker", "totalgrad"):
        if not re.search(rf"/{re.escape(name)}\b", build_runs):
            problem(f"Dockerfile: {name} is not copied out of the build")
    if "runtime-packages.sh" not in build_runs or "runtime-packages.txt" not in runtime_text:
        problem("Dockerfile: the runtime packages are not derived from the binaries")
    if re.search(r"-dev\b|build-essential|cmake", runtime_text):
        problem("Dockerfile: the runtime stage installs build tools")

    # The runtime package list, computed from this build's binaries.
    binaries = [b for b in (args.coordinator, args.worker, args.cli) if b]
    if binaries and shutil.which("dpkg-query") and shutil.which("ldd"):
        script = os.path.join(args.source, "deploy", "docker", "runtime-packages.sh")
        result = subprocess.run(["bash", script] + binaries, capture_output=True, text=True)
        packages = result.stdout.split()
        if result.returncode != 0 or not packages:
            problem("runtime-packages.sh failed:\n" + result.stderr)
        else:
            dev = [p for p in packages if p.endswith("-dev")]
            if dev:
                problem(f"runtime-packages.sh lists -dev packages: {dev}")
            for needed in ("libsqlite3-0", "libc6"):
                if needed not in packages:
                    problem(f"runtime-packages.sh misses {needed}")
            note(f"runtime image packages for these binaries ({len(packages)}): {' '.join(packages)}")
    ignore = path + ".dockerignore"
    if not os.path.exists(ignore):
        problem("deploy/docker/Dockerfile.dockerignore is missing (host build trees in the context)")
    if not shutil.which("docker"):
        print("note: no docker client; the image itself is not built here")
    return 1 if PROBLEMS else 0


# ---- Slurm ------------------------------------------------------------------------

def check_sbatch(args):
    path = os.path.join(args.source, "deploy", "slurm", "totalgrad-workers.sbatch")
    text = open(path, encoding="utf-8").read()
    result = subprocess.run(["bash", "-n", path], capture_output=True, text=True)
    if result.returncode != 0:
        problem("bash -n: " + result.stderr)
    else:
        note("bash -n")
    if shutil.which("shellcheck"):
        result = subprocess.run(["shellcheck", "-S", "warning", path], capture_output=True, text=True)
        if result.returncode != 0:
            problem("shellcheck:\n" + result.stdout)
        else:
            note("shellcheck -S warning")
    if not text.startswith("#!/bin/bash"):
        problem("sbatch script must start with #!/bin/bash")
    directives = {}
    for line in text.splitlines():
        if not line.startswith("#SBATCH"):
            if directives and line.strip() and not line.startswith("#"):
                break  # sbatch stops reading directives at the first command
            continue
        option = line.split()[1]
        key, _, value = option.partition("=")
        directives[key] = value
    for key, value in (("--signal", "B:TERM@300"),):
        if directives.get(key) != value:
            problem(f"#SBATCH {key}={directives.get(key)} (expected {value})")
    for key in ("--nodes", "--ntasks-per-node", "--time", "--job-name"):
        if key not in directives:
            problem(f"#SBATCH {key} is missing")
    if not re.search(r"^srun\b", text, re.M):
        problem("the workers are not started with srun")
    if not re.search(r"^export OPENBLAS_NUM_THREADS=1$", text, re.M):
        problem("export OPENBLAS_NUM_THREADS=1 missing (one BLAS thread per trial)")
    if "trap drain TERM" not in text:
        problem("SIGTERM is not trapped and passed to the workers")
    # The worker flags the script passes.
    # (The drain function's squeue and scancel flags are Slurm's, not the worker's.)
    passed = text[text.index("worker_args=("):]
    passed = re.sub(r"\ndrain\(\) \{.*?\n\}\n", "\n", passed, flags=re.S)
    words = re.findall(r"(--[a-z][a-z0-9-]*)", passed)
    srun_flags = {"--kill-on-bad-exit", "--ntasks-per-node", "--cpus-per-task"}
    check_flags("sbatch worker_args", [args.worker], [w for w in words if w not in srun_flags])
    for required in ("--walltime", "--trial-time", "--drain-timeout"):
        if required not in words:
            problem(f"the workers are not given {required}")
    note(f"#SBATCH directives: {', '.join(f'{k}={v}' for k, v in directives.items())}")
    return 1 if PROBLEMS else 0


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("kind", choices=["systemd", "compose", "k8s", "dockerfile", "sbatch"])
    parser.add_argument("--source", required=True)
    parser.add_argument("--build", default="")
    parser.add_argument("--coordinator", default="")
    parser.add_argument("--worker", default="")
    parser.add_argument("--cli", default="")
    args = parser.parse_args()
    code = {"systemd": check_systemd, "compose": check_compose, "k8s": check_k8s,
            "dockerfile": check_dockerfile, "sbatch": check_sbatch}[args.kind](args)
    print(f"{args.kind}: {len(PROBLEMS)} problem(s)")
    sys.exit(code)


if __name__ == "__main__":
    main()
