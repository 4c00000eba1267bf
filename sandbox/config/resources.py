"""Where the shipped scenes and assets live: inside the installed package as `sandbox.scenes` and `sandbox.assets`.

pyproject.toml maps the repository's top-level scenes/ and assets/ folders into the package, so a wheel, a plain
`pip install .` and an editable install all find them through importlib.resources. A source tree that was never
installed (tests run from a checkout) falls back to the folders beside the package.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path


def _shipped_folder(name: str) -> Path:
    try:
        return Path(str(resources.files(f"sandbox.{name}")))
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[2] / name  # the repository root: sandbox/config/ is two below


SCENES_DIR = _shipped_folder("scenes")
ASSETS_DIR = _shipped_folder("assets")
MATERIALS_FILE = ASSETS_DIR / "materials.toml"


def shipped_scenes() -> list[Path]:
    """Every shipped scene file, sorted by name."""
    return sorted(SCENES_DIR.glob("*.toml"))


def shipped_scene(name: str) -> Path | None:
    """The shipped scene called `name` (without .toml), or None."""
    path = SCENES_DIR / f"{name}.toml"
    return path if path.is_file() else None
