"""The refusals of a tag read or write, protocol-neutral: each front-end maps them to its
own answer (Modbus: :class:`AddressError` and :class:`ReadOnlyError` -> exception 02,
:class:`BadValueError` -> 03; OPC UA: BadNotWritable, BadOutOfRange ...)."""

from __future__ import annotations


class TagAccessError(Exception):
    """A read or write the image refuses (the base of the errors below)."""


class AddressError(TagAccessError):
    """Registers outside the map."""


class ReadOnlyError(TagAccessError):
    """A write to a read-only tag or register."""


class BadValueError(TagAccessError):
    """A value the tag cannot hold (wrong type or range, an unknown clock mode ...)."""
