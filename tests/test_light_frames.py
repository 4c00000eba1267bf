"""Issue 74: scenes whose particles glow (candle's flame; fireworks' sparks, with curved motion-blur streaks) are
drawn by the page too: the session sends a light frame (render/light_frame.py) before each particle frame, and the
page's own code (light.js, WebGL2 in Chromium) adds the light to its picture as the renderer does."""

import base64
import io
import shutil
from multiprocessing import Pipe

import numpy as np
import pytest
from PIL import Image

from sandbox.render.light_frame import decode_light
from sandbox.render.particle_frame import decode
from tests.test_particle_frames import WEB, b64, composed, messages, session_png_backdrop

pytestmark = pytest.mark.xdist_group("serve")

PAGE_CODE = ("discs.js", "light.js")


def page_picture(chromium: str, backdrop: np.ndarray, light: bytes, frame: bytes) -> np.ndarray:
    """The page's picture from `backdrop` (with the charts), the light frame and the particle frame, drawn by the
    page's own code in Chromium."""
    playwright = pytest.importorskip("playwright.sync_api")
    out = io.BytesIO()
    Image.fromarray(backdrop).save(out, "PNG")
    app = (WEB / "app.js").read_text().replace("\nstart();", "\n")  # the page's functions, connecting nowhere
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        try:
            tab = browser.new_page()
            tab.set_content('<canvas id="picture"></canvas><div id="status"></div>')
            for name in PAGE_CODE:
                tab.add_script_tag(content=(WEB / name).read_text())
            tab.add_script_tag(content=app)
            data = tab.evaluate(
                """async ([png, light, frame]) => {
                  const bytes = (text) => Uint8Array.from(atob(text), (c) => c.charCodeAt(0)).buffer;
                  const bitmap = await bitmapOf(bytes(png), "image/png");
                  const context = pictureContext(bitmap.width, bitmap.height);
                  context.drawImage(bitmap, 0, 0);
                  drawParticles(context, bytes(frame));
                  if (!drawLight(context, bytes(light))) return null;
                  return document.getElementById("picture").toDataURL("image/png");
                }""",
                [b64(out.getvalue()), b64(light), b64(frame)],
            )
        finally:
            browser.close()
    assert data is not None, "no WebGL2 with float colour buffers in this Chromium"
    return np.array(Image.open(io.BytesIO(base64.b64decode(data.split(",", 1)[1]))).convert("RGB"))


@pytest.mark.long  # a browser's picture of each glowing scene: `python3 -m pytest -m long` (README)
@pytest.mark.parametrize("scene, frames", [("candle", 30), ("fireworks", 45)])
def test_the_page_adds_the_glowing_particles_light_as_the_renderer_does(scene, frames):
    """A glowing scene's session sends a light frame, then a particle frame whose glowing particles the page does
    not draw as discs; the page's picture is the renderer's: on average within a level, 99% of pixels within a few,
    the light where the renderer's is (the pixels it brightens over the picture without light)."""
    from sandbox.app.serve_session import Session

    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("no Chromium (apt-get install chromium)")
    page, end = Pipe()
    session = Session(end, scene, 960, 540, draw="page")
    for _ in range(frames):
        session.frame()
        messages(page)
    session.frame()
    sent = messages(page)
    kinds = [m[:1] for m in sent if m[:1] in (b"F", b"L", b"P")]
    assert kinds == [b"L", b"P"]  # the light, then its frame; no JPEG
    light, frame = (next(m for m in sent if m[:1] == kind) for kind in (b"L", b"P"))
    session.page.send_band()
    band = [m[1:] for m in messages(page) if m[:1] == b"C"]
    backdrop = composed(session_png_backdrop(session), band)
    glowing = decode_light(light)
    records = decode(frame)
    assert 20 < len(glowing["intensity"]) <= int(np.sum(records["kind"] == 2))  # (those off the picture give none)
    assert np.all(glowing["intensity"] > 0.0) and glowing["curved"] == (scene == "fireworks")
    assert glowing["blurred"].any() == (scene == "fireworks")
    session.renderer.full_refresh = True
    picture = session.renderer.frame().copy()
    drawn = page_picture(chromium, backdrop, light, frame)
    difference = np.abs(drawn.astype(int) - picture.astype(int))
    assert difference.mean() < 1.0 and np.percentile(difference, 99) < 12, (
        difference.mean(),
        np.percentile(difference, 99),
    )
    without_light = page_picture(chromium, backdrop, light[:5] + bytes(4) + light[9:], frame)  # exposure 0: no light
    lit = np.any(drawn.astype(int) - without_light > 8, axis=2)  # where the page's light shows
    assert lit.sum() > 200 and difference[lit].mean() < 2.0, (lit.sum(), difference[lit].mean())
    assert np.abs(without_light.astype(int) - picture.astype(int))[lit].mean() > 20.0  # and it is the light that does


def test_a_spark_born_this_frame_is_drawn_still_not_streaked_from_a_stale_tail():
    """fireworks' gold shell goes off again at 2.5 s (in the 79th frame), its 700 sparks born into slots that the
    dead sparks' compaction freed: the frame they are born in has no tail for them, so each is drawn still where it
    is. Before, each took the tail left in its slot (where another spark had been a frame ago): 539 of them were
    drawn as streaks up to 160 pixels long, from nowhere to the shell."""
    import sandbox
    from sandbox.render.light_frame import LightFrame
    from sandbox.render.raster import Renderer

    sim = sandbox.load("fireworks")
    renderer = Renderer(sim.model, sim.state, 320, 180, sim.scene.render, output="picture")
    sim.state.carry(renderer.tails)
    light = LightFrame(renderer)
    for _ in range(79):
        renderer.begin_frame()
        sim.advance_frame(None, renderer.mid_frame)
    assert sum(sim.terms.emitters.emitted) > sim.state.live_count() + 700  # sparks died before this burst
    drawn = decode_light(light.encode())
    painter = renderer.painter
    shell = np.array([50.0, 60.0]) * painter.px_per_unit + painter.offset.to_numpy()
    shell[1] = renderer.height - shell[1]  # rows from the top
    near = np.linalg.norm(drawn["head"] - shell, axis=1) < 1.5 * painter.px_per_unit  # the newborn, and any passing
    streaks = np.linalg.norm(drawn["head"] - drawn["tail"], axis=1)[near]
    assert near.sum() >= 700 and drawn["blurred"][near].sum() <= 2 and streaks.max() < 2.0
