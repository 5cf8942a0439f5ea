"""Site maps: TOML files naming the axes, groups and instruction instances of a site.

Validated with pydantic; every error names the file, the line and the field. The demo
map embedded in the package (``data/demo.toml``) is what ``motion-server run`` uses when
given none (unless ``MOTION_SERVER_MAP`` names a file). Settings of the single-table
sections can be overridden from the environment (containers, CI benches): see
:func:`environment_settings`.
"""

from __future__ import annotations

import ipaddress
import os
import re
import tomllib
import typing
from collections.abc import Mapping
from enum import Enum
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .instructions import MotionSystem, catalog
from .kernel import (
    AxisConfig,
    AxisType,
    ConfigError,
    Controller,
    FeedbackSignal,
    GroupConfig,
    ProgrammedStopMode,
)
from .kernel.config import MAX_PERIOD, MIN_PERIOD

DEMO_MAP = "demo.toml"
#: environment variable naming the site map file used when none is given
MAP_ENV = "MOTION_SERVER_MAP"
#: prefix of the per-setting overrides: MOTION_SERVER_<SECTION>_<FIELD>
ENV_PREFIX = "MOTION_SERVER_"
NAME_RE = r"^[A-Za-z][A-Za-z0-9_]*$"


class SiteMapError(ValueError):
    """A site map that cannot be used; the message names file, line and field."""


def _enum_by_name(enum: type[Enum]) -> Any:
    def parse(value: Any) -> Any:
        if isinstance(value, str):
            try:
                return enum[value.upper()]
            except KeyError:
                names = ", ".join(m.name.lower() for m in enum)
                raise ValueError(f"unknown value {value!r}; expected one of: {names}") from None
        return value

    return parse


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class SiteSection(_Model):
    name: str = Field(default="site", pattern=NAME_RE)
    namespace_uri: str = ""


class ControllerSection(_Model):
    clock: Literal["realtime", "scaled", "manual", "fast"] = "realtime"
    scale: Annotated[float, Field(ge=0.1, le=100.0)] = 1.0
    remote_clock: bool = True
    status_log_interval: Annotated[float, Field(ge=0.0)] = 10.0
    max_catch_up: Annotated[int, Field(ge=1, le=1000)] = 50


class AxisSection(_Model):
    name: str = Field(pattern=NAME_RE)
    number: Annotated[int, Field(ge=1, le=65535)] | None = None
    type: AxisType = AxisType.SERVO
    units: str = "mm"
    conversion_constant: Annotated[float, Field(gt=0.0)] = 1000.0
    rollover: Annotated[float, Field(ge=0.0)] = 0.0
    max_velocity: Annotated[float, Field(gt=0.0)] = 1000.0
    max_acceleration: Annotated[float, Field(gt=0.0)] = 10000.0
    max_deceleration: Annotated[float, Field(gt=0.0)] = 10000.0
    max_jerk: Annotated[float, Field(ge=0.0)] = 0.0
    programmed_stop_mode: ProgrammedStopMode = ProgrammedStopMode.FAST_STOP
    coast_deceleration: Annotated[float, Field(ge=0.0)] = 1000.0
    drive_bandwidth: Annotated[float, Field(gt=0.0, le=10000.0)] = 40.0
    encoder_resolution: Annotated[float, Field(ge=0.0)] = 0.0
    following_error_limit: Annotated[float, Field(ge=0.0)] = 0.0
    feedback_signal: FeedbackSignal = FeedbackSignal.INPUT
    signal_velocity: float = 0.0
    signal_amplitude: float = 0.0
    signal_frequency: Annotated[float, Field(ge=0.0)] = 0.0

    _parse_type = field_validator("type", mode="before")(_enum_by_name(AxisType))
    _parse_stop = field_validator("programmed_stop_mode", mode="before")(
        _enum_by_name(ProgrammedStopMode)
    )
    _parse_signal = field_validator("feedback_signal", mode="before")(_enum_by_name(FeedbackSignal))


