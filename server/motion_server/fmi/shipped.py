"""What the script inside an FMU shares between FMI 2.0 and 3.0: its resources.

``motion-server fmu`` puts two files beside the slave script in the FMU's ``resources``
folder: the site map (``site.toml``, exactly as given, or the embedded demo's text) and
``motion_fmu.json`` (the model identifier and where the site map came from). The script
finds them through the ``resources`` path the FMU wrapper passes it, at build time as at
run time.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

from .engine import CoSimController, Logger, site_for_fmu

SITE_FILE = "site.toml"
INFO_FILE = "motion_fmu.json"


@dataclass(frozen=True)
class Shipped:
    """The FMU's model identifier and site map source, read from its resources."""

    model: str
    source: str
    site_text: str
    #: the site map's front-ends serve the controller while the master steps it
    serve: bool = False


def model_identifier(stem: str) -> str:
    """A C identifier from a file name (the FMU's binaries are named after it)."""
    ident = re.sub(r"[^A-Za-z0-9_]", "_", stem) or "motion_server"
    return ident if not ident[0].isdigit() else f"fmu_{ident}"


def read_shipped(resources: str | Path) -> Shipped:
    folder = Path(resources)
    info = json.loads((folder / INFO_FILE).read_text("utf-8"))
    text = (folder / SITE_FILE).read_text("utf-8")
    return Shipped(str(info["model"]), str(info["source"]), text, bool(info.get("serve")))


def write_shipped(
    folder: Path, model: str, source: str, site_text: str, serve: bool = False
) -> list[Path]:
    """Write the resources files into ``folder``; the paths written."""
    site = folder / SITE_FILE
    site.write_text(site_text, "utf-8")
    info = folder / INFO_FILE
    fields = {"model": model, "source": source, "serve": serve}
    info.write_text(json.dumps(fields, indent=2) + "\n", "utf-8")
    return [site, info]


def controller_from(resources: str | Path, log: Logger) -> tuple[Shipped, CoSimController]:
    shipped = read_shipped(resources)
    site = site_for_fmu(shipped.site_text, shipped.source)
    return shipped, CoSimController(site, log, serve=shipped.serve)
