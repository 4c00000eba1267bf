"""Videos for editors (issue 76, item 5): every MP4 is converted from RGB with BT.709's matrix and tagged BT.709
(primaries, transfer, matrix, limited range), so players and editors, which read HD video as BT.709, show the
colours the sandbox drew. The videos were untagged and converted with swscale's BT.601 matrix."""

from __future__ import annotations

import re
import subprocess

import numpy as np

from sandbox.render.encoder import Encoder, ff_path, ffmpeg_exe

W, H = 64, 48
SWATCHES = [(255, 0, 0), (0, 255, 0), (0, 0, 255), (59, 94, 156), (219, 31, 20), (128, 128, 128)]


def swatch_frame() -> np.ndarray:
    """(H, W, 3) uint8: vertical bands of SWATCHES (wide enough that 4:2:0's shared chroma stays inside a band)."""
    frame = np.zeros((H, W, 3), np.uint8)
    bands = np.array_split(np.arange(W), len(SWATCHES))
    for band, color in zip(bands, SWATCHES):
        frame[:, band] = color
    return frame


def test_an_mp4_is_bt709_tagged_and_decodes_to_the_colours_drawn(tmp_path):
    path = tmp_path / "s.mp4"
    encoder = Encoder(path, W, H, 30.0)
    for _ in range(3):
        encoder.write(swatch_frame())
    encoder.close()
    info = subprocess.run([ffmpeg_exe(), "-hide_banner", "-i", ff_path(path)], capture_output=True, text=True).stderr
    stream = re.search(r"Video: h264.*", info).group(0)
    assert "yuv420p(tv, bt709" in stream, stream  # one word: primaries, transfer and matrix all BT.709
    decoded = subprocess.run(  # as a player does: the YUV read through the matrix the stream is tagged with
        [
            ffmpeg_exe(),
            "-v",
            "error",
            "-i",
            ff_path(path),
            "-frames:v",
            "1",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
            "-",
        ],
        capture_output=True,
    ).stdout
    picture = np.frombuffer(decoded, np.uint8).reshape(H, W, 3).astype(int)
    bands = np.array_split(np.arange(W), len(SWATCHES))
    for band, color in zip(bands, SWATCHES):
        middle = picture[H // 2, band[len(band) // 2]]
        assert np.abs(middle - np.array(color)).max() <= 4, (color, middle)
