"""Which image slot holds which tag: one float64 per tag.

Every value a tag can hold fits a float64 exactly (BOOL 0/1, integers up to 32 bits,
REAL and LREAL). The axis fields the kernel keeps as arrays (positions, velocities,
following error, and the status words it gives as arrays:
:data:`~motion_server.tagmap.image.AXIS_ARRAYS`, :data:`~.AXIS_STATUS`,
:data:`~.AXIS_FAULT_WORDS`) come first, one
run per field in axis order, so the scan copies each kernel array into the image in one
slice; every other tag follows in tag-map order. Both sides compute the layout from the
same site map; the fingerprint (a hash of the names and types in slot order) is checked
when a front-end connects, so a front-end built from another map is refused rather than
misread.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

from ..tagmap.image import AXIS_ARRAYS, AXIS_FAULT_WORDS, AXIS_STATUS
from ..tagmap.model import Folder, Tag, TagMap


@dataclass(frozen=True)
class ImageLayout:
    """Slots of a :class:`TagMap`: ``slot(tag)`` is the index of its value."""

    tagmap: TagMap
    tags: tuple[Tag, ...] = field(init=False)
    _slots: dict[str, int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        axes = {owner: k for k, owner in enumerate(self.tagmap.owners(Folder.AXES))}
        fields = {name: k for k, name in enumerate([*AXIS_ARRAYS, *AXIS_STATUS, *AXIS_FAULT_WORDS])}

        def arrays(t: Tag) -> bool:
            return t.folder == Folder.AXES and t.field in fields

        first = sorted(
            (t for t in self.tagmap.tags if arrays(t)),
            key=lambda t: (fields[t.field], axes[t.owner]),
        )
        tags = (*first, *(t for t in self.tagmap.tags if not arrays(t)))
        object.__setattr__(self, "tags", tags)
        object.__setattr__(self, "_slots", {t.name: i for i, t in enumerate(tags)})

    @property
    def size(self) -> int:
        return len(self.tags)

    def slot(self, tag: Tag | str) -> int:
        name = tag if isinstance(tag, str) else tag.name
        return self._slots[name]

    @property
    def fingerprint(self) -> int:
        """A 63-bit hash of the tag names and types in slot order."""
        h = hashlib.sha256()
        for t in self.tags:
            h.update(f"{t.name}:{t.type.value};".encode())
        return int.from_bytes(h.digest()[:8], "little") & ((1 << 63) - 1)
