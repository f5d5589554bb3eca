"""LICENSE and CITATION.cff agree with pyproject.toml: the MIT licence, the package's name and
version, and the paper graspsim reproduces among the references."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_license_is_mit_as_pyproject_says() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    text = (ROOT / "LICENSE").read_text()
    assert project["license"] == "MIT"
    assert text.startswith("MIT License") and "Copyright (c) 2026 The graspsim authors" in text


def test_citation_names_the_software_and_the_paper() -> None:
    yaml = pytest.importorskip("yaml")  # PyYAML comes with the ray extra
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software"
    assert (cff["title"], cff["version"], cff["license"]) == (
        project["name"],
        project["version"],
        project["license"],
    )
    (paper,) = cff["references"]
    assert paper["title"] == "Effective Multifingered Grasp Synthesis"
    assert [a["family-names"] for a in paper["authors"]] == ["Coelho", "Grupen"]
