"""A podman of the tests' own, playing the manifests on the project's container image.

Nothing on the machine changes: the engine's configuration (``CONTAINERS_CONF``,
``CONTAINERS_STORAGE_CONF``) and its store are in a temporary directory, as in
``make test-compose`` (runc, cgroupfs, container ulimits within the shell's hard limits:
podman's defaults need CAP_SYS_RESOURCE where they exceed them). The project's image is
read, never written, from the store ``make test-container`` builds into
(``localhost/motion-server:test``), as an additional image store. On it the tests build
one layer: this tree's ``motion_server`` package in place of the one the image was built
with (seconds, no network), so the pods run the code under test with the image's
dependencies, user, entry point and healthcheck.
"""

from __future__ import annotations

import os
import resource
import shutil
import stat
import subprocess
from pathlib import Path
from typing import Any

import yaml

from .kube import ROOT

#: the image ``make test-container`` builds (container/test-container.sh)
PROJECT_IMAGE = os.environ.get("MOTION_SERVER_TEST_IMAGE", "localhost/motion-server:test")
#: where ``make test-container`` keeps it (container/lib.sh, ct_store)
PROJECT_STORES = {
    "overlay": Path("/var/lib/containers/motion-server-overlay"),
    "vfs": Path("/var/lib/containers/motion-server-vfs"),
}
#: the image the tests build on it
TEST_IMAGE = "localhost/motion-server:kube-test"

CONTAINERFILE = """\
FROM {image}
USER root
COPY motion_server /tmp/motion_server
RUN set -eu; \\
    dest=$(python -c 'import motion_server, os; print(os.path.dirname(motion_server.__file__))'); \\
    rm -rf "$dest"; mv /tmp/motion_server "$dest"
USER motion
"""


def give_to_group(root: Path, group: int) -> None:
    """What the kubelet does to a volume for a pod's ``fsGroup``: every file the group's,
    readable and writable by it, directories set-group-ID (new files stay the group's)."""
    for path in [root, *root.rglob("*")]:
        os.chown(path, -1, group, follow_symlinks=False)
        if path.is_symlink():
            continue
        mode = path.stat().st_mode | stat.S_IRGRP | stat.S_IWGRP
        if path.is_dir():
            mode |= stat.S_IXGRP | stat.S_ISGID
        path.chmod(mode)


class Unavailable(Exception):
    """podman cannot be used here (the message says why)."""


def _limit(kind: int, cap: int) -> int:
    hard = resource.getrlimit(kind)[1]
    return cap if hard == resource.RLIM_INFINITY or hard > cap else hard


