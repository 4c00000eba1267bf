"""Imported first by the scripts here: puts this checkout's root first on the import path, so that `python
benchmarks/X.py` measures the code of the tree the script sits in, not whichever copy of sandbox is installed (an
editable install points at one checkout: two copies of the tree compared through it would run the same code)."""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if sys.path[:1] != [str(ROOT)]:
    sys.path.insert(0, str(ROOT))