class GroupSection(_Model):
    name: str = Field(pattern=NAME_RE)
    number: Annotated[int, Field(ge=1, le=255)] | None = None
    coarse_update_period_ms: Annotated[float, Field(ge=MIN_PERIOD * 1000, le=MAX_PERIOD * 1000)] = (
        2.0
    )
    axes: list[str] = Field(default_factory=list)


class InstanceSection(_Model):
    name: str = Field(pattern=NAME_RE)
    type: str
    operands: dict[str, float | int | bool] = Field(default_factory=dict)
    #: explicit Modbus base register of the instance block (overrides the kind's default)
    modbus_base: Annotated[int, Field(ge=0, le=65535)] | None = None

    @field_validator("type")
    @classmethod
    def _known_type(cls, value: str) -> str:
        types = catalog()
        if value not in types:
            raise ValueError(f"unknown instruction type {value!r}; known: {', '.join(types)}")
        return value

    @model_validator(mode="after")
    def _known_operands(self) -> InstanceSection:
        cls = catalog()[self.type]
        names = {op.name for op in cls.OPERANDS}
        for key in self.operands:
            if key not in names:
                raise ValueError(
                    f"{self.type} has no operand {key!r}; operands: {', '.join(sorted(names))}"
                )
        return self


class InstructionsSection(_Model):
    every_type: bool = False
    instances: list[InstanceSection] = Field(default_factory=list)


class WriteRule(_Model):
    """Who may write what: clients from ``networks`` may write only the tags that
    ``write`` names (a folder ``Instructions``, an owner ``MAJ_1``, a tag ``MAJ_1.Speed``
    or a register range ``"5000-5999"``); an empty list makes them read-only."""

    networks: list[str]
    write: list[str] = Field(default_factory=list)

    @field_validator("networks")
    @classmethod
    def _networks(cls, value: list[str]) -> list[str]:
        for net in value:
            ipaddress.ip_network(net, strict=False)  # ValueError names the bad one
        return value

    @field_validator("write")
    @classmethod
    def _ranges(cls, value: list[str]) -> list[str]:
        for item in value:
            if re.fullmatch(r"\d+\s*-\s*\d+", item):
                lo, hi = (int(x) for x in item.split("-"))
                if not 0 <= lo <= hi <= 65535:
                    raise ValueError(f"bad register range {item!r}")
        return value


class ModbusAccessSection(_Model):
    """Modbus access control (``[modbus.access]``): which client networks may connect
    (``allow``; empty = everyone), read-only mode, per-network write rules (the first
    rule whose networks hold the client decides; no rule = every writable tag),
    connection limit and idle timeout (seconds without a request; 0 = none)."""

    allow: list[str] = Field(default_factory=list)
    read_only: bool = False
    rules: list[WriteRule] = Field(default_factory=list)
    max_connections: Annotated[int, Field(ge=1, le=10000)] = 64
    idle_timeout: Annotated[float, Field(ge=0.0)] = 0.0

    @field_validator("allow")
    @classmethod
    def _networks(cls, value: list[str]) -> list[str]:
        for net in value:
            ipaddress.ip_network(net, strict=False)
        return value


RoleName = Literal["viewer", "operator", "admin"]

#: certificate roles understood without a ``roles`` table in the site map
DEFAULT_CERTIFICATE_ROLES: dict[str, RoleName] = {
    "viewer": "viewer",
    "read": "viewer",
    "operator": "operator",
    "admin": "admin",
}


