"""hand_sim.resources: the data folders are found relative to the package, the installed copy
first, a top-level folder only in a checkout, and a missing folder is a clear error."""

from __future__ import annotations

from pathlib import Path

import pytest

from hand_sim import resources
from hand_sim.resources import DataNotFoundError, data_dir, models_dir, scenes_dir

REPO = Path(__file__).resolve().parents[2]


def test_checkout_uses_its_top_level_folders() -> None:
    assert models_dir() == REPO / "models"
    assert scenes_dir() == REPO / "scenes"
    assert (models_dir() / "hand.xml").is_file() and (scenes_dir() / "random.toml").is_file()


def _layout(tmp_path: Path, *, installed: bool, checkout: bool, marker: bool) -> Path:
    """A fake site: ``tmp/hand_sim`` with optionally ``_data/models``, a sibling ``models`` and a
    ``pyproject.toml`` beside it."""
    package = tmp_path / "hand_sim"
    package.mkdir()
    if installed:
        (package / "_data" / "models").mkdir(parents=True)
    if checkout:
        (tmp_path / "models").mkdir()
    if marker:
        (tmp_path / "pyproject.toml").write_text("[project]\n")
    return package


@pytest.mark.parametrize(
    ("installed", "checkout", "marker", "expected"),
    [
        (True, True, True, "hand_sim/_data/models"),  # the installed copy wins
        (True, False, False, "hand_sim/_data/models"),  # a wheel in site-packages
        (False, True, True, "models"),  # a checkout
    ],
)
def test_installed_copy_first_then_checkout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, installed, checkout, marker, expected
) -> None:
    package = _layout(tmp_path, installed=installed, checkout=checkout, marker=marker)
    monkeypatch.setattr(resources, "_package_root", lambda: package)
    assert data_dir("models") == tmp_path / expected


def test_a_stray_models_folder_in_site_packages_is_not_taken(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    package = _layout(tmp_path, installed=False, checkout=True, marker=False)
    monkeypatch.setattr(resources, "_package_root", lambda: package)
    with pytest.raises(DataNotFoundError) as e:
        data_dir("models")
    assert str(package / "_data" / "models") in str(e.value)
    assert str(tmp_path / "models") in str(e.value)
    assert "reinstall graspsim" in str(e.value)


def test_unknown_data_folder_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown data folder 'meshes'; valid: models, scenes"):
        data_dir("meshes")
