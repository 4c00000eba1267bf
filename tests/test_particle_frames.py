"""The classroom's pictures drawn by the page (issue 56, item 4): a 2D session sends the picture without its
particles once, the charts' band a few times a second and a particle frame (places, sizes, colours) a picture; what
the page composes from them is the renderer's picture. Scenes the page cannot compose, and `draw="server"`, send
JPEG pictures (3D spheres: tests/test_sphere_frames.py)."""

import base64
import io
import json
from multiprocessing import Pipe
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from sandbox.render.particle_frame import decode

pytestmark = pytest.mark.xdist_group("serve")
WEB = Path(__file__).resolve().parents[1] / "sandbox" / "app" / "web"


def messages(page) -> list[bytes]:
    """Everything the session has sent so far."""
    out = []
    while page.poll(0):
        out.append(page.recv_bytes())
    return out


def composed(backdrop: bytes, bands: list[bytes]) -> np.ndarray:
    """The page's picture under its particles: the backdrop with the last bands pasted where they belong."""
    picture = np.array(Image.open(io.BytesIO(backdrop)).convert("RGB"))
    for band in bands:
        x0, r0 = np.frombuffer(band[:4], np.uint16)
        crop = np.array(Image.open(io.BytesIO(band[4:])).convert("RGB"))
        picture[r0 : r0 + crop.shape[0], x0 : x0 + crop.shape[1]] = crop
    return picture


@pytest.fixture
def session_2d():
    """A melting_block session whose page draws the particles (Taichi starts afresh for each test: one each)."""
    from sandbox.app.serve_session import Session

    page, end = Pipe()
    session = Session(end, "melting_block", 960, 540, draw="page")
    yield session, page
    end.close()


def test_a_2d_session_sends_particle_frames_that_make_the_renderers_picture(session_2d):
    """Composed as the page composes it, the backdrop and band are the renderer's picture wherever no particle is
    drawn (to the byte), each particle sits where the renderer puts it (within 1/32 pixel and f32 rounding) with
    the colour the renderer gives its centre, and the frame carries the session's clock and the last setting
    applied."""
    session, page = session_2d
    sent = messages(page)
    scene = json.loads([m for m in sent if m[:1] == b"J" and b'"scene"' in m][0][1:])
    assert scene["draw"] == "page"
    backdrops = [m[1:] for m in sent if m[:1] == b"B"]
    assert len(backdrops) == 1 and backdrops[0][:4] == b"\x89PNG"
    session.handle({"t": "set", "key": "air", "value": 25.0, "seq": 7})
    sent = []
    for _ in range(14):
        session.frame()
        sent += messages(page)  # read as they come: a pipe holds only so much
    session.page.send_band()  # the charts as they are now (they go every BAND_SECONDS)
    sent += messages(page)
    kinds = [m[:1] for m in sent]
    assert kinds.count(b"P") == 14 and b"F" not in kinds
    bands = [m[1:] for m in sent if m[:1] == b"C"]
    frame = decode([m for m in sent if m[:1] == b"P"][-1])
    sim = session.sim
    assert (frame["frame"], frame["seq"], frame["time"]) == (session.frames, 7, sim.time)
    places = session.renderer.plan.pixels(sim.positions())
    assert len(frame["x"]) == len(places) == 1200
    reach = 1 / 32 + 1e-3  # half a step of 1/16 pixel, and the renderer's single-precision arithmetic
    assert np.abs(frame["x"] - places[:, 0]).max() <= reach and np.abs(frame["y"] - places[:, 1]).max() <= reach
    session.renderer.full_refresh = True
    picture = session.renderer.frame().copy()
    under = composed(backdrops[0], bands)
    clear = np.ones(picture.shape[:2], bool)  # pixels no particle reaches
    for x, y, r in zip(frame["x"], frame["y"], frame["r"]):
        clear[max(int(y - r - 2), 0) : int(y + r + 3), max(int(x - r - 2), 0) : int(x + r + 3)] = False
    assert clear.mean() > 0.5 and np.array_equal(under[clear], picture[clear])
    centres = picture[frame["y"].astype(int), frame["x"].astype(int)]
    same = np.all(centres == frame["rgba"][:, :3], axis=1)
    assert same.mean() > 0.99, same.mean()
    assert np.all(frame["rgba"][:, 3] == 255) and np.all(frame["kind"] == 0)  # opaque discs
    assert np.allclose(frame["r"], frame["r"][0]) and 4.0 < frame["r"][0] < 6.0  # half a spacing, in pixels


