"""The size of every shipped scene's GIF with the defaults (`sandbox run SCENE --out SCENE.gif`): what a teacher
gets when sharing one. The README's promise is under 10 MB each.

    python benchmarks/gif_sizes.py [--out DIR]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import this_tree  # this checkout's sandbox, not the installed one

from sandbox.config.resources import shipped_scenes


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="gif-sizes", help="folder for the GIFs")
    args = parser.parse_args()
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    worst = 0.0
    print(f"{'scene':<18} {'MB':>6} {'wall s':>7}")
    for scene in shipped_scenes():
        gif = out / f"{scene.stem}.gif"
        start = time.perf_counter()
        done = subprocess.run(
            [sys.executable, "-m", "sandbox", "run", scene.stem, "--headless", "--quiet", "--out", str(gif)],
            capture_output=True,
            text=True,
            cwd=this_tree.ROOT,  # `-m sandbox` from the checkout's root: its own sandbox, as this script's
        )
        wall = time.perf_counter() - start
        if done.returncode != 0:
            print(f"{scene.stem:<18} failed: {done.stderr.strip().splitlines()[-1]}")
            continue
        size = gif.stat().st_size / 1e6
        worst = max(worst, size)
        print(f"{scene.stem:<18} {size:6.1f} {wall:7.1f}")
    print(f"largest: {worst:.1f} MB")
    return 0 if worst < 10 else 1


if __name__ == "__main__":
    sys.exit(main())
