"""How a run's video is encoded, for players and for editors: the codec, its quality, lossless, alpha, and the
BT.709 colour tags every video carries.

    .mp4   h264 (default) or h265
    .mov   prores (default), png, h264 or h265; prores and png can carry alpha (`--alpha`)

Every video's pictures are converted from the sandbox's RGB with BT.709's matrix (YUV codecs: limited range) and
tagged BT.709 (primaries, transfer, matrix, range), because players and editors read HD video as BT.709 and an
untagged stream converted with swscale's default (BT.601) matrix shows shifted colours in them. A PNG stream keeps
RGB and is tagged with BT.709's primaries and transfer.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import SandboxError

CODECS = ("h264", "h265", "prores", "png")
CONTAINERS = {".mp4": ("h264", "h265"), ".mov": ("prores", "png", "h264", "h265")}  # the first is the default
QUALITY = {"h264": 15, "h265": 18, "prores": 3}  # CRF (lower is better) or ProRes's profile (0 proxy .. 3 HQ)
QUALITY_RANGE = {"h264": (0, 51), "h265": (0, 51), "prores": (0, 3)}
NAMES = {"h264": "H.264", "h265": "H.265", "prores": "ProRes", "png": "PNG"}
TAGS = ["-color_primaries", "bt709", "-color_trc", "bt709"]
YUV_TAGS = [*TAGS, "-colorspace", "bt709", "-color_range", "tv"]
TO_YUV709 = (
    "scale=out_color_matrix=bt709:out_range=tv,"
    "setparams=color_primaries=bt709:color_trc=bt709:colorspace=bt709:range=tv"
)
RGB709 = "setparams=color_primaries=bt709:color_trc=bt709:colorspace=gbr:range=pc"


@dataclass(frozen=True)
class VideoCodec:
    """A video's encoding: `name` one of CODECS, `quality` its QUALITY (None: the default), `lossless` (h264 and
    h265 in 4:4:4 at no loss in YUV; png always), `alpha` (prores 4444 and png: the pictures' background
    transparent)."""

    name: str = "h264"
    quality: int | None = None
    lossless: bool = False
    alpha: bool = False

    @property
    def input_format(self) -> str:
        """The raw frames ffmpeg is given: rgb24, or rgba with alpha."""
        return "rgba" if self.alpha else "rgb24"

    def args(self) -> list[str]:
        """ffmpeg's output arguments for this encoding (filters, codec, pixel format, quality, tags)."""
        q = QUALITY.get(self.name) if self.quality is None else self.quality
        if self.name == "png":
            return ["-vf", RGB709, "-vcodec", "png", "-pix_fmt", "rgba" if self.alpha else "rgb24", *TAGS]
        if self.name == "prores":
            profile, pix = ("4", "yuva444p10le") if self.alpha else (str(q), "yuv422p10le")
            extra = ["-alpha_bits", "16"] if self.alpha else []
            codec = ["-vcodec", "prores_ks", "-profile:v", profile, "-pix_fmt", pix, *extra, "-vendor", "apl0"]
            return ["-vf", TO_YUV709, *codec, *YUV_TAGS]
        pix = "yuv444p" if self.lossless else "yuv420p"
        if self.name == "h264":
            rate = ["-qp", "0"] if self.lossless else ["-crf", str(q)]
            return ["-vf", TO_YUV709, "-vcodec", "libx264", "-pix_fmt", pix, *rate, *YUV_TAGS]
        params = "log-level=error" + (":lossless=1" if self.lossless else f":crf={q}")
        codec = ["-vcodec", "libx265", "-pix_fmt", pix, "-x265-params", params, "-tag:v", "hvc1"]
        return ["-vf", TO_YUV709, *codec, *YUV_TAGS]

    def words(self) -> str:
        """The encoding in words ("H.264, CRF 15"), as a resume's refusal names it."""
        if self.name == "png":
            return "PNG" + (" with alpha" if self.alpha else "")
        if self.name == "prores":
            return "ProRes 4444 with alpha" if self.alpha else f"ProRes profile {self.profile()}"
        return f"{NAMES[self.name]}, " + ("lossless" if self.lossless else f"CRF {self.profile()}")

    def profile(self) -> int:
        return QUALITY[self.name] if self.quality is None else self.quality


def choose_codec(
    suffix: str | None, name: str | None = None, quality: int | None = None, lossless: bool = False, alpha: bool = False
) -> VideoCodec:
    """The encoding of a video ending in `suffix` (None: the run writes no video) asked for by --codec, --quality,
    --lossless and --alpha; a SandboxError of one line naming what does not go together."""
    suffix = suffix.lower() if suffix is not None else None
    asked = name is not None or quality is not None or lossless or alpha
    if suffix not in CONTAINERS:
        if asked:
            what = {None: "a run without a video", ".gif": "a GIF"}.get(suffix, "a PNG output")
            raise SandboxError(
                f"--codec/--quality/--lossless/--alpha: {what} has no codec; expected an .mp4 or .mov --out"
            )
        return VideoCodec()
    name = name or CONTAINERS[suffix][0]
    if name not in CONTAINERS[suffix]:
        raise SandboxError(
            f"--codec {name}: {suffix} holds {', '.join(CONTAINERS[suffix])}; expected one of them, or a .mov --out"
        )
    if quality is not None:
        if name not in QUALITY_RANGE:
            raise SandboxError(f"--quality {quality}: {NAMES[name]} has no quality setting (it is lossless)")
        lo, hi = QUALITY_RANGE[name]
        if not lo <= quality <= hi:
            what = "a CRF (lower is better)" if name != "prores" else "a ProRes profile (0 proxy, 3 HQ)"
            raise SandboxError(f"--quality {quality}: expected {what} from {lo} to {hi} for {NAMES[name]}")
        if lossless:
            raise SandboxError("--quality with --lossless: a lossless video has no quality to choose; expected one")
    if lossless and name == "prores":
        raise SandboxError("--lossless: ProRes is never lossless; expected --codec png (or h264/h265) for lossless")
    if alpha and name not in ("prores", "png"):
        raise SandboxError(f"--alpha: {NAMES[name]} has no alpha channel; expected --codec prores or png in a .mov")
    return VideoCodec(name, quality, lossless or name == "png", alpha)
