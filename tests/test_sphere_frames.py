"""The classroom's 3D pictures drawn by the page (issue 74, item 2): a 3D session of opaque spheres sends the
picture without its particles and a sphere frame (camera, places, radii, colours) a picture, and the page's WebGL
code (spheres.js) turns them into the renderer's picture; a page without WebGL2 gets the renderer's pictures."""

import base64
import io
import json
import shutil
from multiprocessing import Pipe

import numpy as np
import pytest
from PIL import Image

from sandbox.render.sphere_frame import decode
from tests.test_particle_frames import WEB, b64, messages

pytestmark = pytest.mark.xdist_group("serve")


@pytest.fixture
def session_3d():
    """A melting_block_3d session whose page draws the spheres."""
    from sandbox.app.serve_session import Session

    page, end = Pipe()
    session = Session(end, "melting_block_3d", 480, 270, draw="page")
    yield session, page
    end.close()


def picture_of(data: bytes) -> np.ndarray:
    return np.array(Image.open(io.BytesIO(data)).convert("RGB"))


def test_a_3d_session_sends_sphere_frames_with_the_renderers_camera_and_colours(session_3d):
    """The scene says the page draws; the backdrop is the renderer's picture wherever no sphere is drawn (to the
    byte); each frame carries the session's clock, the last setting applied, the renderer's camera, every particle's
    place and drawn radius, and the colour the renderer gives it. Turning the camera sends the backdrop again."""
    session, page = session_3d
    sent = messages(page)
    scene = json.loads([m for m in sent if m[:1] == b"J" and b'"scene"' in m][0][1:])
    assert scene["draw"] == "page" and scene["dim"] == 3
    backdrops = [picture_of(m[1:]) for m in sent if m[:1] == b"B"]
    assert len(backdrops) == 1
    session.handle({"t": "set", "key": "air", "value": 25.0, "seq": 5})
    sent = []
    for _ in range(4):
        session.frame()
        sent += messages(page)
    kinds = [m[:1] for m in sent]
    assert kinds.count(b"S") == 4 and b"F" not in kinds and b"B" not in kinds
    from sandbox.app.serve_session import FRAMES
    from sandbox.render.particle_frame import PAGE_FRAMES

    assert set(FRAMES) == {b"F", *PAGE_FRAMES}  # the server passes every kind on and counts each as a picture
    frame = decode([m for m in sent if m[:1] == b"S"][-1])
    sim, painter = session.sim, session.renderer.painter
    assert (frame["frame"], frame["seq"], frame["time"]) == (session.frames, 5, sim.time)
    step = np.array(frame["camera"][32:35]) / 65535  # a place is given to half a 65,535th of the box (and f32)
    assert np.all(np.abs(frame["x"] - sim.positions()) <= 0.5 * step + 1e-5)
    assert np.allclose(frame["camera"][:12], painter.camera.to_numpy().ravel())
    assert frame["camera"][12] == pytest.approx(float(painter.focal_field[None]))
    radius = sim.particles.radius.to_numpy()[: len(frame["x"])] * session.renderer.cfg.particle_scale
    assert np.abs(np.abs(frame["r"]) - radius).max() <= 0.5 * frame["camera"][35] / 65535 + 1e-6
    assert np.all(frame["r"] > 0)  # shaded spheres
    assert len(sent[-1]) == 21 + 144 + 12 * len(radius)  # 12 bytes a particle
    session.renderer.full_refresh = True
    picture = session.renderer.frame().copy()
    clear = np.all(picture == backdrops[0], axis=2)
    assert 0.3 < clear.mean() < 0.97  # spheres cover part of the picture, the rest is the backdrop to the byte
    session.view("orbit", 0.1, 0.0)
    session.page.last_backdrop = -1e9
    session.frame()
    assert [m[:1] for m in messages(page)].count(b"B") == 1


