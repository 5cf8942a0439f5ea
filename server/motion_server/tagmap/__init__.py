"""The tag map: every value a client can reach, with its Modbus registers and OPC UA node.

Computed from two things only: the instruction catalog (each instruction class's own
schema, ``input_operands()`` — the trigger and the operands, writable — and
``status_fields()``, read-only) and a site map (axes, groups, instances). New instruction
types appear in the map, both front-ends and every export without touching this package.

Public API (what front-ends, exports and clients use)::

    from motion_server.tagmap import build_tagmap, TagImage

    tagmap = build_tagmap(site)            # a TagMap, static for the server's life
    tag = tagmap.tag("MAJ_1.Speed")        # look-up by name (UnknownTagError if absent)
    tagmap.by_node_id("Axes.Axis2.ActualPosition")
    tagmap.at(5010)                        # the tags occupying register 5010
    tagmap.access(5010)                    # RegisterAccess.NONE / READ / READ_WRITE
    for tag in tagmap: ...                 # ordered by address, then bit
    tagmap.in_folder(Folder.AXES), tagmap.owners(Folder.INSTRUCTIONS), tagmap.blocks

    image = TagImage(tagmap, system, host) # live values (host: the runtime's clock)
    image.read(tag)                        # the last completed cycle's value
    image.write("MAJ_1.Speed", 25.0)       # ReadOnlyError / BadValueError on refusal
    image.write_many([...])                # all or nothing; words before bits
    image.read_registers(address, count)   # AddressError outside the map
    image.write_registers(address, values) # ReadOnlyError, BadValueError
    await image.settle()                   # after a Clock.Step write: the cycles ran

A :class:`Tag` carries everything a front-end needs: ``name`` (``Owner.Field``),
``folder`` (Clock, Diagnostics, Groups, Axes, Instructions), ``type`` (BOOL, SINT, INT,
DINT, UDINT, REAL, LREAL), ``access`` (read / read_write), ``address``/``count``/``bit``
(0-based holding registers), ``node_id`` (``Instructions.MAJ_1.Speed``: the OPC UA string
NodeId, the browse path under the site's namespace), ``units`` (engineering units from
the axis units and the operand's quantity), ``enum`` (an IntEnum), ``minimum``/
``maximum`` (the operand's range), ``eu_range`` (the OPC UA EURange), ``description`` and,
for instruction tags, ``instruction`` (the type, e.g. ``MAJ``).

The register layout rules are in :mod:`.layout`; value encoding in :mod:`.codec`; the
exports (``motion-server map --format json|csv|md|nodeset|kepware|ignition``) and the
JSON Schema of the ``motion-server-map/1`` contract in :mod:`.export`.
"""

from ..instructions.schema import TagType
from .codec import decode, encode
from .errors import AddressError, BadValueError, ReadOnlyError, TagAccessError
from .export import FORMATS, export, json_schema, to_dict
from .fields import ClockMode, CommFault
from .image import Host, StandaloneHost, TagImage
from .layout import build_tagmap, layout_problems
from .model import (
    MAP_FORMAT,
    Access,
    Block,
    Folder,
    RegisterAccess,
    Tag,
    TagMap,
    TagMapError,
    UnknownTagError,
    WordOrder,
)

__all__ = [
    "FORMATS",
    "MAP_FORMAT",
    "Access",
    "AddressError",
    "BadValueError",
    "Block",
    "ClockMode",
    "CommFault",
    "Folder",
    "Host",
    "ReadOnlyError",
    "RegisterAccess",
    "StandaloneHost",
    "Tag",
    "TagAccessError",
    "TagImage",
    "TagMap",
    "TagMapError",
    "TagType",
    "UnknownTagError",
    "WordOrder",
    "build_tagmap",
    "decode",
    "encode",
    "export",
    "json_schema",
    "layout_problems",
    "to_dict",
]