@pytest.mark.long  # a picture of each compared pixel by pixel: `python3 -m pytest -m long` (README)
@pytest.mark.parametrize("scene", ["melting_block", "freeze_thaw"])
def test_the_page_draws_a_particle_frame_as_the_renderer_draws_the_picture(scene):
    """The page's own drawing code (discs.js, in Chromium) turns the session's backdrop, band and particle frame into
    the renderer's picture: the same colours at every particle's centre, and on average within a level where the
    discs' anti-aliased edges (and freeze_thaw's springs, drawn as lines under the discs) are drawn by the browser
    instead."""
    import shutil

    from sandbox.app.serve_session import Session

    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("no Chromium (apt-get install chromium)")
    playwright = pytest.importorskip("playwright.sync_api")
    page, end = Pipe()
    session = Session(end, scene, 960, 540, draw="page")
    messages(page)
    if scene == "freeze_thaw":  # the blob pulled apart, paused, 100 springs put in: the lines show between discs
        session.control.pause()
        x = session.sim.particles.x.to_numpy()
        n = int(session.sim.particles.n[None])
        x[:n] = x[:n].mean(axis=0) + 1.6 * (x[:n] - x[:n].mean(axis=0))
        session.sim.particles.x.from_numpy(x)
        springs = session.sim.state.springs
        ends = [springs.i.to_numpy(), springs.j.to_numpy(), springs.alive.to_numpy()]
        ends[0][:100], ends[1][:100], ends[2][:100] = np.arange(100), np.arange(100) + 7, 1
        for field, values in zip((springs.i, springs.j, springs.alive), ends):
            field.from_numpy(values)
        springs.span[None] = max(int(springs.span[None]), 100)
    session.frame()
    sent = messages(page)
    session.page.send_band()
    sent += messages(page)
    frame_bytes = [m for m in sent if m[:1] == b"P"][-1]
    band = [m[1:] for m in sent if m[:1] == b"C"][-1]
    backdrop = composed(session_png_backdrop(session), [band])
    session.renderer.full_refresh = True
    picture = session.renderer.frame().copy()
    app = (WEB / "app.js").read_text()
    app = app.replace("\nstart();", "\n")  # the page's functions, without connecting anywhere
    out = io.BytesIO()
    Image.fromarray(backdrop).save(out, "PNG")
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        try:
            tab = browser.new_page()
            tab.set_content('<canvas id="picture"></canvas><div id="status"></div>')
            tab.add_script_tag(content=(WEB / "discs.js").read_text())
            tab.add_script_tag(content=app)
            pictures = tab.evaluate(
                """async ([png, frames]) => {
                  const bytes = (text) => Uint8Array.from(atob(text), (c) => c.charCodeAt(0)).buffer;
                  const bitmap = await bitmapOf(bytes(png), "image/png");
                  const context = pictureContext(bitmap.width, bitmap.height);
                  const out = [];
                  for (const frame of frames) {
                    context.drawImage(bitmap, 0, 0);
                    drawParticles(context, bytes(frame));
                    out.push(document.getElementById("picture").toDataURL("image/png"));  // lossless, compact
                  }
                  return out;
                }""",
                # the frame, and the frame without its springs' lines
                [b64(out.getvalue()), [b64(frame_bytes), b64(frame_bytes[: 21 + 12 * decode(frame_bytes)["n"]])]],
            )
        finally:
            browser.close()
    drawn, without_lines = (
        np.array(Image.open(io.BytesIO(base64.b64decode(data.split(",", 1)[1]))).convert("RGB")) for data in pictures
    )
    frame = decode(frame_bytes)
    if scene == "freeze_thaw":  # every live spring's ends, in some order, and the renderer's line colour
        springs = session.sim.state.springs
        alive = springs.alive.to_numpy().astype(bool)
        live = {(int(i), int(j)) for i, j in zip(springs.i.to_numpy()[alive], springs.j.to_numpy()[alive])}
        assert {tuple(pair) for pair in frame["springs"].tolist()} == live and len(frame["springs"]) == len(live)
        assert frame["line_rgba"].tolist() == [140, 153, 178, 153]  # SPRING_COLOR, SPRING_OPACITY
        # where the page's lines show between the discs, they bring it to the renderer's picture
        lines = np.any(drawn != without_lines, axis=2)
        near = np.abs(drawn.astype(int) - picture.astype(int))[lines].mean()
        apart = np.abs(without_lines.astype(int) - picture.astype(int))[lines].mean()
        assert lines.sum() > 200 and near < apart / 3, (lines.sum(), near, apart)
    else:
        assert "springs" not in frame
    centres = np.s_[frame["y"].astype(int), frame["x"].astype(int)]
    assert np.mean(np.all(drawn[centres] == picture[centres], axis=1)) > 0.99
    difference = np.abs(drawn.astype(int) - picture.astype(int))
    assert difference.mean() < 1.0 and np.percentile(difference, 99) < 40, (
        difference.mean(),
        np.percentile(difference, 99),
    )
    by_renderer, by_page = np.any(picture != backdrop, axis=2), np.any(drawn != backdrop, axis=2)
    assert by_renderer.mean() > 0.01 and (by_renderer & by_page).sum() > 0.95 * by_renderer.sum(), (
        by_renderer.mean(),
        (by_renderer & by_page).sum() / by_renderer.sum(),
    )


