"""Render the Kubernetes manifests and turn them into what podman can play.

``kubectl kustomize`` (or a standalone ``kustomize build``) renders an overlay offline;
the tests then read the documents as plain dictionaries.

podman 4.3 plays Pods, Deployments and PersistentVolumeClaims only (``podman kube play
--help``): a StatefulSet is ignored, and so is a Service. :func:`podman_pods` gives each
StatefulSet's pod as the StatefulSet controller would create it (ordinal 0: the
template, the hostname ``<name>-0``, its claims ``<template>-<name>-0``), so podman
plays the very pod template of the manifests. Two podman differences are bridged and no
more: an ``emptyDir`` becomes a named volume shared by every pod that uses the same
volume name (Kubernetes gives each pod its own), so each pod's are renamed after the pod;
and podman publishes every container port on the host (on the same port number when the
manifest gives no ``hostPort``), so pods that run are given host ports of their own.
A third, podman's disregard of ``fsGroup`` for the claim volumes, is bridged where the
pods are started (:meth:`tests.deploy.podman_env.Podman.play`).
"""

from __future__ import annotations

import copy
import shutil
import subprocess
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[2]
DEPLOY = ROOT / "deploy" / "kubernetes"
OVERLAYS = {
    "base": DEPLOY / "base",
    "realtime": DEPLOY / "overlays" / "realtime",
    "plant": DEPLOY / "overlays" / "plant",
}

Doc = dict[str, Any]


def renderer() -> list[str] | None:
    """The command that renders a kustomization directory (its path appended), if any."""
    if shutil.which("kubectl"):
        return ["kubectl", "kustomize"]
    if shutil.which("kustomize"):
        return ["kustomize", "build"]
    return None


def render(directory: Path) -> str:
    command = renderer()
    assert command is not None
    done = subprocess.run(
        [*command, str(directory)], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, f"{' '.join(command)} {directory}: {done.stderr}"
    return done.stdout


def documents(text: str) -> list[Doc]:
    return [doc for doc in yaml.safe_load_all(text) if doc]


def of_kind(docs: list[Doc], kind: str) -> list[Doc]:
    return [doc for doc in docs if doc["kind"] == kind]


def containers(docs: list[Doc]) -> list[Doc]:
    """Every container of every StatefulSet's pod template."""
    return [
        container
        for sts in of_kind(docs, "StatefulSet")
        for container in sts["spec"]["template"]["spec"]["containers"]
    ]


def podman_pods(
    docs: list[Doc], image: str, host_ports: dict[str, dict[str, int]] | None = None
) -> list[Doc]:
    """The ConfigMaps, claims and pods (ordinal 0) of the StatefulSets in ``docs``, for
    ``podman kube play``; ``image`` replaces the manifests' image; ``host_ports`` maps a
    StatefulSet's name to {port name: host port on 127.0.0.1}."""
    out: list[Doc] = [copy.deepcopy(doc) for doc in of_kind(docs, "ConfigMap")]
    for sts in of_kind(docs, "StatefulSet"):
        name = sts["metadata"]["name"]
        pod_name = f"{name}-0"
        template = copy.deepcopy(sts["spec"]["template"])
        spec = template["spec"]
        spec["hostname"] = pod_name
        renamed: dict[str, str] = {}
        for volume in spec["volumes"]:
            if "emptyDir" in volume:
                renamed[volume["name"]] = f"{volume['name']}-{pod_name}"
                volume["name"] = renamed[volume["name"]]
        for claim in sts["spec"].get("volumeClaimTemplates", []):
            claim_name = f"{claim['metadata']['name']}-{pod_name}"
            out.append(
                {
                    "apiVersion": "v1",
                    "kind": "PersistentVolumeClaim",
                    "metadata": {"name": claim_name},
                    "spec": claim["spec"],
                }
            )
            spec["volumes"].append(
                {
                    "name": claim["metadata"]["name"],
                    "persistentVolumeClaim": {"claimName": claim_name},
                }
            )
        for container in spec["containers"]:
            container["image"] = image
            for mount in container.get("volumeMounts", []):
                mount["name"] = renamed.get(mount["name"], mount["name"])
            for port in container.get("ports", []):
                host = (host_ports or {}).get(name, {}).get(port["name"])
                if host:
                    port["hostPort"] = host
                    port["hostIP"] = "127.0.0.1"
        out.append(
            {
                "apiVersion": "v1",
                "kind": "Pod",
                "metadata": {"name": pod_name, "labels": template["metadata"]["labels"]},
                "spec": spec,
            }
        )
    return out


def dump(docs: list[Doc]) -> str:
    return yaml.safe_dump_all(docs, sort_keys=False)
