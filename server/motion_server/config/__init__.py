"""Site maps: TOML files naming the axes, groups and instruction instances of a site.

Three layers, each importing only the ones before it:

- :mod:`.schema`: the sections as pydantic models and their cross-field checks;
- :mod:`.loading`: files, the environment and locations: :func:`load` and :func:`parse`
  give a validated :class:`SiteMap`, and every problem is one line naming file, line and
  field;
- :mod:`.assembly`: :func:`~.assembly.assemble` builds everything ``motion-server run``
  needs before it serves (and ``motion-server check`` builds exactly that).

The demo map embedded in the package (``data/demo.toml``) is what ``motion-server run``
uses when given none (unless ``MOTION_SERVER_MAP`` names a file).

This package is imported by the tag map, the front-ends and the safety modules for its
section classes; it imports the tag map (for the register layout checks) but never the
front-ends, the runtime or :mod:`.assembly`.
"""

from .loading import (
    DEFAULT_USERS_FILE,
    MAX_FILE_BYTES,
    USERS_FILE_ENV,
    Locations,
    environment_settings,
    load,
    load_users_file,
    opcua_users,
    parse,
    read_text,
    unknown_variables,
    users_file_path,
)
from .schema import (
    DEFAULT_CERTIFICATE_ROLES,
    DEMO_MAP,
    ENV_PREFIX,
    HASH_RE,
    MAP_ENV,
    NAME_RE,
    AuditSection,
    AxisSection,
    ControllerSection,
    GroupSection,
    InstanceSection,
    InstructionsSection,
    ModbusAccessSection,
    ModbusSection,
    ModbusTlsSection,
    OpcUaSection,
    OpcUaUser,
    RetainSection,
    RoleName,
    SecurityPolicy,
    SiteMap,
    SiteMapError,
    SiteSection,
    UsersFile,
    WatchdogSection,
    WebSection,
    WriteRule,
)

__all__ = [
    "DEFAULT_CERTIFICATE_ROLES",
    "DEFAULT_USERS_FILE",
    "DEMO_MAP",
    "ENV_PREFIX",
    "HASH_RE",
    "MAP_ENV",
    "MAX_FILE_BYTES",
    "NAME_RE",
    "USERS_FILE_ENV",
    "AuditSection",
    "AxisSection",
    "ControllerSection",
    "GroupSection",
    "InstanceSection",
    "InstructionsSection",
    "Locations",
    "ModbusAccessSection",
    "ModbusSection",
    "ModbusTlsSection",
    "OpcUaSection",
    "OpcUaUser",
    "RetainSection",
    "RoleName",
    "SecurityPolicy",
    "SiteMap",
    "SiteMapError",
    "SiteSection",
    "UsersFile",
    "WatchdogSection",
    "WebSection",
    "WriteRule",
    "environment_settings",
    "load",
    "load_users_file",
    "opcua_users",
    "parse",
    "read_text",
    "unknown_variables",
    "users_file_path",
]