def session_png_backdrop(session) -> bytes:
    from sandbox.render.particle_frame import backdrop_picture

    out = io.BytesIO()
    Image.fromarray(backdrop_picture(session.renderer)).save(out, "PNG")
    return out.getvalue()


def b64(data: bytes) -> str:
    return base64.b64encode(data).decode()


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_light_on_a_page_without_webgl2_and_server_drawing_send_jpeg_pictures():
    """A glowing scene (the candle's additive light) on a page that says it has no WebGL2 ("nogl": light.js cannot
    add the light) gets the renderer's JPEG pictures from then on, as a 2D session does when the server draws
    (`draw="server"`). With WebGL2 the page draws it (tests/test_light_frames.py); 3D scenes send sphere frames
    (tests/test_sphere_frames.py)."""
    from sandbox.app.serve_session import Session

    for scene, draw in (("candle", "page"), ("lj_box", "server")):
        page, end = Pipe()
        session = Session(end, scene, 160, 90, draw=draw)
        said = json.loads([m for m in messages(page) if m[:1] == b"J" and b'"scene"' in m][0][1:])
        assert said["draw"] == ("page" if scene == "candle" else "server")
        session.handle({"t": "nogl"})
        session.frame()
        pictures = [m for m in messages(page) if m[:1] in (b"F", b"P", b"L", b"B", b"C")]
        assert [m[:1] for m in pictures] == [b"F"] and pictures[0][1:3] == b"\xff\xd8"  # one JPEG picture
        end.close()
    with pytest.raises(ValueError, match="draw: expected one of page, server"):
        Session(end, "lj_box", 160, 90, draw="browser")


STEP_SECONDS = 0.0002  # a step's cost, fixed: the allowance moves by the same steps a turn on a busy machine


