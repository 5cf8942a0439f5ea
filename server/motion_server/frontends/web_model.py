"""The web view's model (``GET /api/model``): the axes, groups and instruction instances
of the site with their tag names, from the same tag map as Modbus and OPC UA, and the
list of tags a status message or a trend may carry.
"""

from __future__ import annotations

from typing import Any

from ..config import SiteMap
from ..instructions.schema import TagType
from ..tagmap import Folder, Tag, TagMap

#: the trigger field of an instance (the rung-condition-in of Logix, PLCopen's Execute)
TRIGGER = "Execute"
#: folders whose tags the status messages carry
STATUS_FOLDERS = (Folder.AXES, Folder.GROUPS, Folder.INSTRUCTIONS)


def family(instruction_type: str) -> str:
    """``plcopen`` for the MC_ blocks, else ``logix``."""
    return "plcopen" if instruction_type.startswith("MC_") else "logix"


def trendable(tag: Tag) -> bool:
    """A tag a trend may carry: every numeric or BOOL tag but cam table points."""
    return tag.folder != Folder.CAMS


def _axis_type(value: object) -> str:
    """``servo``, ``virtual``, ``feedback_only`` (the site map's spelling)."""
    name = getattr(value, "name", None)
    return str(name).lower() if name is not None else str(value)


def build_model(site: SiteMap, tagmap: TagMap) -> dict[str, Any]:
    """The JSON model of ``docs/web.md`` § "Protocol"."""
    types = {a.name: _axis_type(a.type) for a in site.axes}
    axes = [
        {
            "name": owner,
            "type": types.get(owner, ""),
            "tags": {t.field: t.name for t in tagmap.owned_by(owner)},
        }
        for owner in tagmap.owners(Folder.AXES)
    ]
    groups = [
        {"name": owner, "tags": {t.field: t.name for t in tagmap.owned_by(owner)}}
        for owner in tagmap.owners(Folder.GROUPS)
    ]
    instructions = []
    for owner in tagmap.owners(Folder.INSTRUCTIONS):
        tags = tagmap.owned_by(owner)
        kind = tags[0].instruction if tags else ""
        trigger = next((t.name for t in tags if t.field == TRIGGER and t.writable), "")
        instructions.append(
            {
                "name": owner,
                "type": kind,
                "family": family(kind),
                "bits": [t.field for t in tags if not t.writable and t.type == TagType.BOOL],
                "operands": [
                    {"name": t.field, "tag": t.name, "type": t.type.name, "writable": True}
                    for t in tags
                    if t.writable and t.name != trigger
                ],
                "outputs": [t.name for t in tags if not t.writable],
                "trigger": trigger,
            }
        )
    period_ms = site.groups[0].coarse_update_period_ms if site.groups else 0.0
    return {
        "controller": {
            "name": site.site.name,
            "period_us": round(period_ms * 1000.0),
            "clock": site.controller.clock.upper(),
        },
        "axes": axes,
        "groups": groups,
        "instructions": instructions,
        "channels": [t.name for t in tagmap if trendable(t)],
    }


def status_tags(tagmap: TagMap) -> list[Tag]:
    """The tags a status message carries: those of the axes, groups and instances."""
    return [t for t in tagmap if t.folder in STATUS_FOLDERS]
