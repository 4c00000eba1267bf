"""Videos for editors (issue 76, item 5): every MP4 and MOV is converted from RGB with BT.709's matrix and tagged
BT.709 (primaries, transfer, matrix, limited range), so players and editors, which read HD video as BT.709, show the
colours the sandbox drew (the videos were untagged and converted with swscale's BT.601 matrix); --codec h264, h265,
prores or png, --quality, --lossless and --alpha give what they say, checked with ffmpeg's own reading of each file;
what does not fit together is one line; a resume keeps its video's encoding."""

from __future__ import annotations

import os
import re
import subprocess

import numpy as np
import pytest

from sandbox.app.cli import EXIT_BAD_INPUT, main
from sandbox.render.encoder import Encoder, ff_path, ffmpeg_exe
from tests.test_hostile_files import errors, run

pytestmark = pytest.mark.xdist_group("run_files")

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


# ---------------------------------------------------------------------------------------------------------- codecs
def stream_of(path) -> str:
    """ffmpeg's line for the video stream of `path`: codec, profile, pixel format and colour tags."""
    info = subprocess.run([ffmpeg_exe(), "-hide_banner", "-i", ff_path(path)], capture_output=True, text=True).stderr
    return re.search(r"Video: .*", info).group(0)


def first_frame(path, pixels: str = "rgb24") -> np.ndarray:
    """The first decoded frame of `path` as (H, W, C) uint8 (C = 3, or 4 for rgba)."""
    read = [ffmpeg_exe(), "-v", "error", "-i", ff_path(path), "-frames:v", "1", "-f", "rawvideo", "-pix_fmt", pixels]
    raw = subprocess.run([*read, "-"], capture_output=True).stdout
    return np.frombuffer(raw, np.uint8).reshape(SMALL_H, SMALL_W, 4 if pixels == "rgba" else 3)


SMALL_W, SMALL_H = 160, 96


def run_video(folder, *args: str, frames: int = 2) -> int:
    size = ["--width", str(SMALL_W), "--height", str(SMALL_H)]
    return run(folder, *size, *args, frames=frames, outputs=[], size=[])


@pytest.mark.parametrize(
    "out, args, says",
    [
        ("a.mp4", ["--codec", "h265"], ["hevc", "yuv420p(tv, bt709"]),
        ("b.mov", [], ["prores (HQ)", "yuv422p10le(tv, bt709"]),
        ("c.mov", ["--codec", "prores", "--quality", "0"], ["prores (Proxy)"]),
        ("d.mp4", ["--lossless"], ["High 4:4:4 Predictive", "yuv444p(tv, bt709"]),
        ("e.mov", ["--codec", "png"], ["png", "rgb24(pc, gbr/bt709/bt709"]),
        pytest.param("f.mov", ["--alpha"], ["prores (4444)", "yuva444p"], marks=pytest.mark.long),
    ],
)
def test_every_codec_is_what_was_asked_and_tagged_bt709(tmp_path, capsys, out, args, says):
    assert run_video(tmp_path, "--out", out, *args) == 0, errors(capsys)
    stream = stream_of(tmp_path / out)
    assert all(word in stream for word in says), stream


@pytest.mark.long  # `python3 -m pytest -m long`
def test_png_is_lossless_and_alpha_makes_the_background_transparent(tmp_path, capsys):
    """A PNG video's frame is the still picture of that frame exactly; H.264 --lossless within the YUV rounding; with
    --alpha the backdrop is transparent and the particles opaque in their colours."""
    for out, args in (("p.mov", ["--codec", "png"]), ("l.mp4", ["--lossless"]), ("s.png", ["--still-frame", "0"])):
        assert run_video(tmp_path, "--out", out, *args, frames=1) == 0, errors(capsys)
    from PIL import Image

    still = np.asarray(Image.open(tmp_path / "s.png").convert("RGB"))
    assert np.array_equal(first_frame(tmp_path / "p.mov"), still)
    assert np.abs(first_frame(tmp_path / "l.mp4").astype(int) - still).max() <= 3
    assert run_video(tmp_path, "--out", "a.mov", "--codec", "png", "--alpha", frames=1) == 0, errors(capsys)
    rgba = first_frame(tmp_path / "a.mov", "rgba")
    alpha = rgba[..., 3]
    solid = alpha == 255
    assert (alpha == 0).mean() > 0.5 and solid.sum() > 40  # mostly backdrop, the particles' cores solid
    assert np.abs(rgba[..., :3][solid].astype(int) - still[solid]).max() <= 2  # the particles in their colours


@pytest.mark.parametrize(
    "out, args, says",
    [
        ("x.gif", ["--codec", "h264"], "a GIF has no codec"),
        ("y.mp4", ["--codec", "prores"], "--codec prores: .mp4 holds h264, h265"),
        ("z.mov", ["--codec", "prores", "--lossless"], "ProRes is never lossless"),
        ("w.mp4", ["--alpha"], "H.264 has no alpha channel"),
        ("q.mp4", ["--quality", "60"], "--quality 60: expected a CRF"),
        ("p.mov", ["--codec", "png", "--quality", "3"], "PNG has no quality setting"),
        ("r.mp4", ["--lossless", "--quality", "3"], "--quality with --lossless"),
    ],
)
def test_a_codec_that_does_not_fit_is_one_line(tmp_path, capsys, out, args, says):
    assert run_video(tmp_path, "--out", out, *args) == EXIT_BAD_INPUT
    lines = errors(capsys)
    assert len(lines) == 1 and says in lines[0], lines
    assert not list(tmp_path.iterdir())


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_resume_with_another_encoding_is_refused(tmp_path, capsys):
    """A checkpoint's video continues only in the encoding it began with (the pieces are joined packet for packet)."""
    assert run_video(tmp_path, "--out", "m.mp4", "--checkpoint-every", "2", "--checkpoint", "c.npz", frames=4) == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    resume = ["run", "candle", "--resume", "c.npz", "--headless", "--quiet", "--frames", "6", "--out", "m.mp4"]
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        code = main([*resume, "--checkpoint-every", "2", "--checkpoint", "c.npz", "--codec", "h265"])
    finally:
        os.chdir(cwd)
    lines = errors(capsys)
    assert code == EXIT_BAD_INPUT and len(lines) == 1 and "encoded as H.264, CRF 15, this run encodes H.265" in lines[0]
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