def test_a_tab_whose_core_is_short_takes_fewer_steps_a_picture_and_all_it_owes_again_with_room(session_2d):
    """Issue 74: a host's tabs share one allowance of steps a frame (pacing.Turns). Where a tab's turn comes every
    80 ms (its 14 neighbours' frames take the core), longer than 1 / SMOOTH_FPS, its frames take fewer steps than
    its clock owes, down to FEWEST frames' worth; with its turn every frame interval again, every step owed."""
    import math

    from sandbox.app.pacing import FEWEST

    session, page = session_2d
    session.turns.share = 15
    record = session.turns.record  # each step costs STEP_SECONDS: the allowance moves alike on a busy machine
    session.turns.record = lambda elapsed, steps, seconds: record(elapsed, steps, STEP_SECONDS * steps)
    substeps = int(session.sim.scene.world.substeps)
    now = due = 0.0

    def frames(count: int, apart: float) -> int:
        """`count` pictures `apart` seconds apart; the steps the last one took."""
        nonlocal now, due
        for _ in range(count):
            before = session.sim.step_count
            session.handle({"t": "ready"})
            due = session.tick(now, due)
            messages(page)
            now += apart
        return session.sim.step_count - before

    assert frames(200, 0.080) == math.ceil(FEWEST * substeps)
    assert frames(200, session.interval) == substeps


def test_the_teachers_thumbnail_comes_from_the_particle_frame_and_looks_like_the_picture(session_2d):
    """Where the page draws, the teacher's thumbnail is made from the particle frame over the picture without its
    particles (no whole picture drawn for it): 240 x 135, within a few levels on average of the renderer's picture
    made small (measured 6.7), and far nearer it than the picture without its particles."""
    session, page = session_2d
    for _ in range(10):
        session.frame()
        messages(page)
    small = session.thumbnail()
    assert small.shape == (135, 240, 3)
    session.renderer.full_refresh = True
    reference = np.asarray(Image.fromarray(session.renderer.frame()).resize((240, 135), Image.Resampling.BILINEAR))
    empty = np.asarray(Image.fromarray(session.page.under).resize((240, 135), Image.Resampling.BILINEAR))
    difference = np.abs(small.astype(int) - reference.astype(int)).mean()
    assert difference < 8.0 and difference < 0.5 * np.abs(empty.astype(int) - reference.astype(int)).mean()


def test_a_tabs_motion_blur_streaks_start_where_its_particles_were_when_the_frame_began():
    """The classroom's fireworks (motion blur, drawn by the server): each picture's streaks run from where a spark
    was when its frame's steps began. Before, a session never told its renderer a frame began, so the tails stayed
    where they were first put (the origin: streaks across the sky, 117 lengths long after 40 frames)."""
    from sandbox.app.serve_session import Session

    page, end = Pipe()
    session = Session(end, "fireworks", 160, 90)
    for _ in range(40):
        session.frame()
        messages(page)
    sim = session.sim
    n = int(sim.particles.n[None])
    x, tail = sim.particles.x.to_numpy()[:n], session.renderer.footprint.x_prev.to_numpy()[:n]
    fastest = np.linalg.norm(sim.particles.v.to_numpy()[:n], axis=1).max()
    frame_time = session.sim.scene.world.substeps * session.sim.scene.world.dt
    assert n > 100 and np.abs(x - tail).max() <= 1.5 * fastest * frame_time
    end.close()


@pytest.mark.long  # a long validation: `python3 -m pytest -m long` (README)
def test_a_sessions_next_tab_compiles_no_page_frame_kernel_again(compiled_kernels):
    """A host's session given to tab after tab (Session.restart) packs its frames with the packers it made for its
    renderer: before, every restart made new ones, which compiled their kernels again (the particle frame's, and a
    glowing scene's light frame's) while the host's other tabs waited."""
    from sandbox.app.serve_session import Session

    class Unread:  # a host's session warms up unseen: what it sends then goes nowhere (a pipe would fill)
        def send_bytes(self, data: bytes) -> None:
            pass

    session = Session(Unread(), "candle", 160, 90)
    session.warm_up()
    for _ in range(2):
        before = len(compiled_kernels)
        session.restart()
        for _ in range(3):
            session.frame()
        assert not {"ParticleFrame._pack", "LightFrame._pack"} & set(compiled_kernels[before:])
