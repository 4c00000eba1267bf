"""The classroom notebook (examples/melting_in_class.ipynb) runs top to bottom in a Jupyter kernel and shows what it
promises: the block, a playable movie, the heating curve, and chocolate melting before wax."""

import re

import pytest

from .conftest import ROOT

pytestmark = pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)

NOTEBOOK = ROOT / "examples" / "melting_in_class.ipynb"


def _outputs(cell) -> tuple[str, str, set[str]]:
    """(stdout text, html text, the MIME types shown) of one executed code cell."""
    text, html, kinds = "", "", set()
    for out in cell.get("outputs", []):
        if out.get("output_type") == "stream" and out.get("name") == "stdout":
            text += out["text"]
        data = out.get("data", {})
        kinds |= set(data)
        html += data.get("text/html", "")
    return text, html, kinds


@pytest.mark.slow  # a Jupyter kernel in another process, which compiles its own kernels
def test_the_classroom_notebook_runs_and_shows_its_results(tmp_path):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    pytest.importorskip("matplotlib")
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        notebook, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()  # raises CellExecutionError, naming the cell, when any cell fails
    cells = [c for c in notebook.cells if c.cell_type == "code"]
    _, first_html, _ = _outputs(cells[0])
    assert "<img" in first_html and "melting_block: 1,200 particles, t = 0 s after 0 frames" in first_html
    text, html, _ = _outputs(cells[1])
    assert '<video controls autoplay loop muted playsinline src="data:video/mp4;base64,' in html
    assert "melting_block: 100 frames" in html  # every third of 300
    molten = float(re.search(r"molten fraction ([0-9.]+)", text).group(1))
    temperature = float(re.search(r"mean temperature ([0-9.]+)", text).group(1))
    assert molten > 0.5 and temperature > 62.0  # most of it melted, and the melt is above the liquidus on average
    text, _, kinds = _outputs(cells[2])  # the heating curve of the ice cube, with its plateau found
    assert "image/png" in kinds
    level, start, end = map(float, re.search(r"level at (-?[0-9.]+) from ([0-9.]+) s to ([0-9.]+) s", text).groups())
    assert abs(level) <= 1.0 and end - start > 3.0  # the ice melts at 0 °C, and melting takes most of the run
    text, _, kinds = _outputs(cells[3])
    assert "image/png" in kinds
    half = dict(re.findall(r"(\w+) ([0-9.]+) s", text.split("half melted after:")[1]))
    assert float(half["chocolate"]) < float(half["wax"])  # the lower melting range melts first
    streams = [out for c in cells for out in c.get("outputs", []) if out.get("output_type") == "stream"]
    every = "".join(out["text"] for out in streams if out.get("name") == "stdout")
    every += "".join(out["text"] for out in streams if out.get("name") == "stderr" and "frame/s" not in out["text"])
    assert "Taichi" not in every and "[I " not in every  # no log lines among the lesson's output
    assert not re.search(r"\d\.\d{5,}", every)  # numbers printed rounded, no float noise