class ModbusTlsSection(_Model):
    """Modbus/TCP Security (``[modbus.tls]``): Modbus over TLS (1.2 or later) on ``port``
    (802, the standard's; 0 = ephemeral), beside plain Modbus TCP (``tls_only`` turns
    that off). Every client must present a certificate that ``ca_file`` (PEM) verifies.
    The server's own certificate is ``cert_file`` + ``key_file`` (PEM, key unencrypted),
    or, when both are empty, a self-signed pair generated in ``data_dir`` on first start.

    A client's role comes from its certificate's role extension (OID
    1.3.6.1.4.1.50316.802.1, a UTF8String), looked up without regard to case in
    ``roles`` (certificate role -> viewer, operator or admin); a certificate without the
    extension gets ``default_role``; one whose role is not in ``roles`` (or unreadable)
    gets viewer. ``handshake_timeout``: seconds a connection may take to complete the
    handshake."""

    enabled: bool = False
    port: Annotated[int, Field(ge=0, le=65535)] = 802
    tls_only: bool = False
    cert_file: str = ""
    key_file: str = ""
    ca_file: str = ""
    data_dir: str = "modbus-tls-data"
    default_role: RoleName = "viewer"
    roles: dict[str, RoleName] = Field(default_factory=lambda: dict(DEFAULT_CERTIFICATE_ROLES))
    handshake_timeout: Annotated[float, Field(gt=0.0, le=300.0)] = 10.0

    @field_validator("roles")
    @classmethod
    def _roles(cls, value: dict[str, RoleName]) -> dict[str, RoleName]:
        out: dict[str, RoleName] = {}
        for name, role in value.items():
            key = name.strip().lower()
            if not key:
                raise ValueError("an empty certificate role name")
            if key in out and out[key] != role:
                raise ValueError(f"certificate role {name!r} is mapped twice")
            out[key] = role
        return out

    @model_validator(mode="after")
    def _files(self) -> ModbusTlsSection:
        if bool(self.cert_file) != bool(self.key_file):
            raise ValueError("cert_file and key_file go together (or both empty: self-signed)")
        if self.enabled and not self.ca_file:
            raise ValueError("ca_file is required: client certificates are always verified")
        if self.tls_only and not self.enabled:
            raise ValueError("tls_only needs enabled = true (else Modbus would serve nothing)")
        return self


class WatchdogSection(_Model):
    """A communication watchdog (``[[watchdogs]]``): a client must change the tag
    ``<name>.Heartbeat`` at least every ``timeout`` seconds (simulated time), else
    ``group`` is stopped with ``stop_mode`` (an MGS) and the fault is latched.
    ``per_connection``: every client connection that changed the heartbeat is
    supervised on its own (else any change by anyone counts)."""

    name: str = Field(pattern=NAME_RE)
    timeout: Annotated[float, Field(gt=0.0, le=3600.0)]
    group: str
    stop_mode: Literal["programmed", "fast_stop", "fast_disable"] = "programmed"
    per_connection: bool = False


class AuditSection(_Model):
    """Audit log of client writes (``[audit]``): JSON lines, rotated by size. A relative
    ``path`` is taken in the data directory."""

    enabled: bool = False
    path: str = "audit.jsonl"
    max_bytes: Annotated[int, Field(ge=1024)] = 10_000_000
    backups: Annotated[int, Field(ge=0, le=1000)] = 5


class RetainSection(_Model):
    """Retentive memory (``[retain]``): absolute axis positions, homed flags and operand
    values survive a restart. Written at shutdown and every ``interval`` seconds (real
    time; 0 = only at shutdown) to ``path`` (relative: in the data directory)."""

    enabled: bool = False
    path: str = "retain.json"
    interval: Annotated[float, Field(ge=0.0)] = 10.0
    #: axes with absolute feedback: their positions are retained
    axes: list[str] = Field(default_factory=list)


class ModbusSection(_Model):
    """Modbus TCP front-end. ``port = 0`` binds an ephemeral port (tests); ``unit_id = 0``
    answers every unit id. The bases place the register blocks of each kind (see
    ``motion_server.tagmap.layout``). ``access``: who may connect and write; ``tls``:
    Modbus/TCP Security beside (or instead of) plain Modbus TCP."""

    enabled: bool = True
    host: str = "127.0.0.1"
    port: Annotated[int, Field(ge=0, le=65535)] = 5020
    unit_id: Annotated[int, Field(ge=0, le=255)] = 1
    word_order: Literal["big", "little"] = "big"
    group_base: Annotated[int, Field(ge=100, le=65534, multiple_of=2)] = 100
    axis_base: Annotated[int, Field(ge=100, le=65534, multiple_of=2)] = 1000
    instruction_base: Annotated[int, Field(ge=100, le=65534, multiple_of=2)] = 5000
    #: ``every_type`` instances: block at every_type_base + 100·(type code − 1)
    every_type_base: Annotated[int, Field(ge=100, le=60000, multiple_of=2)] = 20000
    #: watchdog blocks (``[[watchdogs]]``): safety_base + 20·k
    safety_base: Annotated[int, Field(ge=100, le=65000, multiple_of=2)] = 900
    access: ModbusAccessSection = ModbusAccessSection()
    tls: ModbusTlsSection = ModbusTlsSection()


