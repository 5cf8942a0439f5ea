"""What a new user meets first (issue 24): links in the documents lead somewhere, and
installing the package raises no deprecation warning about its metadata."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = sorted([ROOT / "README.md", ROOT / "bench" / "README.md", *ROOT.glob("docs/*.md")])
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(document: Path) -> None:
    broken = [
        target
        for target in LINK.findall(document.read_text("utf-8"))
        if "://" not in target and not (document.parent / target).exists()
    ]
    assert broken == []


def test_the_license_is_an_spdx_expression_for_a_setuptools_that_reads_it() -> None:
    # PEP 639: project.license is an SPDX expression string; the TOML table form is
    # deprecated and setuptools warns about it on every build (setuptools >= 77 reads the
    # string)
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text("utf-8"))
    assert meta["project"]["license"] == "MIT"
    requires = meta["build-system"]["requires"]
    assert requires == ["setuptools>=77"]