def draw_in_chromium(scripts: list[str], sent: list[bytes]) -> tuple[np.ndarray | None, bool]:
    """What the page's code draws from the session's messages `sent` (the backdrop, bands and a sphere frame, in
    order) in headless Chromium (None where the browser has no WebGL2), and whether the page asked the session for
    pictures instead."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("no Chromium (apt-get install chromium)")
    playwright = pytest.importorskip("playwright.sync_api")
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox", "--use-angle=swiftshader"])
        try:
            tab = browser.new_page()
            tab.set_content('<canvas id="picture"></canvas><div id="status"></div>')
            for script in scripts:
                tab.add_script_tag(content=script)
            drawn, asked = tab.evaluate(
                """async (messages) => {
                  const bytes = (text) => Uint8Array.from(atob(text), (c) => c.charCodeAt(0)).buffer;
                  const said = [];
                  send = (msg) => said.push(msg.t);
                  for (const message of messages) await onBytes(bytes(message));
                  const canvas = document.getElementById("picture");
                  return [said.includes("nogl") ? null : canvas.toDataURL("image/png"), said.includes("nogl")];
                }""",
                [b64(m) for m in sent if m[:1] in (b"B", b"C", b"S")],
            )
        finally:
            browser.close()
    if drawn is None:
        return None, asked
    return picture_of(base64.b64decode(drawn.split(",", 1)[1])), asked


def page_scripts() -> list[str]:
    app = (WEB / "app.js").read_text().replace("\nstart();", "\n")  # the page's functions, not connecting anywhere
    return [(WEB / "discs.js").read_text(), (WEB / "spheres.js").read_text(), app]


@pytest.mark.long  # Chromium drawing each scene (the molecular ones compile the molecular model): the long tier
@pytest.mark.parametrize("scene", ["melting_block_3d", "evaporation", "states_of_matter_atoms"])
def test_the_page_draws_a_sphere_frame_as_the_renderer_draws_the_picture(scene):
    """The page's WebGL code (spheres.js in Chromium, on its software GPU) turns the session's backdrop, charts'
    band and sphere frame into the renderer's picture: 99% of the pixels within two levels of the renderer's (the
    shading's float rounding), the pixels covered by spheres the same to within 1% of them; with evaporation's
    charts (atoms of the molecular model, drawn flat), the charts drawn over the spheres as the renderer draws
    them; with states_of_matter_atoms' lid, its tinted cross-section and outline, which hides what lies behind it."""
    from sandbox.app.serve_session import Session

    page, end = Pipe()
    session = Session(end, scene, 480, 270, draw="page")
    sent = messages(page)
    for _ in range(3):
        session.frame()
        sent += messages(page)  # read as they come: a pipe holds only so much
    session.page.send_band()
    session.frame()
    sent += messages(page)
    end.close()
    assert [m[:1] for m in sent].count(b"C") >= (scene != "melting_block_3d")
    assert decode([m for m in sent if m[:1] == b"S"][-1])["camera"][20] == (scene == "states_of_matter_atoms")
    session.renderer.full_refresh = True
    picture = session.renderer.frame().copy()
    drawn, asked = draw_in_chromium(page_scripts(), sent)
    if drawn is None:
        pytest.skip("this Chromium has no WebGL2")
    assert drawn.shape == picture.shape and not asked
    difference = np.abs(drawn.astype(int) - picture.astype(int)).max(axis=2)
    assert np.mean(difference <= 2) > 0.99, np.mean(difference <= 2)
    under = picture_of([m for m in sent if m[:1] == b"B"][-1][1:])
    covered = np.any(picture != under, axis=2)  # the renderer's spheres (and the chart's new points)
    shown = np.any(drawn != under, axis=2)
    assert covered.mean() > 0.05 and (covered ^ shown).sum() < 0.01 * covered.sum()


def test_a_page_without_webgl2_asks_for_pictures_and_gets_them(session_3d):
    """Where the browser has no WebGL2 the page says "nogl" rather than showing nothing; the session then sends
    the renderer's JPEG pictures, for this scene and the next 3D one."""
    session, page = session_3d
    session.frame()
    sent = messages(page)
    no_webgl = (
        "const plainContext = HTMLCanvasElement.prototype.getContext;"
        "HTMLCanvasElement.prototype.getContext = function (kind, options) {"
        "  return kind === 'webgl2' ? null : plainContext.call(this, kind, options); };"
    )
    drawn, asked = draw_in_chromium([no_webgl, *page_scripts()], sent)
    assert drawn is None and asked
    session.handle({"t": "nogl"})
    session.frame()
    assert [m[:1] for m in messages(page)] == [b"J", b"F"]
    session.load("melting_block_3d")
    session.frame()
    said = messages(page)
    scene = json.loads([m for m in said if m[:1] == b"J" and b'"scene"' in m][0][1:])
    assert scene["draw"] == "server" and [m[:1] for m in said].count(b"F") == 1