HASH_RE = r"^scrypt\$\d+\$\d+\$\d+\$[A-Za-z0-9+/=]+\$[A-Za-z0-9+/=]+$"
#: environment variable naming the users secret file (TOML, ``[[users]]`` entries)
USERS_FILE_ENV = "MOTION_SERVER_USERS_FILE"
#: the users secret file used when the variable is not set and this file exists
DEFAULT_USERS_FILE = "/run/secrets/motion_server_users"


SecurityPolicy = Literal["Basic256Sha256_Sign", "Basic256Sha256_SignAndEncrypt"]


class OpcUaUser(_Model):
    """An OPC UA user: ``password_hash`` from ``motion-server hash-password``."""

    name: str = Field(min_length=1, max_length=64)
    role: Literal["viewer", "operator", "admin"] = "viewer"
    password_hash: str = Field(pattern=HASH_RE)


class OpcUaSection(_Model):
    """OPC UA front-end. ``port = 0`` binds an ephemeral port (tests). The server
    certificate and key are generated in ``data_dir`` on first start and kept there.
    Anonymous access and the None endpoint are off unless asked for, and honoured only on
    a loopback bind unless ``allow_insecure_remote`` is set as well."""

    enabled: bool = True
    host: str = "127.0.0.1"
    port: Annotated[int, Field(ge=0, le=65535)] = 4840
    data_dir: str = "opcua-data"
    security_policies: list[SecurityPolicy] = Field(
        default_factory=lambda: list(typing.get_args(SecurityPolicy)), min_length=1
    )
    allow_anonymous: bool = False
    anonymous_role: Literal["viewer", "operator", "admin"] = "viewer"
    allow_none_endpoint: bool = False
    #: anonymous access and the None endpoint are honoured on a loopback bind only,
    #: unless this is set too (the server drops both, with a warning, otherwise)
    allow_insecure_remote: bool = False
    users: list[OpcUaUser] = Field(default_factory=list)
    #: how often changed values are pushed to the OPC UA nodes
    publish_rate_hz: Annotated[float, Field(gt=0.0, le=1000.0)] = 20.0
    #: absolute deadband of analog (REAL/LREAL) values; 0 publishes every change
    deadband: Annotated[float, Field(ge=0.0)] = 0.0
    #: node updates per chunk before the publisher yields to the event loop
    chunk_size: Annotated[int, Field(ge=1, le=100000)] = 100
    max_sessions: Annotated[int, Field(ge=1, le=10000)] = 100
    #: transport limits (asyncua's defaults allow 100 MB messages): the largest chunk
    #: (OPC UA's minimum is 8192 bytes), chunks per message and message size we accept
    max_chunk_size: Annotated[int, Field(ge=8192, le=1 << 24)] = 65535
    max_chunk_count: Annotated[int, Field(ge=1, le=100000)] = 64
    max_message_size: Annotated[int, Field(ge=8192, le=100 << 20)] = 4 << 20
    max_subscriptions: Annotated[int, Field(ge=1, le=10000)] = 100
    max_session_timeout_s: Annotated[float, Field(ge=5.0, le=86400.0)] = 600.0
    #: seconds a TCP connection may stay silent (no byte received) before it is closed;
    #: a connection with an activated session gets its session timeout if that is longer
    #: (conforming clients talk at least that often). 0: never close for silence
    idle_timeout: Annotated[float, Field(ge=0.0, le=86400.0)] = 60.0
    #: failed logins per client address within ``login_window_s`` before a lockout
    max_login_failures: Annotated[int, Field(ge=1, le=1000)] = 5
    login_window_s: Annotated[float, Field(gt=0.0)] = 60.0
    login_lockout_s: Annotated[float, Field(ge=0.0)] = 30.0
    #: OperationLimits, published in Server.ServerCapabilities.OperationLimits: the most
    #: operations one request may carry (more: BadTooManyOperations); 0: no limit
    max_nodes_per_read: Annotated[int, Field(ge=0, le=1000000)] = 1000
    max_nodes_per_write: Annotated[int, Field(ge=0, le=1000000)] = 1000
    max_nodes_per_browse: Annotated[int, Field(ge=0, le=1000000)] = 100
    max_nodes_per_translate_browse_paths: Annotated[int, Field(ge=0, le=1000000)] = 100
    max_nodes_per_register_nodes: Annotated[int, Field(ge=0, le=1000000)] = 1000
    max_nodes_per_method_call: Annotated[int, Field(ge=0, le=1000000)] = 100
    #: HistoryRead, of data and of events alike
    max_nodes_per_history_read: Annotated[int, Field(ge=0, le=1000000)] = 100
    #: AddNodes, AddReferences, DeleteNodes, DeleteReferences
    max_nodes_per_node_management: Annotated[int, Field(ge=0, le=1000000)] = 100
    #: CreateMonitoredItems, ModifyMonitoredItems, SetMonitoringMode, DeleteMonitoredItems
    max_monitored_items_per_call: Annotated[int, Field(ge=0, le=1000000)] = 1000
    #: per session: subscriptions (more: BadTooManySubscriptions) and monitored items in
    #: all of them (each item past it: BadTooManyMonitoredItems); 0: no limit
    max_subscriptions_per_session: Annotated[int, Field(ge=0, le=10000)] = 10
    max_monitored_items_per_session: Annotated[int, Field(ge=0, le=1000000)] = 10000


