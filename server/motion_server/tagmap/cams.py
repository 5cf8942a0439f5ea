"""Cam tables in the tag map: where a table's elements are, and its OPC UA array views.

Every cam table (``[[cams]]``) is an owner of the ``Cams`` folder whose tags are laid out
by :mod:`.layout` (``ProfileStatus``, ``Capacity``, ``Number``, ``Length``, then
``Master[k]``, ``Slave[k]``, ``SegmentType[k]`` for every element k). Beside the scalar
tags, OPC UA shows three arrays per table, ``Cams.<name>.MasterValues`` (Float),
``SlaveValues`` (Float) and ``SegmentTypes`` (Int32), each ``capacity`` long: views of
the element tags, read from the same image slots and written as one batch of those tags
through the same judged write queue. They have no registers of their own, so they are
not tags; :func:`cam_tables` lists them for the OPC UA model and the exports.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..instructions.schema import TagType
from .fields import CAM_ELEMENT_FIELDS, cam_element_of
from .model import Folder, Tag, TagMap

#: registers before element 0 in a table's block, and registers per element
CAM_HEADER_WORDS = 8
CAM_ELEMENT_WORDS = 6
#: element field -> (array view name, its description)
ARRAY_VIEWS: dict[str, tuple[str, str]] = {
    "Master": ("MasterValues", "every element's master (x) value: Master[0..capacity-1]"),
    "Slave": ("SlaveValues", "every element's slave (y) value: Slave[0..capacity-1]"),
    "SegmentType": (
        "SegmentTypes",
        "every element's segment type (0 linear, 1 cubic): SegmentType[0..capacity-1]",
    ),
}


@dataclass(frozen=True)
class ArrayView:
    """An OPC UA array of one field of every element of a cam table."""

    owner: str
    #: ``MasterValues``, ``SlaveValues``, ``SegmentTypes``
    name: str
    #: ``Master``, ``Slave``, ``SegmentType``
    field: str
    #: the element tags, element 0 first
    tags: tuple[Tag, ...]
    description: str

    @property
    def node_id(self) -> str:
        return f"{Folder.CAMS.value}.{self.owner}.{self.name}"

    @property
    def type(self) -> TagType:
        return self.tags[0].type

    @property
    def writable(self) -> bool:
        return True


@dataclass(frozen=True)
class CamInfo:
    """One cam table of a tag map."""

    name: str
    #: the first register of its block
    base: int
    capacity: int
    views: tuple[ArrayView, ...]

    @property
    def node_id(self) -> str:
        return f"{Folder.CAMS.value}.{self.name}"

    def address(self, field: str, k: int) -> int:
        """The register of ``field`` (Master, Slave, SegmentType) of element ``k``."""
        return (
            self.base
            + CAM_HEADER_WORDS
            + CAM_ELEMENT_WORDS * k
            + 2 * CAM_ELEMENT_FIELDS.index(field)
        )


def cam_tables(tagmap: TagMap) -> list[CamInfo]:
    """Every cam table of ``tagmap``, in block order."""
    out: list[CamInfo] = []
    for owner in tagmap.owners(Folder.CAMS):
        elements: dict[str, list[tuple[int, Tag]]] = {f: [] for f in CAM_ELEMENT_FIELDS}
        for tag in tagmap.owned_by(owner):
            found = cam_element_of(tag.field)
            if found is not None:
                elements[found[0]].append((found[1], tag))
        views = tuple(
            ArrayView(
                owner,
                ARRAY_VIEWS[f][0],
                f,
                tuple(t for _, t in sorted(elements[f], key=lambda kt: kt[0])),
                ARRAY_VIEWS[f][1],
            )
            for f in CAM_ELEMENT_FIELDS
        )
        base = tagmap.block(owner).base
        out.append(CamInfo(owner, base, len(views[0].tags), views))
    return out


def scada_name(field: str) -> str:
    """A field name SCADA tag names can hold: ``Master[3]`` -> ``Master_3`` (brackets
    mean arrays or providers to KEPServerEX and Ignition)."""
    found = cam_element_of(field)
    return f"{found[0]}_{found[1]}" if found is not None else field
