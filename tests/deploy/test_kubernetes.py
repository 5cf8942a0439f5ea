"""The Kubernetes manifests of deploy/kubernetes (docs/deployment.md).

Every overlay renders offline (``kubectl kustomize``) and passes ``kubernetes-validate
--strict`` (the schemas of the Kubernetes release it bundles; unknown fields refused).
Then what a schema cannot say: Guaranteed QoS, probes that run the server's own probe on
the ready file ``run`` writes, the ports the image's server listens on, no capability by
default and exactly SYS_NICE + IPC_LOCK in the real-time overlay, one StatefulSet and one
headless Service per site map in the plant, and site maps that ``motion-server check``
accepts as the container sees them.

podman: the plant's pods are created from the rendered manifests (``podman kube play
--start=false``) and inspected; then two controllers are started, and a Modbus client on
the host reads both, the probes pass inside them, and a stop writes the retained state to
the claim's volume (tests/deploy/podman_env.py says how, and when that part is skipped).
"""

from __future__ import annotations

import copy
import json
import os
import re
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from motion_server import cli
from motion_server import probe as probe_module

from .kube import OVERLAYS, ROOT, Doc, containers, documents, of_kind, podman_pods, render
from .kube import dump as dump_yaml
from .kube import renderer as find_renderer
from .podman_env import Podman, Unavailable

#: the capabilities the Pod Security baseline level lets a pod add
#: (kubernetes.io/docs/concepts/security/pod-security-standards, "Capabilities")
BASELINE_CAPABILITIES = {
    "AUDIT_WRITE", "CHOWN", "DAC_OVERRIDE", "FOWNER", "FSETID", "KILL", "MKNOD",
    "NET_BIND_SERVICE", "SETFCAP", "SETGID", "SETPCAP", "SETUID", "SYS_CHROOT",
}  # fmt: skip
#: what the real-time overlay adds: SCHED_FIFO for the scan, memory locking
REALTIME_CAPABILITIES = {"SYS_NICE", "IPC_LOCK"}
#: the site maps of the plant: one directory each
PLANT_SITES = sorted(p.parent.name for p in (OVERLAYS["plant"]).glob("*/site.toml"))


def dockerfile_env() -> dict[str, str]:
    """The ENV of the Dockerfile's runtime stage (what the server in the pod sees)."""
    text = (ROOT / "Dockerfile").read_text("utf-8").split("FROM ${BASE_IMAGE}\n")[-1]
    block = re.search(r"^ENV (.*?)(?:\n\n|\n#)", text, re.S | re.M)
    assert block is not None
    pairs = re.findall(r"(\w+)=(\S+)", block.group(1))
    return {key: value.rstrip("\\").strip() for key, value in pairs}


IMAGE_ENV = dockerfile_env()


@pytest.fixture(scope="module")
def rendered() -> dict[str, list[Doc]]:
    if find_renderer() is None:
        pytest.skip("neither kubectl nor kustomize is installed (`make test` installs kubectl)")
    return {name: documents(render(path)) for name, path in OVERLAYS.items()}