class UsersFile(_Model):
    """The users secret file: ``[[users]]`` entries like ``[[opcua.users]]``."""

    users: list[OpcUaUser] = Field(default_factory=list)


class SiteMap(_Model):
    site: SiteSection = SiteSection()
    controller: ControllerSection = ControllerSection()
    axes: list[AxisSection]
    groups: list[GroupSection]
    instructions: InstructionsSection = InstructionsSection()
    modbus: ModbusSection = ModbusSection()
    opcua: OpcUaSection = OpcUaSection()
    watchdogs: list[WatchdogSection] = Field(default_factory=list)
    audit: AuditSection = AuditSection()
    retain: RetainSection = RetainSection()
    #: directory of the audit log and the retain file (relative: to the working directory)
    data_dir: str = "."
    #: where the map came from (for messages); not a TOML field
    source: str = Field("<memory>", exclude=True)

    # -- derived --------------------------------------------------------------------------
    def axis_configs(self) -> list[AxisConfig]:
        out = []
        for i, a in enumerate(self.axes):
            data = a.model_dump()
            data["number"] = a.number or i + 1
            out.append(AxisConfig(**data))
        return out

    def group_configs(self) -> list[GroupConfig]:
        numbers = {a.name: a.number for a in self.axis_configs()}
        return [
            GroupConfig(
                number=g.number or i + 1,
                name=g.name,
                axes=tuple(numbers[name] for name in g.axes),
                coarse_update_period=g.coarse_update_period_ms / 1000.0,
            )
            for i, g in enumerate(self.groups)
        ]

    def instances(self) -> list[InstanceSection]:
        """Declared instances, then ``<TYPE>_1`` for every type when ``every_type``."""
        out = list(self.instructions.instances)
        if self.instructions.every_type:
            names = {i.name for i in out}
            for type_name in catalog():
                name = f"{type_name}_1"
                if name not in names:
                    out.append(InstanceSection(name=name, type=type_name))
        return out

    def build(self) -> MotionSystem:
        """The controller and its instruction instances."""
        try:
            ctl = Controller(self.axis_configs(), self.group_configs())
        except ConfigError as exc:
            raise SiteMapError(f"{self.source}: {exc}") from exc
        system = MotionSystem(ctl)
        for inst in self.instances():
            system.add(inst.type, inst.name, inst.operands)
        return system

    def problems(self) -> list[tuple[tuple[int | str, ...], str]]:
        """Cross-field checks: (location, message) pairs, empty when the map is sound."""
        out: list[tuple[tuple[int | str, ...], str]] = []
        out += _duplicates([a.name for a in self.axes], ("axes",), "name")
        out += _duplicates([a.number for a in self.axes], ("axes",), "number")
        out += _duplicates([g.name for g in self.groups], ("groups",), "name")
        out += _duplicates(
            [i.name for i in self.instructions.instances], ("instructions", "instances"), "name"
        )
        out += _duplicates([u.name for u in self.opcua.users], ("opcua", "users"), "name")
        out += _duplicates([w.name for w in self.watchdogs], ("watchdogs",), "name")
        groups = {g.name for g in self.groups}
        for wi, w in enumerate(self.watchdogs):
            if w.group not in groups:
                out.append((("watchdogs", wi, "group"), f"watchdog {w.name}: unknown group"))
        known = {a.name for a in self.axes}
        for gi, g in enumerate(self.groups):
            for name in g.axes:
                if name not in known:
                    out.append((("groups", gi, "axes"), f"group {g.name}: unknown axis {name!r}"))
        return out