class Podman:
    """podman with a configuration and a store of its own under ``work``."""

    def __init__(self, work: Path) -> None:
        if os.geteuid() != 0:
            raise Unavailable("podman runs as root here (the project's container tests do)")
        if not shutil.which("podman"):
            raise Unavailable("podman is not installed (Debian: apt-get install podman runc)")
        found = [
            (driver, store)
            for driver, store in PROJECT_STORES.items()
            if (store / f"{driver}-images").is_dir()
        ]
        if not found:
            stores = ", ".join(map(str, PROJECT_STORES.values()))
            raise Unavailable(f"no image store of `make test-container` ({stores})")
        self.work = work
        driver, store = found[0]
        (work / "networks").mkdir(parents=True, exist_ok=True)
        (work / "storage.conf").write_text(
            f'[storage]\ndriver = "{driver}"\ngraphroot = "{work / "root"}"\n'
            f'runroot = "{work / "run"}"\n[storage.options]\n'
            f'additionalimagestores = ["{store}"]\n',
            "utf-8",
        )
        nofile = _limit(resource.RLIMIT_NOFILE, 65536)
        nproc = _limit(resource.RLIMIT_NPROC, 4096)
        (work / "containers.conf").write_text(
            f'[containers]\ndefault_ulimits = ["nofile={nofile}:{nofile}", '
            f'"nproc={nproc}:{nproc}"]\nlog_driver = "k8s-file"\n'
            f'[engine]\nruntime = "runc"\ncgroup_manager = "cgroupfs"\nevents_logger = "file"\n'
            f'[network]\nnetwork_config_dir = "{work / "networks"}"\n',
            "utf-8",
        )
        self.env = {
            **os.environ,
            "CONTAINERS_CONF": str(work / "containers.conf"),
            "CONTAINERS_STORAGE_CONF": str(work / "storage.conf"),
        }
        if self.run("image", "exists", PROJECT_IMAGE, check=False).returncode != 0:
            raise Unavailable(f"no {PROJECT_IMAGE} in {store}: `make test-container` builds it")

    def run(
        self, *args: str, check: bool = True, timeout: float = 180
    ) -> subprocess.CompletedProcess[str]:
        done = subprocess.run(
            ["podman", *args],
            capture_output=True,
            text=True,
            env=self.env,
            timeout=timeout,
            check=False,
        )
        if check and done.returncode != 0:
            raise AssertionError(f"podman {' '.join(args)}: {done.returncode}\n{done.stderr}")
        return done

    def build_test_image(self) -> str:
        """:data:`TEST_IMAGE`: the project's image with this tree's server package."""
        context = self.work / "context"
        shutil.copytree(
            ROOT / "server" / "motion_server",
            context / "motion_server",
            ignore=shutil.ignore_patterns("__pycache__"),
        )
        (context / "Containerfile").write_text(CONTAINERFILE.format(image=PROJECT_IMAGE))
        self.run(
            "build", "--isolation", "chroot", "--format", "docker", "--quiet",
            "-t", TEST_IMAGE, str(context),
        )  # fmt: skip
        return TEST_IMAGE

    def play(self, path: Path, docs: list[dict[str, Any]], start: bool) -> None:
        """``podman kube play`` the pods of ``docs`` (written to ``path``), then give each
        claim's volume to the pod's ``fsGroup`` as the kubelet does (group-owned,
        group-writable, set-group-ID: podman 4.3 ignores ``fsGroup``), then start them;
        without ``start`` the pods are only created.
        The containers are initialised first: podman copies the image's directory (its
        owner and mode) onto an empty volume when it first mounts it, which would undo
        the group's."""
        path.write_text(yaml.safe_dump_all(docs, sort_keys=False), "utf-8")
        self.run("kube", "play", "--start=false", str(path))
        for pod in docs:
            if pod["kind"] != "Pod" or not start:
                continue
            group = pod["spec"].get("securityContext", {}).get("fsGroup")
            if group is not None:  # podman copies the image's directory onto an empty
                for container in pod["spec"]["containers"]:  # volume when it mounts it
                    self.run("init", f"{pod['metadata']['name']}-{container['name']}")
            for volume in pod["spec"]["volumes"]:
                claim = volume.get("persistentVolumeClaim", {}).get("claimName")
                if group is not None and claim:
                    out = self.run("volume", "inspect", "--format", "{{.Mountpoint}}", claim)
                    give_to_group(Path(out.stdout.strip()), int(group))
            self.run("pod", "start", pod["metadata"]["name"])

    def secret(self, name: str, data: dict[str, str]) -> None:
        """A Secret that pods reach by ``secretName``: podman 4.3 reads its data as the
        YAML of a Kubernetes Secret (values base64, as there)."""
        lines = [f"apiVersion: v1\nkind: Secret\nmetadata:\n  name: {name}\ndata:"]
        lines += [f"  {key}: {value}" for key, value in data.items()] or ["  {}"]
        path = self.work / f"{name}.yaml"
        path.write_text("\n".join(lines) + "\n", "utf-8")
        self.run("secret", "create", name, str(path))

    def close(self) -> None:
        """Remove every pod and volume of this store, then the store."""
        self.run("pod", "rm", "--all", "--force", "--time", "10", check=False)
        self.run("volume", "rm", "--all", "--force", check=False)
        self.run("secret", "rm", "--all", check=False)
        self.run("rmi", "--all", "--force", check=False)
        shutil.rmtree(self.work, ignore_errors=True)
