"""``motion-server fmu``: build a Co-Simulation FMU of a site map's controller.

The FMU is built by the well-kept builders: pythonfmu (FMI 2.0) or pythonfmu3 (FMI 3.0).
Their ``FmuBuilder`` packs a slave script (:mod:`.slave2` or :mod:`.slave3`), the builder's
own Python package and its C++ wrapper binaries; we add the site map and a small JSON file
(:mod:`.shipped`). The model description is written by instantiating the slave once, so the
variables are exactly those the FMU will have at run time.

The builders are optional dependencies (the ``fmi`` extra); without them the command says
which package to install, in one line.
"""

from __future__ import annotations

import importlib
import shutil
import tempfile
from importlib import resources
from pathlib import Path

from .. import config
from ..config.loading import DEMO_MAP
from ..tagmap import TagMapError, build_tagmap
from .serving import SERVE_NEEDS
from .shipped import model_identifier, write_shipped

#: the builder package of each FMI version, and the pinned version it was tested with
BUILDERS = {2: ("pythonfmu", "0.7.0"), 3: ("pythonfmu3", "0.3.4")}
SCRIPTS = {2: "slave2.py", 3: "slave3.py"}


class FmuBuildError(Exception):
    """The FMU cannot be built (a missing builder, a bad site map, a file not written)."""


def site_source(path: str | Path | None) -> tuple[str, str]:
    """The text of the site map and where it came from (``None``: the embedded demo).
    The map is checked here, so a bad one fails the build, not the import."""
    try:
        if path is None:
            text = resources.files("motion_server").joinpath("data", DEMO_MAP).read_text("utf-8")
            source = f"<embedded {DEMO_MAP}>"
        else:
            text = config.loading.read_text(path)
            source = Path(path).name
        build_tagmap(config.parse(text, source, environ={}))
    except (config.SiteMapError, TagMapError) as exc:
        raise FmuBuildError(str(exc)) from None
    return text, source


def build_fmu(
    site_map: str | Path | None, output: str | Path, fmi: int = 2, serve: bool = False
) -> Path:
    """Build the FMU of ``site_map`` (None: the demo) into ``output`` (a ``.fmu`` file);
    ``serve``: its front-ends serve the controller while a master steps it."""
    if fmi not in BUILDERS:
        raise FmuBuildError(f"--fmi must be 2 or 3, not {fmi}")
    package, version = BUILDERS[fmi]
    try:
        builder = importlib.import_module(package).FmuBuilder
    except ImportError:
        raise FmuBuildError(
            f"FMI {fmi}.0 needs {package} (pip install 'motion-server[fmi]', "
            f"or {package}=={version})"
        ) from None
    out = Path(output)
    if out.suffix != ".fmu":
        raise FmuBuildError(f"{out}: the output must be a .fmu file")
    text, source = site_source(site_map)
    if serve and config.parse(text, source, environ={}).controller.remote_clock:
        raise FmuBuildError(SERVE_NEEDS)
    model = model_identifier(out.stem)
    script = resources.files("motion_server.fmi").joinpath(SCRIPTS[fmi])
    with tempfile.TemporaryDirectory(prefix="motion_fmu_") as tmp:
        folder = Path(tmp)
        script_file = folder / SCRIPTS[fmi]
        script_file.write_text(script.read_text("utf-8"), "utf-8")
        project = write_shipped(folder, model, source, text, serve)
        built_dir = folder / "built"
        # steps of any size are taken (carry-over); pythonfmu3 0.3.4 would write false
        options = {"canHandleVariableCommunicationStepSize": True}
        built = Path(
            builder.build_FMU(script_file, dest=built_dir, project_files=project, **options)
        )
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(built, out)
        except OSError as exc:
            raise FmuBuildError(f"cannot write {out}: {exc.strerror or exc}") from None
    return out