def _duplicates(
    values: list[Any], where: tuple[str, ...], field: str
) -> list[tuple[tuple[int | str, ...], str]]:
    seen: set[Any] = set()
    out: list[tuple[tuple[int | str, ...], str]] = []
    for i, v in enumerate(values):
        if v is None:
            continue
        if v in seen:
            out.append(((*where, i, field), f"duplicate {field} {v!r}"))
        seen.add(v)
    return out


# -- loading -------------------------------------------------------------------------------


def _locate(text: str, loc: tuple[int | str, ...]) -> int:
    """Best line number (1-based) for a pydantic error location in TOML text: the line of
    the field's assignment, else of its table header, else of the enclosing table."""
    lines = text.splitlines()
    line, start, end = 1, 0, len(lines)
    i = 0
    while i < len(loc):
        key = loc[i]
        idx: int | None = None
        if i + 1 < len(loc):
            following = loc[i + 1]
            if isinstance(following, int):
                idx = following
        i += 1 if idx is None else 2
        if not isinstance(key, str):
            continue
        header = re.compile(rf"^\s*\[\[?\s*(?:[\w.]+\.)?{re.escape(key)}\s*\]\]?\s*(?:#.*)?$")
        hits = [n for n in range(start, end) if header.match(lines[n])]
        if hits:
            n = hits[idx] if idx is not None and idx < len(hits) else hits[0]
            line, start = n + 1, n + 1
            # the table runs to the next header that is not one of its own sub-tables
            end = next(
                (
                    m
                    for m in range(start, len(lines))
                    if lines[m].lstrip().startswith("[") and f"{key}." not in lines[m]
                ),
                len(lines),
            )
            continue
        assign = re.compile(rf"^\s*{re.escape(key)}\s*=")
        n2 = next((m for m in range(start, end) if assign.match(lines[m])), None)
        if n2 is None:
            # a dotted header names this key with the next one ([[instructions.instances]])
            if i < len(loc) and isinstance(loc[i], str):
                continue
            break
        line = n2 + 1
    return line


