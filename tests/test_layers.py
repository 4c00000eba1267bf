"""The package's layers (pyproject's import-linter contracts): they hold, and a lower layer importing a higher one
breaks them."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from .conftest import ROOT

LINT = [
    sys.executable,
    "-c",
    "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())",
]


def lint(package_parent: Path, config: Path) -> subprocess.CompletedProcess:
    """lint-imports over the `sandbox` package found in `package_parent`, with the contracts in `config`."""
    env = dict(os.environ, PYTHONPATH=str(package_parent))
    return subprocess.run(
        [*LINT, "--config", str(config), "--no-cache"], cwd=package_parent, env=env, capture_output=True, text=True
    )


def test_the_layer_contracts_hold():
    run = lint(ROOT, ROOT / "pyproject.toml")
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    assert "4 kept, 0 broken" in run.stdout


def test_a_lower_layer_importing_a_higher_one_breaks_a_contract(tmp_path):
    """core importing the simulation (inside a function: those count too) breaks the layers."""
    shutil.copytree(ROOT / "sandbox", tmp_path / "sandbox", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    runtime = tmp_path / "sandbox" / "core" / "runtime.py"
    runtime.write_text(
        runtime.read_text() + "\n\ndef _upward():\n    from ..simulation import Simulation\n\n    return Simulation\n"
    )
    run = lint(tmp_path, tmp_path / "pyproject.toml")
    assert run.returncode == 1
    assert "layers: each imports only from the layers below it BROKEN" in run.stdout
    assert re.search(r"never the\s+simulation facade or the app BROKEN", run.stdout)  # the data contract, too
    assert "sandbox.core.runtime -> sandbox.simulation" in run.stdout
