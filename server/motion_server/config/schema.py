"""Site-map schema: the sections of a site map as pydantic models, their cross-field
checks, and the kernel configuration they describe.

Every number is finite (TOML's ``inf`` and ``nan`` are refused everywhere). Axis
attributes follow the Logix axis object (Rockwell MOTION-RM003): they are REALs, so a
limit, rate or signal is at most :data:`REAL_MAX` in magnitude, and the conversion
constant (feedback counts per position unit) lies in [1e-12, 1e12]. The axis fields and
their defaults are those of :class:`~motion_server.kernel.AxisConfig` (the kernel's
dataclass is the one definition; a test keeps the two field lists equal).

This module reads no file and builds nothing: :mod:`.loading` turns TOML text into a
:class:`SiteMap` and names file and line for every problem; :mod:`.assembly` builds the
running system from it.
"""

from __future__ import annotations

import ipaddress
import os
import re
import struct
import typing
from collections.abc import Mapping, Sequence
from enum import Enum
from typing import Annotated, Any, Literal, Protocol

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationInfo,
    field_validator,
    model_validator,
)

from ..instructions import MotionSystem, catalog
from ..kernel import (
    AxisConfig,
    AxisType,
    ConfigError,
    Controller,
    FeedbackSignal,
    GroupConfig,
    ProgrammedStopMode,
)
from ..kernel.appl_limits import long_ramps
from ..kernel.cam_tables import MAX_CAM_POINTS, CamTableConfig
from ..kernel.config import MAX_PERIOD, MIN_PERIOD
from ..kernel.enums import HomeDirection, HomeMode, HomeSequence
from ..kernel.trapezoid import MAX_DURATION
from ..safety.passwords import parse_hash
from .checks import Problem, duplicates, number_clashes, operand_problem, period_problems

DEMO_MAP = "demo.toml"
#: environment variable naming the site map file used when none is given
MAP_ENV = "MOTION_SERVER_MAP"
#: prefix of the per-setting overrides: MOTION_SERVER_<SECTION>_<FIELD>
ENV_PREFIX = "MOTION_SERVER_"
#: environment variable naming the data directory of a site map that sets no ``data_dir``
DATA_DIR_ENV = "MOTION_SERVER_DATA_DIR"
NAME_RE = r"^[A-Za-z][A-Za-z0-9_]*$"
#: the longest name of a site, axis, group, instance or watchdog: a Logix tag name's 40
#: characters (names become tag names, node ids and the lines of every export)
NAME_MAX = 40
#: the largest and the smallest normal Logix REAL (IEEE 754 binary32): axis attributes
#: are REALs, and a positive limit below the normal range makes no stop computable (a
#: speed over a deceleration of 5e-324 is an infinite time)
REAL_MAX = 3.4028234663852886e38
REAL_MIN = 1.1754943508222875e-38
#: the longest time a limit may imply: reaching max_velocity at max_acceleration, stopping
#: from it at max_deceleration, reaching either rate at max_jerk. The longest profile the
#: kernel plans (about two hours, beyond any machine; more is a rate in the wrong units): a
#: limit beyond it would make a group stop from max_velocity a plan the kernel refuses
MAX_RAMP_TIME = MAX_DURATION
#: feedback counts per position unit: the Logix Conversion Constant range (MOTION-RM003)
MIN_COUNTS_PER_UNIT = 1e-12
MAX_COUNTS_PER_UNIT = 1e12


class SiteMapError(ValueError):
    """A site map that cannot be used; every line of the message names file, line and
    field (or the environment variable) of one problem."""


class Locator(Protocol):
    """Where the fields of a site map were written (see :class:`.loading.Locations`)."""

    def describe(self, loc: Sequence[int | str], message: str) -> str: ...

    def overridden(self, origins: Mapping[tuple[str, str], str]) -> Locator: ...


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


def _ip_address(value: str) -> str:
    try:
        ipaddress.ip_address(value)
    except ValueError:
        raise ValueError(
            f"{value!r} is not an IP address (a bind address such as 127.0.0.1, 0.0.0.0 or ::)"
        ) from None
    return value


def _no_nul(value: str) -> str:
    if "\0" in value:
        raise ValueError("a path cannot contain a NUL character")
    return value


