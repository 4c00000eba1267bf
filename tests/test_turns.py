"""Issue 74: a classroom host's tabs keep their scenes' pace by the wall clock and share the core's time alike
(app/pacing.py: SceneClock, Turns), checked on a core simulated in virtual time: each view's frame costs its steps
at a fixed price plus a fixed price for its picture, and the host ticks each attached view when its frame is due
(serve_session.Session.tick's rule)."""

import pytest

from sandbox.app.pacing import SceneClock, Turns

SUBSTEPS = 8  # steps a frame interval, as melting_block
INTERVAL = 1.0 / 30.0  # a tab's frame interval (serve --max-fps 30)
FPS = 20.0  # the pictures a second every tab keeps where the core is short


def run_core(
    views: int, per_step: float, picture: float, seconds: float = 20.0, old_rule: bool = False, substeps=SUBSTEPS
):
    """`views` tabs on one core for `seconds` of virtual time; a step costs `per_step` s and a picture `picture` s.
    Returns (pictures a second, pace: steps taken against the steps of the wall time) for each view, measured over
    the second half. `old_rule`: a frame takes a frame's substeps whenever it comes (the rule before)."""
    clocks = [SceneClock(INTERVAL) for _ in range(views)]
    turns = Turns(FPS)
    turns.share = views
    due = [0.0] * views
    now = 0.0
    frames, steps = [0] * views, [0] * views
    while now < seconds:
        ticked = False
        for k in range(views):
            if due[k] > now:
                continue
            owed, elapsed = clocks[k].owes(now, substeps)
            n = substeps if old_rule else turns.limit(owed, substeps)
            cost = n * per_step
            now += cost + picture
            clocks[k].paid(n)
            turns.record(elapsed, n, cost)
            if now > seconds / 2:
                frames[k] += 1
                steps[k] += n
            due[k] = max(due[k] + INTERVAL, now - INTERVAL)
            ticked = True
        if not ticked:
            now = min(due)
    half = seconds / 2
    return [f / half for f in frames], [s / half / (substeps / INTERVAL) for s in steps]


def test_a_core_with_room_shows_every_tab_at_full_pace_and_30_pictures():
    fps, pace = run_core(views=4, per_step=0.2e-3, picture=1e-3)
    assert min(fps) == pytest.approx(30.0, rel=0.02)
    assert min(pace) == pytest.approx(1.0, abs=0.01)


def test_a_short_core_keeps_20_pictures_a_second_and_gives_every_tab_the_same_pace_the_most_it_allows():
    """15 tabs whose frames at full pace would take 1.3 times the core: each keeps 20 pictures a second and the
    pace the core's remaining time allows (after 20 pictures a second each, the steps it has time for), every tab
    alike. Before, a late frame took a frame's steps: pictures came as fast as the core allowed and the pace was
    their share of 30 (here 25 pictures and 0.84)."""
    views, per_step, picture = 15, 0.22e-3, 0.9e-3
    fps, pace = run_core(views, per_step, picture)
    most = (1.0 / views - FPS * picture) / per_step / (SUBSTEPS / INTERVAL)  # the pace the core can give: 0.92
    assert min(fps) >= 19.5 and max(fps) <= 21.0
    assert min(pace) >= most - 0.03 and max(pace) <= most + 0.01
    assert max(pace) - min(pace) < 0.02
    old_fps, old_pace = run_core(views, per_step, picture, old_rule=True)
    assert max(old_pace) < min(pace) - 0.05 and min(old_fps) > max(fps)


def test_a_frame_late_by_a_stall_takes_the_steps_of_the_time_missed_up_to_catch_up_frames():
    clock = SceneClock(INTERVAL)
    assert clock.owes(0.0, SUBSTEPS) == (SUBSTEPS, INTERVAL)  # the first frame: one interval's
    clock.paid(SUBSTEPS)
    owed, elapsed = clock.owes(2.5 * INTERVAL, SUBSTEPS)
    assert owed == 20 and elapsed == pytest.approx(2.5 * INTERVAL)
    clock.paid(owed)
    assert clock.owes(2.5 * INTERVAL + 10.0, SUBSTEPS)[0] == 4 * SUBSTEPS  # a stall of 10 s: CATCH_UP frames, no more
    clock.paid(4 * SUBSTEPS)
    clock.wait()  # nobody watching: the clock waits
    assert clock.owes(100.0, SUBSTEPS)[0] == SUBSTEPS


def test_a_core_far_too_short_gives_fewer_pictures_not_a_step_a_picture():
    """Where even FEWEST frames' steps a picture cannot keep 20 pictures a second, the pictures give way: each still
    shows half a frame's steps (before this floor the allowance fell to one step a picture: a scene at 1/8 pace)."""
    fps, pace = run_core(views=15, per_step=0.6e-3, picture=2.5e-3)
    assert min(pace) >= 0.5 * min(fps) / 30.0 - 0.01
    assert max(fps) < 20.0


def test_one_stall_on_the_core_cuts_no_tabs_steps():
    """A turn that took a second (a kernel compiled, another program ran) counts as STALL turns in the average: the
    tabs' allowance stays near all the steps they are owed (before, one stall cut it to half a frame's steps, and
    the class ran in slow motion for seconds after)."""
    turns = Turns(FPS)
    turns.share = 15
    turns.limit(SUBSTEPS, SUBSTEPS)
    for _ in range(60):  # a core with room: turns of a frame interval
        turns.record(INTERVAL, SUBSTEPS, SUBSTEPS * 0.2e-3)
    most = turns.allowed
    turns.record(1.0, SUBSTEPS, SUBSTEPS * 0.2e-3)
    for _ in range(15):
        turns.record(INTERVAL, SUBSTEPS, SUBSTEPS * 0.2e-3)
    assert most == 4 * SUBSTEPS and turns.allowed >= 0.8 * most


def test_a_scene_whose_steps_cost_far_more_than_the_core_has_gives_pictures_from_the_start():
    """A world host of six 3D lid scenes (400 steps a frame interval, 1 ms a step for the six): no allowance can
    keep the pace, and each picture shows FEWEST frames' steps (200, 0.2 s) from the first seconds. Before
    STEP_BUDGET the allowance started at CATCH_UP frames' worth (1,600 steps, 1.6 s a picture) and came down about
    16 steps a turn: 0.6 pictures a second for minutes (`sandbox bench --serve 12 --serve-scene
    states_of_matter_atoms`)."""
    fps, pace = run_core(views=1, per_step=1e-3, picture=5e-3, seconds=20.0, substeps=400)
    assert fps[0] > 4.0
    assert pace[0] == pytest.approx(fps[0] * 200 / 400 / 30.0, rel=0.05)  # half a frame's steps a picture
