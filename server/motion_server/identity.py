"""Who the server says it is: product name, manufacturer, URIs, version, build.

The OPC UA front-end publishes these as the server's BuildInfo and ApplicationDescription;
the NodeSet2 export stamps its model with the version and release date. One place, so a
client, a certificate and an export never disagree.
"""

from __future__ import annotations

import contextlib
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

from . import __version__

PRODUCT_NAME = "motion-server"
MANUFACTURER_NAME = "motion-server project"
#: identifies the product (every installation); the application URI identifies one
#: installation and lives in its certificate (``frontends.certificates``)
PRODUCT_URI = "urn:motion-server:product"
#: publication date of this version's information model (NodeSet2 ``<Model>``)
RELEASE_DATE = datetime(2026, 11, 24, tzinfo=UTC)


def software_version() -> str:
    """The package version (``motion_server.__version__``)."""
    return __version__


def build_number() -> str:
    """The version of the installed distribution (the same as the package version for a
    release; a development install may carry a local suffix)."""
    try:
        return metadata.version(PRODUCT_NAME)
    except metadata.PackageNotFoundError:
        return __version__


def build_date() -> datetime:
    """When this build was installed: the time stamp of the distribution's metadata (the
    package files when it is not installed), else the release date."""
    candidates: list[Path] = []
    with contextlib.suppress(metadata.PackageNotFoundError):
        dist = metadata.distribution(PRODUCT_NAME)
        located = dist.locate_file("")
        meta = getattr(dist, "_path", None)
        if isinstance(meta, Path):
            candidates.append(meta)
        candidates.append(Path(str(located)))
    candidates.append(Path(__file__))
    for path in candidates:
        with contextlib.suppress(OSError):
            return datetime.fromtimestamp(path.stat().st_mtime, UTC)
    return RELEASE_DATE