def _within(lo: float, hi: float, zero: bool = False) -> AfterValidator:
    """A bound check whose message prints the bounds as numbers are written (``1e+12``,
    not forty digits); ``zero``: 0 is allowed too (off, or unlimited)."""
    allowed = f"0 or {lo:.7g}..{hi:.7g}" if zero else f"{lo:.7g}..{hi:.7g}"

    def check(value: float) -> float:
        if not (lo <= value <= hi or (zero and value == 0.0)):
            raise ValueError(f"{value:.7g} is outside {allowed}")
        return value

    return AfterValidator(check)


def _short_name(value: Any) -> Any:
    if isinstance(value, str) and len(value) > NAME_MAX:
        raise ValueError(
            f"a name of {len(value)} characters (at most {NAME_MAX}, as a Logix tag name): "
            f"{value[:20]!r}..."
        )
    return value


#: a name that becomes a tag name: a letter, then letters, digits and _, 40 at most
Name = Annotated[str, BeforeValidator(_short_name), Field(pattern=NAME_RE)]
#: an IP address to bind to
BindAddress = Annotated[str, AfterValidator(_ip_address)]
#: a file or directory name (relative ones as the section says)
PathText = Annotated[str, Field(min_length=1), AfterValidator(_no_nul)]
#: a file name that may be left empty
OptionalPath = Annotated[str, AfterValidator(_no_nul)]
#: a magnitude a Logix REAL can hold
Real = Annotated[float, _within(-REAL_MAX, REAL_MAX)]
NonNegativeReal = Annotated[float, _within(0.0, REAL_MAX)]
#: a positive REAL of the normal range
PositiveReal = Annotated[float, _within(REAL_MIN, REAL_MAX)]
#: 0 (off, or unlimited: as the field says) or a positive REAL
ZeroOrReal = Annotated[float, _within(REAL_MIN, REAL_MAX, zero=True)]
CountsPerUnit = Annotated[float, _within(MIN_COUNTS_PER_UNIT, MAX_COUNTS_PER_UNIT)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class SiteSection(_Model):
    name: Name = "site"
    namespace_uri: str = ""


class ControllerSection(_Model):
    clock: Literal["realtime", "scaled", "manual", "fast"] = "realtime"
    scale: Annotated[float, Field(ge=0.1, le=100.0)] = 1.0
    remote_clock: bool = True
    status_log_interval: Annotated[float, Field(ge=0.0, le=86400.0)] = 10.0
    max_catch_up: Annotated[int, Field(ge=1, le=1000)] = 50
    #: units of client writes a cycle applies (scan/writes.py); unset: 8 per ms of period
    write_budget: Annotated[int, Field(ge=1, le=1_000_000)] | None = None


#: the kernel's defaults: one definition of every axis field's default
_AXIS = AxisConfig(number=1, name="Axis1")


class AxisSection(_Model):
    """An axis (``[[axes]]``): the fields of :class:`~motion_server.kernel.AxisConfig`,
    with its defaults; ``number`` defaults to the axis's place in the list (1-based)."""

    name: Name
    number: Annotated[int, Field(ge=1, le=65535)] | None = None
    type: AxisType = _AXIS.type
    units: str = Field(default=_AXIS.units, max_length=32)
    conversion_constant: CountsPerUnit = _AXIS.conversion_constant
    rollover: ZeroOrReal = _AXIS.rollover
    max_velocity: PositiveReal = _AXIS.max_velocity
    max_acceleration: PositiveReal = _AXIS.max_acceleration
    max_deceleration: PositiveReal = _AXIS.max_deceleration
    max_jerk: ZeroOrReal = _AXIS.max_jerk
    programmed_stop_mode: ProgrammedStopMode = _AXIS.programmed_stop_mode
    coast_deceleration: ZeroOrReal = _AXIS.coast_deceleration
    drive_bandwidth: Annotated[float, Field(gt=0.0, le=10000.0)] = _AXIS.drive_bandwidth
    encoder_resolution: Annotated[
        float, _within(MIN_COUNTS_PER_UNIT, MAX_COUNTS_PER_UNIT, zero=True)
    ] = _AXIS.encoder_resolution
    following_error_limit: NonNegativeReal = _AXIS.following_error_limit
    feedback_signal: FeedbackSignal = _AXIS.feedback_signal
    signal_velocity: Real = _AXIS.signal_velocity
    signal_amplitude: Real = _AXIS.signal_amplitude
    signal_frequency: NonNegativeReal = _AXIS.signal_frequency
    home_mode: HomeMode = _AXIS.home_mode
    home_sequence: HomeSequence = _AXIS.home_sequence
    home_direction: HomeDirection = _AXIS.home_direction
    home_position: Real = _AXIS.home_position
    home_offset: Real = _AXIS.home_offset
    home_speed: ZeroOrReal = _AXIS.home_speed
    home_return_speed: ZeroOrReal = _AXIS.home_return_speed
    home_acceleration: ZeroOrReal = _AXIS.home_acceleration
    home_deceleration: ZeroOrReal = _AXIS.home_deceleration
    home_switch: Real | None = _AXIS.home_switch
    home_switch_width: ZeroOrReal = _AXIS.home_switch_width
    marker_interval: ZeroOrReal = _AXIS.marker_interval
    marker_offset: Real = _AXIS.marker_offset

    _parse_type = field_validator("type", mode="before")(_enum_by_name(AxisType))
    _parse_stop = field_validator("programmed_stop_mode", mode="before")(
        _enum_by_name(ProgrammedStopMode)
    )
    _parse_signal = field_validator("feedback_signal", mode="before")(_enum_by_name(FeedbackSignal))
    _parse_home_mode = field_validator("home_mode", mode="before")(_enum_by_name(HomeMode))
    _parse_home_sequence = field_validator("home_sequence", mode="before")(
        _enum_by_name(HomeSequence)
    )
    _parse_home_direction = field_validator("home_direction", mode="before")(
        _enum_by_name(HomeDirection)
    )


class GroupSection(_Model):
    name: Name
    number: Annotated[int, Field(ge=1, le=255)] | None = None
    coarse_update_period_ms: Annotated[float, Field(ge=MIN_PERIOD * 1000, le=MAX_PERIOD * 1000)] = (
        2.0
    )
    axes: list[str] = Field(default_factory=list)


class InstanceSection(_Model):
    name: Name
    type: str
    operands: dict[str, Any] = Field(default_factory=dict)
    #: explicit Modbus base register of the instance block (overrides the kind's default)
    modbus_base: Annotated[int, Field(ge=0, le=65535)] | None = None

    @field_validator("type")
    @classmethod
    def _known_type(cls, value: str) -> str:
        types = catalog()
        if value not in types:
            raise ValueError(f"unknown instruction type {value!r}; known: {', '.join(types)}")
        return value

    @field_validator("operands")
    @classmethod
    def _known_operands(cls, value: dict[str, Any], info: ValidationInfo) -> dict[str, Any]:
        type_name = info.data.get("type")
        if type_name is None:  # the type itself was refused
            return value
        ops = {op.name: op for op in catalog()[type_name].OPERANDS}
        for key, item in value.items():
            op = ops.get(key)
            if op is None:
                raise ValueError(
                    f"{type_name} has no operand {key!r}; operands: {', '.join(sorted(ops))}"
                )
            problem = operand_problem(op, item)
            if problem:
                raise ValueError(f"{key}: {problem}")
        return value


#: the DINT range (a cam point's segment type)
DINT_MIN, DINT_MAX = -(2**31), 2**31 - 1


def _cam_point(value: Any) -> Any:
    """A point is written ``[master, slave, segment_type]``: say so when it is not."""
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise ValueError(
            f"{value!r} is not a point: write [master, slave, segment_type] "
            "(two numbers and an integer)"
        )
    return value


CamPoint = Annotated[
    tuple[
        Annotated[float, Field(strict=True), _within(-REAL_MAX, REAL_MAX)],
        Annotated[float, Field(strict=True), _within(-REAL_MAX, REAL_MAX)],
        Annotated[int, Field(strict=True, ge=DINT_MIN, le=DINT_MAX)],
    ],
    BeforeValidator(_cam_point),
]


class CamSection(_Model):
    """A cam table (``[[cams]]``): the Logix CAM array a client writes as tags, and its
    CAM_PROFILE. ``number`` defaults to the table's place in the list (1-based);
    ``capacity`` (points, 2..1000) to the number of initial ``points`` (at least 2);
    ``length`` (the points MC_CamTableSelect uses) to the number of initial points.
    ``points``: ``[master, slave, segment_type]`` triples; the segment type is any
    integer (MCCP judges it: 0 linear, 1 cubic)."""

    name: str = Field(pattern=NAME_RE)
    number: Annotated[int, Field(ge=1, le=65535)] | None = None
    capacity: Annotated[int, Field(ge=2, le=MAX_CAM_POINTS)] | None = None
    length: Annotated[int, Field(ge=2, le=MAX_CAM_POINTS)] | None = None
    points: Annotated[list[CamPoint], Field(max_length=MAX_CAM_POINTS)] = Field(
        default_factory=list
    )

    @property
    def size(self) -> int:
        """The capacity, given or by default."""
        return self.capacity if self.capacity is not None else max(2, len(self.points))


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
    connection limit and idle timeout (seconds without a complete request before a
    connection is closed; default 60, 0 = never). ``role``: what a plain Modbus TCP client
    may write (viewer, operator or admin, as the roles of OPC UA users); unset, admin on a
    map that defines no users and no TLS roles, operator on one that does."""

    allow: list[str] = Field(default_factory=list)
    read_only: bool = False
    role: Literal["viewer", "operator", "admin"] | None = None
    rules: list[WriteRule] = Field(default_factory=list)
    max_connections: Annotated[int, Field(ge=1, le=10000)] = 64
    idle_timeout: Annotated[float, Field(ge=0.0)] = 60.0

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
    cert_file: OptionalPath = ""
    key_file: OptionalPath = ""
    ca_file: OptionalPath = ""
    data_dir: PathText = "modbus-tls-data"
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

    name: Name
    timeout: Annotated[float, Field(gt=0.0, le=3600.0)]
    group: str
    stop_mode: Literal["programmed", "fast_stop", "fast_disable"] = "programmed"
    per_connection: bool = False


class AuditSection(_Model):
    """Audit log of client writes (``[audit]``): JSON lines, rotated by size. A relative
    ``path`` is taken in the data directory."""

    enabled: bool = False
    path: PathText = "audit.jsonl"
    max_bytes: Annotated[int, Field(ge=1024)] = 10_000_000
    backups: Annotated[int, Field(ge=0, le=1000)] = 5


class RetainSection(_Model):
    """Retentive memory (``[retain]``): absolute axis positions, homed flags and operand
    values survive a restart. Written at shutdown and every ``interval`` seconds (real
    time; 0 = only at shutdown) to ``path`` (relative: in the data directory)."""

    enabled: bool = False
    path: PathText = "retain.json"
    interval: Annotated[float, Field(ge=0.0, le=86400.0)] = 10.0
    #: axes with absolute feedback: their positions are retained
    axes: list[str] = Field(default_factory=list)


class ModbusSection(_Model):
    """Modbus TCP front-end. ``port = 0`` binds an ephemeral port (tests); ``unit_id = 0``
    answers every unit id. The bases place the register blocks of each kind (see
    ``motion_server.tagmap.layout``). ``access``: who may connect and write; ``tls``:
    Modbus/TCP Security beside (or instead of) plain Modbus TCP."""

    enabled: bool = True
    host: BindAddress = "127.0.0.1"
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
    #: axis configuration blocks (read-only, and the REAL mirrors): axis_config_base + 50·k;
    #: unset: 3000 when the axis blocks end there (up to 40 axes at the default axis_base),
    #: else the first multiple of 1000 after every other block
    axis_config_base: Annotated[int, Field(ge=100, le=65000, multiple_of=2)] | None = None
    #: cam table blocks (``[[cams]]``): unset: 30000 when every other block ends there,
    #: else the first multiple of 1000 after them (see ``motion_server.tagmap.layout``)
    cam_base: Annotated[int, Field(ge=100, le=65000, multiple_of=2)] | None = None
    #: float32 (REAL) copies of the LREAL axis values, for panels that cannot read LREAL
    real_mirrors: bool = False
    access: ModbusAccessSection = ModbusAccessSection()
    tls: ModbusTlsSection = ModbusTlsSection()


class EthernetIpAccessSection(_Model):
    """EtherNet/IP access (``[ethernetip.access]``). EtherNet/IP has no users, so the site
    map decides: ``allow``: the networks a client may connect from (empty = everyone);
    ``role``: what a client that no rule matches may write (``viewer``, the default: read
    only); ``rules``: the first rule whose ``networks`` hold the client lets it write the
    tags its ``write`` entries name (folders, owners, tags: as ``[modbus.access]``), with
    the rights of an operator (Clock tags: admin only). ``max_sessions``: open TCP
    connections at most; ``idle_timeout``: seconds without a complete request before a
    connection is closed (0 = never)."""

    allow: list[str] = Field(default_factory=list)
    role: Literal["viewer", "operator", "admin"] = "viewer"
    rules: list[WriteRule] = Field(default_factory=list)
    max_sessions: Annotated[int, Field(ge=1, le=10000)] = 64
    idle_timeout: Annotated[float, Field(ge=0.0)] = 60.0

    @field_validator("allow")
    @classmethod
    def _networks(cls, value: list[str]) -> list[str]:
        for net in value:
            ipaddress.ip_network(net, strict=False)
        return value


class EthernetIpSection(_Model):
    """EtherNet/IP front-end (``[ethernetip]``): the map's tags as native Logix tags (CIP
    over TCP, ``docs/ethernetip.md``). ``port = 0`` binds an ephemeral port (tests);
    ``slot``: the backplane slot the controller says it sits in (a route to any slot is
    answered)."""

    enabled: bool = False
    host: BindAddress = "127.0.0.1"
    port: Annotated[int, Field(ge=0, le=65535)] = 44818
    slot: Annotated[int, Field(ge=0, le=16)] = 0
    access: EthernetIpAccessSection = EthernetIpAccessSection()


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

    @field_validator("password_hash")
    @classmethod
    def _computable(cls, value: str) -> str:
        try:
            parse_hash(value)
        except ValueError as exc:
            # the message names the cost, never the hash itself
            raise ValueError(f"unusable password hash: {exc}") from None
        return value


class OpcUaSection(_Model):
    """OPC UA front-end. ``port = 0`` binds an ephemeral port (tests). The server
    certificate and key are generated in ``data_dir`` on first start and kept there.
    Anonymous access and the None endpoint are off unless asked for, and honoured only on
    a loopback bind unless ``allow_insecure_remote`` is set as well."""

    enabled: bool = True
    host: BindAddress = "127.0.0.1"
    port: Annotated[int, Field(ge=0, le=65535)] = 4840
    data_dir: PathText = "opcua-data"
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
    max_chunk_size: Annotated[int, Field(ge=8192, le=1 << 24)] = 65536
    max_chunk_count: Annotated[int, Field(ge=1, le=100000)] = 64
    max_message_size: Annotated[int, Field(ge=8192, le=100 << 20)] = 4 << 20
    max_subscriptions: Annotated[int, Field(ge=1, le=10000)] = 100
    #: asyncua and node-opcua clients ask for one hour; a lower maximum makes them warn
    max_session_timeout_s: Annotated[float, Field(ge=5.0, le=86400.0)] = 3600.0
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
    #: subscriptions of all the sessions from one client address (more:
    #: BadTooManySubscriptions), so that one client cannot take every slot; 0: no limit
    max_subscriptions_per_client: Annotated[int, Field(ge=0, le=10000)] = 50
    #: TranslateBrowsePathsToNodeIds: elements of one browse path (more: that path's
    #: result is BadQueryTooComplex) and of all the paths of a request (more:
    #: BadTooManyOperations); 0: no limit
    max_browse_path_elements: Annotated[int, Field(ge=0, le=100000)] = 32
    max_browse_path_elements_per_request: Annotated[int, Field(ge=0, le=1000000)] = 1000

    @model_validator(mode="after")
    def _consistent_limits(self) -> OpcUaSection:
        # a peer checks that the chunks can carry the largest message (node-opcua warns)
        if self.max_chunk_size * self.max_chunk_count < self.max_message_size:
            raise ValueError(
                f"max_chunk_size × max_chunk_count ({self.max_chunk_size} × "
                f"{self.max_chunk_count} = {self.max_chunk_size * self.max_chunk_count}) is less "
                f"than max_message_size ({self.max_message_size}): raise max_chunk_count to "
                f"{-(-self.max_message_size // self.max_chunk_size)} or lower max_message_size"
            )
        return self


class WebSection(_Model):
    """The web view (``docs/web.md``): one page and a WebSocket, on loopback by default.
    ``port = 0`` binds an ephemeral port (tests). ``cert_file`` with ``key_file``: HTTPS.
    Users and roles are OPC UA's; anonymous access (with ``anonymous_role``) only when
    asked for, and honoured on a loopback bind only unless ``allow_insecure_remote``."""

    enabled: bool = False
    host: BindAddress = "127.0.0.1"
    port: Annotated[int, Field(ge=0, le=65535)] = 8080
    cert_file: OptionalPath = ""
    key_file: OptionalPath = ""
    allow_anonymous: bool = False
    anonymous_role: RoleName = "viewer"
    allow_insecure_remote: bool = False
    #: host names (besides the bind address, and localhost on loopback) the browser may
    #: use in the address bar: a WebSocket whose Host is another name is refused
    allowed_hosts: list[str] = Field(default_factory=list)

    @model_validator(mode="after")
    def _pair(self) -> WebSection:
        if bool(self.cert_file) != bool(self.key_file):
            raise ValueError("cert_file and key_file go together (both set: HTTPS)")
        return self


class UsersFile(_Model):
    """The users secret file: ``[[users]]`` entries like ``[[opcua.users]]``."""

    users: list[OpcUaUser] = Field(default_factory=list)


def default_data_dir(site_name: str, environ: Mapping[str, str]) -> str:
    """Where a site keeps its files when its map does not say: ``$MOTION_SERVER_DATA_DIR``,
    else ``$XDG_STATE_HOME/motion-server/<site>`` (``~/.local/state/motion-server/<site>``).
    Not the working directory: a server started in a source tree or on a read-only mount
    would leave its snapshots and key there, or fail to write them."""
    named = environ.get(DATA_DIR_ENV, "")
    if named:
        return named
    name = site_name if isinstance(site_name, str) and re.match(NAME_RE, site_name) else "site"
    state = environ.get("XDG_STATE_HOME", "")
    if not state.startswith("/"):  # unset or relative: ignored, as the XDG spec says
        home = environ.get("HOME", "") or os.path.expanduser("~")
        state = os.path.join(home, ".local", "state")
    return os.path.join(state, "motion-server", name)


class SiteMap(_Model):
    site: SiteSection = SiteSection()
    controller: ControllerSection = ControllerSection()
    axes: list[AxisSection] = Field(min_length=1)
    groups: list[GroupSection] = Field(min_length=1)
    instructions: InstructionsSection = InstructionsSection()
    modbus: ModbusSection = ModbusSection()
    opcua: OpcUaSection = OpcUaSection()
    web: WebSection = WebSection()
    ethernetip: EthernetIpSection = EthernetIpSection()
    watchdogs: list[WatchdogSection] = Field(default_factory=list)
    cams: list[CamSection] = Field(default_factory=list)
    audit: AuditSection = AuditSection()
    retain: RetainSection = RetainSection()
    #: directory of the audit log, the retain file and the snapshots (relative: to the
    #: working directory); a map loaded from a file that sets none gets
    #: :func:`default_data_dir`, never the working directory
    data_dir: PathText = "."
    #: where the map came from (for messages); not a TOML field
    source: str = Field("<memory>", exclude=True)
    #: where each field was written (set by the loader; messages name file and line)
    _locator: Locator | None = PrivateAttr(default=None)

    def located(self, loc: Sequence[int | str], message: str) -> str:
        """One line for a problem at field ``loc``: file, line and field, or the
        environment variable that set it."""
        if self._locator is not None:
            return self._locator.describe(loc, message)
        field = ".".join(str(p) for p in loc) or "(top level)"
        return f"{self.source}: {field}: {message}"

    def locate_overrides(self, origins: Mapping[tuple[str, str], str]) -> None:
        """Note fields set elsewhere than in the file (``(section, field) -> "option
        --modbus-port"``): messages about them name that instead of a line."""
        if self._locator is not None:
            self._locator = self._locator.overridden(origins)

    # -- derived --------------------------------------------------------------------------
    def axis_numbers(self) -> list[int]:
        """Every axis's number: its own, else its place in ``[[axes]]`` (1-based)."""
        return [a.number or i + 1 for i, a in enumerate(self.axes)]

    def group_numbers(self) -> list[int]:
        return [g.number or i + 1 for i, g in enumerate(self.groups)]

    def axis_configs(self) -> list[AxisConfig]:
        out = []
        for a, number in zip(self.axes, self.axis_numbers(), strict=True):
            data = a.model_dump()
            data["number"] = number
            out.append(AxisConfig(**data))
        return out

    def group_configs(self) -> list[GroupConfig]:
        numbers = dict(zip((a.name for a in self.axes), self.axis_numbers(), strict=True))
        return [
            GroupConfig(
                number=number,
                name=g.name,
                axes=tuple(numbers[name] for name in g.axes),
                coarse_update_period=g.coarse_update_period_ms / 1000.0,
            )
            for g, number in zip(self.groups, self.group_numbers(), strict=True)
        ]

    def cam_numbers(self) -> list[int]:
        """Every cam table's number: its own, else its place in ``[[cams]]`` (1-based)."""
        return [c.number or i + 1 for i, c in enumerate(self.cams)]

    def cam_configs(self) -> list[CamTableConfig]:
        """The kernel's cam tables. The points are Logix REALs: the initial values are
        rounded to float32, as a client's write of the tag would be."""
        out = []
        for c, number in zip(self.cams, self.cam_numbers(), strict=True):
            points = tuple((_real(m), _real(s), t) for m, s, t in c.points)
            out.append(CamTableConfig(number, c.name, c.size, points, c.length or len(points)))
        return out

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
        """The controller and its instruction instances, as the map describes them.
        :func:`motion_server.config.assembly.assemble` is what ``run`` and ``check`` use:
        it builds this and everything around it, and names file and line on failure."""
        try:
            ctl = Controller(self.axis_configs(), self.group_configs(), cams=self.cam_configs())
        except ConfigError as exc:  # the cross-field checks of problems() catch these first
            raise SiteMapError(f"{self.source}: {exc}") from exc
        system = MotionSystem(ctl)
        for inst in self.instances():
            system.add(inst.type, inst.name, inst.operands)
        return system

    def problems(self) -> list[Problem]:
        """Cross-field checks: (location, message) pairs, empty when the map is sound.
        Everything the kernel would refuse at construction is found here first."""
        out: list[Problem] = []
        out += duplicates([a.name for a in self.axes], ("axes",), "name")
        out += number_clashes(
            [a.name for a in self.axes], [a.number for a in self.axes], "axes", "axis"
        )
        out += duplicates([g.name for g in self.groups], ("groups",), "name")
        out += number_clashes(
            [g.name for g in self.groups], [g.number for g in self.groups], "groups", "group"
        )
        out += duplicates(
            [i.name for i in self.instructions.instances], ("instructions", "instances"), "name"
        )
        out += duplicates([u.name for u in self.opcua.users], ("opcua", "users"), "name")
        out += duplicates([w.name for w in self.watchdogs], ("watchdogs",), "name")
        groups = {g.name for g in self.groups}
        for wi, w in enumerate(self.watchdogs):
            if w.group not in groups:
                out.append((("watchdogs", wi, "group"), f"watchdog {w.name}: unknown group"))
        known = {a.name for a in self.axes}
        member_of: dict[str, str] = {}
        for gi, g in enumerate(self.groups):
            for name in g.axes:
                if name not in known:
                    out.append((("groups", gi, "axes"), f"group {g.name}: unknown axis {name!r}"))
                elif name in member_of:
                    out.append(
                        (
                            ("groups", gi, "axes"),
                            f"group {g.name}: axis {name!r} is already in group {member_of[name]}",
                        )
                    )
                else:
                    member_of[name] = g.name
        for ai, a in enumerate(self.axes):
            if a.name not in member_of:
                out.append((("axes", ai, "name"), f"axis {a.name!r} is in no motion group"))
        out += period_problems([g.coarse_update_period_ms for g in self.groups])
        for ai, a in enumerate(self.axes):
            out += [(("axes", ai, *loc), msg) for loc, msg in _ramp_problems(a)]
            out += [(("axes", ai, *loc), msg) for loc, msg in _homing_problems(a)]
        for name in self.retain.axes:
            if name not in known:
                out.append((("retain", "axes"), f"unknown axis {name!r}"))
        out += duplicates([c.name for c in self.cams], ("cams",), "name")
        out += number_clashes(
            [c.name for c in self.cams], [c.number for c in self.cams], "cams", "cam table"
        )
        for ci, c in enumerate(self.cams):
            out += [(("cams", ci, *loc), msg) for loc, msg in _cam_problems(c)]
        return out


def _real(value: float) -> float:
    """``value`` rounded to the nearest float32 (a Logix REAL)."""
    return float(struct.unpack("<f", struct.pack("<f", value))[0])


def _cam_problems(c: CamSection) -> list[Problem]:
    """A capacity or length the initial points do not fit."""
    out: list[Problem] = []
    n = len(c.points)
    if c.capacity is not None and n > c.capacity:
        out.append((("capacity",), f"cam table {c.name}: {n} points do not fit {c.capacity}"))
    if c.length is not None and c.length > c.size:
        out.append((("length",), f"cam table {c.name}: {c.length} exceeds its capacity {c.size}"))
    return out


def _ramp_problems(a: AxisSection) -> list[Problem]:
    """Limits that imply a ramp longer than :data:`MAX_RAMP_TIME`."""
    return [
        ((name,), f"{what} takes {t:.3g} s at {getattr(a, name):g}; at most {MAX_RAMP_TIME:g} s")
        for name, t, what in long_ramps(a)
    ]


def _homing_problems(a: AxisSection) -> list[Problem]:
    """A homing configuration MAH could not run (MOTION-RM003: an absolute homing mode
    is immediate only; a sequence needs the sensors it names and, when active, the
    speeds it moves at) and sensors that cannot exist."""
    out: list[Problem] = []
    seq, mode, rollover = a.home_sequence, a.home_mode, a.rollover
    # a homing moves within the axis's limits, as every command must
    for name, value, limit, what in (
        ("home_speed", a.home_speed, a.max_velocity, "max_velocity"),
        ("home_return_speed", a.home_return_speed, a.max_velocity, "max_velocity"),
        ("home_acceleration", a.home_acceleration, a.max_acceleration, "max_acceleration"),
        ("home_deceleration", a.home_deceleration, a.max_deceleration, "max_deceleration"),
    ):
        if value > limit:
            out.append(((name,), f"must not exceed {what} ({limit:g})"))
    if a.home_switch is not None:
        if a.home_switch_width <= 0.0:
            out.append((("home_switch_width",), "a home switch needs its width (> 0)"))
        elif rollover > 0.0 and a.home_switch_width >= rollover:
            out.append(
                (("home_switch_width",), f"must be shorter than the rollover ({rollover:g})")
            )
    if rollover > 0.0 and not 0.0 <= a.home_position < rollover:
        out.append((("home_position",), f"a rotary axis homes to [0, {rollover:g})"))
    if mode == HomeMode.ABSOLUTE and seq != HomeSequence.IMMEDIATE:
        out.append((("home_sequence",), "absolute homing is immediate only"))
        return out
    if seq == HomeSequence.IMMEDIATE:
        return out
    if seq in (HomeSequence.SWITCH, HomeSequence.SWITCH_THEN_MARKER) and a.home_switch is None:
        out.append((("home_sequence",), f"{seq.name.lower()} homing needs home_switch"))
    if seq in (HomeSequence.MARKER, HomeSequence.SWITCH_THEN_MARKER) and not a.marker_interval:
        out.append((("home_sequence",), f"{seq.name.lower()} homing needs marker_interval"))
    if mode != HomeMode.ACTIVE:
        return out
    if a.type == AxisType.FEEDBACK_ONLY:
        out.append((("home_mode",), "a feedback-only axis cannot home actively (passive)"))
    if not a.home_speed:
        out.append((("home_speed",), "active homing needs a home speed > 0"))
    if a.home_direction.bidirectional and not a.home_return_speed:
        out.append((("home_return_speed",), "bidirectional homing needs a return speed > 0"))
    return out