@pytest.mark.parametrize("overlay", sorted(OVERLAYS))
def test_every_overlay_passes_strict_validation(
    overlay: str, rendered: dict[str, list[Doc]], tmp_path: Path
) -> None:
    validate = Path(sys.executable).with_name("kubernetes-validate")
    if not validate.exists():
        pytest.skip("kubernetes-validate is not installed (the test extra pins it)")
    path = tmp_path / f"{overlay}.yaml"
    path.write_text(dump_yaml(rendered[overlay]), "utf-8")
    done = subprocess.run(
        [str(validate), "--strict", "--quiet", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    kinds = {doc["kind"] for doc in rendered[overlay]}
    assert {"StatefulSet", "Service", "ConfigMap"} <= kinds


def test_strict_validation_refuses_an_unknown_field(tmp_path: Path) -> None:
    """The validator does fail: a probe field misspelt as in the reference notes."""
    validate = Path(sys.executable).with_name("kubernetes-validate")
    if not validate.exists():
        pytest.skip("kubernetes-validate is not installed (the test extra pins it)")
    sts = (OVERLAYS["base"] / "statefulset.yaml").read_text("utf-8")
    path = tmp_path / "bad.yaml"
    path.write_text(sts.replace("periodSeconds: 10", "periodSecondz: 10"), "utf-8")
    done = subprocess.run(
        [str(validate), "--strict", "--quiet", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode != 0


@pytest.mark.parametrize("overlay", sorted(OVERLAYS))
def test_requests_equal_limits(overlay: str, rendered: dict[str, list[Doc]]) -> None:
    for container in containers(rendered[overlay]):
        resources = container["resources"]
        assert set(resources["limits"]) == {"cpu", "memory"}
        assert resources["requests"] == resources["limits"], container["name"]
        # the CPU manager's static policy pins whole cores only
        assert re.fullmatch(r"[1-9][0-9]*", str(resources["limits"]["cpu"]))


def run_args(container: Doc) -> Any:
    """The container's arguments as ``motion-server`` parses them (the image's entry
    point is ``motion-server``)."""
    assert "command" not in container, "the image's entry point runs the server"
    return cli.build_parser().parse_args(container["args"])


@pytest.mark.parametrize("overlay", sorted(OVERLAYS))
def test_probes_run_the_servers_probe_on_its_ready_file(
    overlay: str, rendered: dict[str, list[Doc]]
) -> None:
    for container in containers(rendered[overlay]):
        args = run_args(container)
        assert args.command == "run"
        assert args.ready_file, "the probes read the ready file `run --ready-file` writes"
        mounts = {m["mountPath"] for m in container["volumeMounts"]}
        assert os.path.dirname(args.ready_file) in mounts, "a writable directory for it"
        for kind, which in (("startupProbe", "ready"), ("readinessProbe", "ready"),
                            ("livenessProbe", "live")):  # fmt: skip
            command = container[kind]["exec"]["command"]
            assert command[:3] == ["python", "-m", "motion_server.probe"], kind
            parsed = probe_module.build_parser().parse_args(command[3:])
            assert getattr(parsed, which), f"{kind} checks --{which}"
            assert parsed.ready_file == args.ready_file, kind
            # the probe must finish before the kubelet gives up on it
            assert container[kind]["timeoutSeconds"] > parsed.interval + parsed.timeout


@pytest.mark.parametrize("overlay", sorted(OVERLAYS))
def test_ports_are_the_servers(overlay: str, rendered: dict[str, list[Doc]]) -> None:
    """Modbus and OPC UA where the image's server listens; the web view and EtherNet/IP
    at their default ports; every Service port names a container port."""
    docs = rendered[overlay]
    for container in containers(docs):
        ports = {p["name"]: p["containerPort"] for p in container["ports"]}
        assert ports["modbus"] == int(IMAGE_ENV["MOTION_SERVER_MODBUS_PORT"])
        assert ports["opcua"] == int(IMAGE_ENV["MOTION_SERVER_OPCUA_PORT"])
        assert ports["web"] == 8080
        assert ports["ethernetip"] == 44818
        assert IMAGE_ENV["MOTION_SERVER_MODBUS_HOST"] == "0.0.0.0"
        assert IMAGE_ENV["MOTION_SERVER_OPCUA_HOST"] == "0.0.0.0"
    for service in of_kind(docs, "Service"):
        assert service["spec"]["clusterIP"] == "None", "headless: the DNS name is the pod's"
        names = {p["name"] for c in containers(docs) for p in c["ports"]}
        for port in service["spec"]["ports"]:
            assert port["targetPort"] in names


@pytest.mark.parametrize("overlay", sorted(OVERLAYS))
def test_pods_run_unprivileged_on_a_read_only_root(
    overlay: str, rendered: dict[str, list[Doc]]
) -> None:
    for sts in of_kind(rendered[overlay], "StatefulSet"):
        pod = sts["spec"]["template"]["spec"]
        if overlay == "realtime":  # root: added capabilities reach no other user
            assert pod["securityContext"]["runAsNonRoot"] is False
            assert pod["securityContext"]["runAsUser"] == 0
        else:
            assert pod["securityContext"]["runAsNonRoot"] is True
            assert pod["securityContext"]["runAsUser"] == 10001, "the image's user motion"
        # the data volume is the image's group's, writable by it, whoever the user
        assert pod["securityContext"]["runAsGroup"] == pod["securityContext"]["fsGroup"] == 10001
        assert pod["securityContext"]["seccompProfile"]["type"] == "RuntimeDefault"
        for key in ("hostNetwork", "hostPID", "hostIPC"):
            assert not pod.get(key)
        for container in pod["containers"]:
            context = container["securityContext"]
            assert context["readOnlyRootFilesystem"] is True
            assert context["allowPrivilegeEscalation"] is False
            assert context.get("privileged") is not True
            assert context["capabilities"]["drop"] == ["ALL"]
            # the server writes only to its data directory (the claim), the ready file's
            # directory and /tmp: each a volume
            mounts = {m["mountPath"]: m for m in container["volumeMounts"]}
            data_dir = IMAGE_ENV["MOTION_SERVER_DATA_DIR"]
            assert IMAGE_ENV["MOTION_SERVER_OPCUA_DATA_DIR"].startswith(data_dir + "/")
            claims = {c["metadata"]["name"] for c in sts["spec"]["volumeClaimTemplates"]}
            assert mounts[data_dir]["name"] in claims
            assert "/tmp" in mounts


@pytest.mark.parametrize("overlay", sorted(OVERLAYS))
def test_secrets_are_volumes_that_must_exist(overlay: str, rendered: dict[str, list[Doc]]) -> None:
    for sts in of_kind(rendered[overlay], "StatefulSet"):
        volumes = sts["spec"]["template"]["spec"]["volumes"]
        secrets = {v["secret"]["secretName"]: v["secret"] for v in volumes if "secret" in v}
        assert set(secrets) == {"motion-server-users", "motion-server-certs"}
        for secret in secrets.values():
            assert secret["optional"] is False  # written out: podman 4.3 needs it
        for container in sts["spec"]["template"]["spec"]["containers"]:
            env = {e["name"]: e for e in container["env"]}
            assert all("valueFrom" not in e for e in env.values()), "no secretKeyRef"
            users = env["MOTION_SERVER_USERS_FILE"]["value"]
            mounts = {m["name"]: m["mountPath"] for m in container["volumeMounts"]}
            users_volume = next(v["name"] for v in volumes if v.get("secret", {}).get(
                "secretName") == "motion-server-users")  # fmt: skip
            assert os.path.dirname(users) == mounts[users_volume]


@pytest.mark.parametrize("overlay", ["base", "plant"])
def test_the_default_adds_no_capability(overlay: str, rendered: dict[str, list[Doc]]) -> None:
    for container in containers(rendered[overlay]):
        assert "add" not in container["securityContext"]["capabilities"]
    for namespace in of_kind(rendered[overlay], "Namespace"):
        assert namespace["metadata"]["labels"]["pod-security.kubernetes.io/enforce"] == "baseline"


def test_the_plant_namespace_enforces_baseline(rendered: dict[str, list[Doc]]) -> None:
    (namespace,) = of_kind(rendered["plant"], "Namespace")
    assert namespace["metadata"]["labels"]["pod-security.kubernetes.io/enforce"] == "baseline"
    for doc in rendered["plant"]:
        if doc["kind"] != "Namespace":
            assert doc["metadata"]["namespace"] == namespace["metadata"]["name"]


def test_realtime_adds_exactly_sys_nice_and_ipc_lock(rendered: dict[str, list[Doc]]) -> None:
    (container,) = copy.deepcopy(containers(rendered["realtime"]))
    capabilities = container["securityContext"]["capabilities"]
    assert set(capabilities["add"]) == REALTIME_CAPABILITIES
    assert len(capabilities["add"]) == 2
    assert capabilities["drop"] == ["ALL"]
    # beyond the baseline level: the namespace must be privileged
    assert REALTIME_CAPABILITIES - BASELINE_CAPABILITIES == REALTIME_CAPABILITIES
    (namespace,) = of_kind(rendered["realtime"], "Namespace")
    assert namespace["metadata"]["labels"]["pod-security.kubernetes.io/enforce"] == "privileged"
    # and nothing else differs from the base's container
    (base,) = containers(rendered["base"])
    del capabilities["add"]
    assert container == base


def test_the_plant_has_one_controller_per_site_map(rendered: dict[str, list[Doc]]) -> None:
    docs = rendered["plant"]
    n = len(PLANT_SITES)
    assert n == 3
    sets, services = of_kind(docs, "StatefulSet"), of_kind(docs, "Service")
    assert len(sets) == n and len(services) == n
    assert len({s["metadata"]["name"] for s in sets}) == n
    assert len({s["metadata"]["name"] for s in services}) == n
    service_by_name = {s["metadata"]["name"]: s for s in services}
    config_maps = {c["metadata"]["name"]: c for c in of_kind(docs, "ConfigMap")}
    site_names = set()
    for sts in sets:
        assert sts["spec"]["replicas"] == 1
        labels = sts["spec"]["template"]["metadata"]["labels"]
        selector = sts["spec"]["selector"]["matchLabels"]
        assert selector.items() <= labels.items()
        # its Service selects its pod and no other controller's
        service = service_by_name[sts["spec"]["serviceName"]]
        chosen = [
            other["metadata"]["name"]
            for other in sets
            if service["spec"]["selector"].items()
            <= other["spec"]["template"]["metadata"]["labels"].items()
        ]
        assert chosen == [sts["metadata"]["name"]]
        volumes = sts["spec"]["template"]["spec"]["volumes"]
        (site,) = [v["configMap"]["name"] for v in volumes if "configMap" in v]
        text = config_maps[site]["data"]["site.toml"]
        site_names.add(re.search(r'^name = "(\w+)"', text, re.M).group(1))  # type: ignore[union-attr]
    assert len(site_names) == n, "each controller runs its own site map"


def site_maps(rendered: dict[str, list[Doc]]) -> Iterator[tuple[str, str, str]]:
    for overlay, docs in rendered.items():
        for config_map in of_kind(docs, "ConfigMap"):
            yield overlay, config_map["metadata"]["name"], config_map["data"]["site.toml"]


def check_site_map(text: str, work: Path) -> subprocess.CompletedProcess[str]:
    """``motion-server check`` of a site map as the container sees it: the image's
    environment (its data directories moved into ``work``), the users file of the Secret,
    free ports."""
    path = work / "site.toml"
    path.write_text(text, "utf-8")
    (work / "users.toml").write_text("", "utf-8")
    env = {k: v for k, v in os.environ.items() if not k.startswith("MOTION_SERVER_")}
    env.update(IMAGE_ENV)
    env.update(
        MOTION_SERVER_DATA_DIR=str(work / "data"),
        MOTION_SERVER_OPCUA_DATA_DIR=str(work / "data" / "opcua"),
        MOTION_SERVER_USERS_FILE=str(work / "users.toml"),
        MOTION_SERVER_MAP=str(path),
    )
    cmd = [sys.executable, "-m", "motion_server.cli", "check", "--modbus-port", "0",
           "--opcua-port", "0"]  # fmt: skip
    return subprocess.run(
        cmd, capture_output=True, text=True, env=env, cwd=work, timeout=120, check=False
    )


def test_every_site_map_passes_check(rendered: dict[str, list[Doc]], tmp_path: Path) -> None:
    seen = 0
    for overlay, name, text in site_maps(rendered):
        work = tmp_path / f"{overlay}-{name}"
        work.mkdir()
        done = check_site_map(text, work)
        assert done.returncode == 0, f"{overlay} {name}: {done.stderr}"
        assert "ok:" in done.stdout
        seen += 1
    assert seen == 2 + len(PLANT_SITES)


def test_check_refuses_a_broken_site_map(tmp_path: Path) -> None:
    """The check above can fail: a site name a site map may not have."""
    text = (OVERLAYS["base"] / "site.toml").read_text("utf-8")
    done = check_site_map(text.replace('name = "controller"', 'name = "line-1"'), tmp_path)
    assert done.returncode == 1
    assert "site.name" in done.stderr


# -- podman ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def podman(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Podman]:
    try:
        engine = Podman(tmp_path_factory.mktemp("podman"))
    except Unavailable as exc:
        pytest.skip(f"podman part skipped: {exc}; the manifests were checked without it")
    try:
        engine.secret("motion-server-users", {"users.toml": ""})
        engine.secret("motion-server-certs", {})
        yield engine
    finally:
        engine.close()


@pytest.fixture(scope="module")
def test_image(podman: Podman) -> str:
    return podman.build_test_image()


def inspect(podman: Podman, name: str) -> dict[str, Any]:
    (data,) = json.loads(podman.run("container", "inspect", name).stdout)
    result: dict[str, Any] = data
    return result


def test_podman_creates_the_plant_pods_as_written(
    podman: Podman, test_image: str, rendered: dict[str, list[Doc]]
) -> None:
    """podman plays the pods of the plant, not started; inspect shows the manifests'
    user, read-only root, no capability, Guaranteed resources, volumes and liveness."""
    podman.play(podman.work / "plant.yaml", podman_pods(rendered["plant"], test_image), False)
    try:
        for site in PLANT_SITES:
            pod = f"motion-server-{site}-0"
            data = inspect(podman, f"{pod}-controller")
            config, host = data["Config"], data["HostConfig"]
            assert config["User"].split(":")[0] == "10001"
            assert host["ReadonlyRootfs"] is True
            assert not data.get("EffectiveCaps"), data.get("EffectiveCaps")
            assert not host.get("CapAdd"), host.get("CapAdd")
            assert host["Memory"] == 1 << 30
            assert host["CpuQuota"] == host["CpuPeriod"], "one core"
            assert config["Hostname"] == pod
            assert "motion_server.probe" in config["Healthcheck"]["Test"]
            assert "--live" in config["Healthcheck"]["Test"]
            mounts = {m["Destination"]: m for m in data["Mounts"]}
            assert mounts["/var/lib/motion-server"]["Name"] == f"data-{pod}"
            assert mounts["/run/motion-server"]["Name"] == f"run-{pod}"
            assert mounts["/etc/motion-server"]["Name"].startswith(f"motion-server-site-{site}-")
    finally:
        podman.run("pod", "rm", "--all", "--force", check=False)
        podman.run("volume", "rm", "--all", "--force", check=False)


#: CAP_IPC_LOCK (14) and CAP_SYS_NICE (23), as /proc/PID/status shows capability sets
REALTIME_CAP_MASK = (1 << 14) | (1 << 23)


@pytest.mark.slow
def test_podman_realtime_pod_runs_with_exactly_the_two_capabilities(
    podman: Podman, test_image: str, rendered: dict[str, list[Doc]]
) -> None:
    """The real-time pod starts and serves, its server holding SYS_NICE and IPC_LOCK
    and nothing else, as root (the user added capabilities reach)."""
    names = ("modbus", "opcua", "web", "ethernetip")
    ports = {"motion-server": {n: free_port() for n in names}}
    pods = podman_pods(rendered["realtime"], test_image, ports)
    podman.play(podman.work / "realtime.yaml", pods, True)
    container = "motion-server-0-controller"
    try:
        data = inspect(podman, container)
        assert sorted(data["EffectiveCaps"]) == ["CAP_IPC_LOCK", "CAP_SYS_NICE"]
        ready = wait_ready(podman, container)
        assert ready.returncode == 0, ready.stderr + podman_logs(podman, container)
        status = podman.run("exec", container, "cat", "/proc/1/status").stdout
        fields = dict(line.split(":", 1) for line in status.splitlines() if ":" in line)
        assert fields["Uid"].split()[0] == "0"
        assert int(fields["CapEff"], 16) == REALTIME_CAP_MASK
        assert int(fields["CapPrm"], 16) == REALTIME_CAP_MASK
        assert int(fields["CapBnd"], 16) == REALTIME_CAP_MASK
        live = podman.run(*probe_command(container), "--live", check=False)
        assert live.returncode == 0, live.stderr
    finally:
        podman.run("pod", "rm", "--all", "--force", "--time", "10", check=False)
        podman.run("volume", "rm", "--all", "--force", check=False)


def probe_command(container: str) -> list[str]:
    """``podman exec`` of the manifests' probe in ``container`` (append --ready/--live)."""
    return ["exec", container, "python", "-m", "motion_server.probe",
            "--ready-file", "/run/motion-server/ready.json"]  # fmt: skip


def wait_ready(podman: Podman, container: str, timeout: float = 180) -> Any:
    """The readiness probe, until it passes or ``timeout`` s are up (its last result)."""
    deadline = time.monotonic() + timeout
    while True:
        ready = podman.run(*probe_command(container), "--ready", check=False)
        if ready.returncode == 0 or time.monotonic() > deadline:
            return ready
        time.sleep(1)


def podman_logs(podman: Podman, container: str) -> str:
    return "\n" + podman.run("logs", container, check=False).stderr[-3000:]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def heartbeat(map_json: Path, port: int, wait: float) -> subprocess.CompletedProcess[str]:
    """The project's Modbus health client (container/heartbeat.py) from the host."""
    script = str(ROOT / "container" / "heartbeat.py")
    cmd = [sys.executable, script, "--map-json", str(map_json), "--port", str(port),
           "--require-increase", "--wait", str(wait)]  # fmt: skip
    return subprocess.run(cmd, capture_output=True, text=True, timeout=wait + 60, check=False)


@pytest.mark.slow
def test_podman_runs_two_controllers_and_a_client_reads_both(
    podman: Podman, test_image: str, rendered: dict[str, list[Doc]], tmp_path: Path
) -> None:
    two = PLANT_SITES[:2]
    docs = [
        doc
        for doc in rendered["plant"]
        if doc["kind"] not in ("StatefulSet", "ConfigMap")
        or any(doc["metadata"]["name"].startswith(f"motion-server-{s}") or
               doc["metadata"]["name"].startswith(f"motion-server-site-{s}") for s in two)
    ]  # fmt: skip
    # every container port gets a free host port: podman 4.3 publishes a port without a
    # hostPort on the same host port, so two pods would collide
    names = ("modbus", "opcua", "web", "ethernetip")
    ports = {f"motion-server-{s}": {n: free_port() for n in names} for s in two}
    podman.play(podman.work / "two.yaml", podman_pods(docs, test_image, ports), True)
    try:
        for site in two:
            sts = f"motion-server-{site}"
            text = (OVERLAYS["plant"] / site / "site.toml").read_text("utf-8")
            map_json = tmp_path / f"{site}.json"
            done = subprocess.run(
                [sys.executable, "-m", "motion_server.cli", "map", "-o", str(map_json)],
                capture_output=True,
                text=True,
                env={
                    **os.environ,
                    "MOTION_SERVER_MAP": str(OVERLAYS["plant"] / site / "site.toml"),
                },
                timeout=120,
                check=False,
            )
            assert done.returncode == 0, done.stderr
            # the client reads this controller's heartbeat counting, over the pod's port
            read = heartbeat(map_json, ports[sts]["modbus"], wait=180)
            logs = podman.run("logs", f"{sts}-0-controller", check=False).stderr[-3000:]
            assert read.returncode == 0, f"{read.stderr}\n{logs}"
            assert read.stdout.startswith("healthy: Diagnostics.Heartbeat")
            name = re.search(r'^name = "(\w+)"', text, re.M).group(1)  # type: ignore[union-attr]
            # the probes of the manifests pass inside the pod, on its own site map
            container = f"{sts}-0-controller"
            ready = wait_ready(podman, container)  # OPC UA listens seconds after Modbus
            assert ready.returncode == 0, ready.stderr + podman_logs(podman, container)
            assert ready.stdout.startswith(f"ready: {name} ")
            assert "modbus 5020, opcua 4840" in ready.stdout
            live = podman.run(*probe_command(container), "--live", check=False)
            assert live.returncode == 0, live.stderr
            assert re.match(r"live: \d+ cycles in 0\.6 s", live.stdout)
        # a stop is the programmed stop, and the retained state lands on the claim
        for site in two:
            pod = f"motion-server-{site}-0"
            podman.run("pod", "stop", "--time", "30", pod, timeout=120)
            state = inspect(podman, f"{pod}-controller")["State"]
            assert state["ExitCode"] == 0, state
            volume = json.loads(podman.run("volume", "inspect", f"data-{pod}").stdout)[0]
            retain = json.loads((Path(volume["Mountpoint"]) / "retain.json").read_text())
            assert retain["format"].startswith("motion-server-retain"), retain.get("format")
    finally:
        podman.run("pod", "rm", "--all", "--force", "--time", "10", check=False)
        podman.run("volume", "rm", "--all", "--force", check=False)