def parse(text: str, source: str = "<memory>", environ: Mapping[str, str] | None = None) -> SiteMap:
    """Validate a site map text; ``environ`` settings (see :func:`environment_settings`)
    replace the TOML values before validation, so every check sees them."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SiteMapError(f"{source}: invalid TOML: {exc}") from exc
    overrides = environment_settings(environ or {})
    for (section, field), (_, value) in overrides.items():
        table = data.setdefault(section, {})
        if isinstance(table, dict):
            table[field] = value
    try:
        site = SiteMap.model_validate({**data, "source": source})
    except ValidationError as exc:
        found = [(tuple(e["loc"]), e["msg"].removeprefix("Value error, ")) for e in exc.errors()]
    else:
        found = site.problems()
        if not found:
            from .tagmap import layout_problems  # the tag map builds on this module

            found = layout_problems(site)
    if found:
        lines = []
        for loc, msg in found:
            field = ".".join(str(p) for p in loc) or "(top level)"
            var = overrides.get((str(loc[0]), str(loc[1]))) if len(loc) > 1 else None
            if var:
                lines.append(f"{source}: environment {var[0]}: {msg}")
            else:
                lines.append(f"{source}:{_locate(text, loc)}: {field}: {msg}")
        raise SiteMapError("\n".join(lines))
    return site


def environment_settings(environ: Mapping[str, str]) -> dict[tuple[str, str], tuple[str, str]]:
    """``MOTION_SERVER_<SECTION>_<FIELD>`` variables: (section, field) -> (variable, value).

    Every field of a single-table section (``[site]``, ``[controller]``, ``[modbus]``, ...)
    can be set this way, e.g. ``MOTION_SERVER_MODBUS_HOST=0.0.0.0`` in a container or
    ``MOTION_SERVER_CONTROLLER_CLOCK=manual`` on a test bench. The values are validated like
    the TOML ones; an invalid one is a :class:`SiteMapError` naming the variable.
    """
    found: dict[tuple[str, str], tuple[str, str]] = {}
    for section, info in SiteMap.model_fields.items():
        model = info.annotation
        if not (isinstance(model, type) and issubclass(model, _Model)):
            continue
        for field in model.model_fields:
            var = f"{ENV_PREFIX}{section}_{field}".upper()
            if var in environ:
                found[(section, field)] = (var, environ[var])
    return found


def load(path: str | Path | None = None, environ: Mapping[str, str] | None = None) -> SiteMap:
    """Load a site map file, or (``path`` None) the file named by ``MOTION_SERVER_MAP``,
    else the embedded demo map, with the settings of the environment (``environ``,
    default ``os.environ``) applied."""
    env = os.environ if environ is None else environ
    if path is None and env.get(MAP_ENV):
        path = env[MAP_ENV]
    if path is None:
        text = resources.files("motion_server").joinpath("data", DEMO_MAP).read_text("utf-8")
        return parse(text, f"<embedded {DEMO_MAP}>", env)
    p = Path(path)
    try:
        text = p.read_text("utf-8")
    except OSError as exc:
        raise SiteMapError(f"{p}: cannot read site map: {exc.strerror}") from exc
    return parse(text, str(p), env)


def users_file_path(environ: dict[str, str] | None = None) -> Path | None:
    """The users secret file: ``$MOTION_SERVER_USERS_FILE``, else
    ``/run/secrets/motion_server_users`` when it exists, else None."""
    env = os.environ if environ is None else environ
    named = env.get(USERS_FILE_ENV)
    if named:
        return Path(named)
    default = Path(DEFAULT_USERS_FILE)
    return default if default.is_file() else None


def load_users_file(path: str | Path) -> list[OpcUaUser]:
    """The ``[[users]]`` of a users secret file; :class:`SiteMapError` naming file, line
    and field (never the hash itself) when it cannot be used."""
    p = Path(path)
    try:
        text = p.read_text("utf-8")
    except OSError as exc:
        raise SiteMapError(f"{p}: cannot read users file: {exc.strerror}") from exc
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SiteMapError(f"{p}: invalid TOML: {exc}") from exc
    try:
        parsed = UsersFile.model_validate(data)
    except ValidationError as exc:
        lines = []
        for e in exc.errors():
            loc = tuple(e["loc"])
            msg = e["msg"].removeprefix("Value error, ")
            if loc and loc[-1] == "password_hash":
                msg = "not a password hash (motion-server hash-password prints one)"
            lines.append(f"{p}:{_locate(text, loc)}: {'.'.join(map(str, loc))}: {msg}")
        raise SiteMapError("\n".join(lines)) from None
    problems = _duplicates([u.name for u in parsed.users], ("users",), "name")
    if problems:
        raise SiteMapError(
            "\n".join(
                f"{p}:{_locate(text, loc)}: {'.'.join(map(str, loc))}: {m}" for loc, m in problems
            )
        )
    return parsed.users


def opcua_users(site: SiteMap, environ: dict[str, str] | None = None) -> list[OpcUaUser]:
    """The site map's OPC UA users, overridden by name by those of the users secret file."""
    users = {u.name: u for u in site.opcua.users}
    path = users_file_path(environ)
    if path is not None:
        users |= {u.name: u for u in load_users_file(path)}
    return list(users.values())
