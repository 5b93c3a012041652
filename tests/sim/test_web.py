"""The browser viewer: served on loopback, drawn by headless Chromium, checked pixel by pixel.

Chromium is Debian's (`.ci/run` installs it), driven by playwright with its own browser download
never used. Outside CI a machine without Chromium skips these tests; CI fails without it.
"""

from __future__ import annotations

import io
import os
import shutil
import signal
import subprocess
import time
from functools import partial

import numpy as np
import pytest

from mbctl.jobs import options
from mbctl.jobs.demo import DEMO
from mbctl.jobs.runner import Job, run_job
from mbctl.jobs.web_view import FORCE_SCALE_M_PER_N, contact_arrows, robot_view, run_view
from mbctl.sim.recorder import read_csv
from mbctl.sim.trajectory import load_trajectory
from mbctl.sim.web import LOOPBACK, WebViewError
from tests.conftest import first_line, mbctl_command, require, run_mbctl

require("viser")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: Headless, software WebGL (SwiftShader), nothing fetched from outside the loopback server.
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


@pytest.fixture(scope="module")
def browser():
    if CHROMIUM is None:
        if os.environ.get("CI"):
            pytest.fail("CI must have Chromium (.ci/run installs Debian's chromium)")
        pytest.skip("no chromium on this machine (apt-get install chromium)")
    playwright = require("playwright.sync_api")
    with playwright.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


def _pixels(page) -> np.ndarray:
    from matplotlib import image

    return image.imread(io.BytesIO(page.screenshot()), format="png")[..., :3].astype(float)


def _settled(page, timeout_s: float = 120.0) -> np.ndarray:
    """The page once two screenshots in a row agree (the scene arrived and was drawn)."""
    deadline = time.monotonic() + timeout_s
    last = _pixels(page)
    while time.monotonic() < deadline:
        page.wait_for_timeout(300)
        now = _pixels(page)
        if np.array_equal(now, last):
            return now
        last = now
    raise AssertionError(f"the page did not settle within {timeout_s} s")


def _open(browser, view):
    page = browser.new_page(viewport={"width": 800, "height": 600})
    page.goto(view.url)
    page.wait_for_selector("canvas", timeout=60_000)
    return page


def _changed(a: np.ndarray, b: np.ndarray) -> float:
    """Fraction of pixels that differ visibly (by more than 10 % in some channel)."""
    return float((np.abs(a - b).max(axis=-1) > 0.1).mean())


def _green(img: np.ndarray) -> int:
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return int(((g - r > 0.2) & (g - b > 0.2)).sum())


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("demo")
    record = run_job(DEMO, options.demo(duration=0.6), folder)
    assert record.status == "completed"
    return folder


def test_replay_draws_the_robot_the_path_and_scrubs(browser, demo_run):
    with run_view(demo_run) as view:
        assert view.url.startswith(f"http://{LOOPBACK}:") and view.port > 0
        page = _open(browser, view)
        shown = _settled(page)
        view.set_robot_visible(False)
        empty = _settled(page)
        assert _changed(shown, empty) > 0.005  # the arm covers > 0.5 % of the page
        assert _green(empty) > 50  # the reference square (green) is drawn
        view.set_robot_visible(True)
        playback = view.playback
        assert playback is not None and playback.frame == 0
        playback.seek(0.6)  # scrub to the end: the arm has moved along the square
        assert playback.frame == len(playback.t) - 1
        assert _changed(shown, _settled(page)) > 0.001
        playback.play()  # from the end, play restarts at the beginning and runs in real time
        deadline = time.monotonic() + 60.0
        while playback.playing and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not playback.playing and playback.frame == len(playback.t) - 1  # played to the end
        playback.seek(0.3)
        playback.play()
        playback.pause()
        frame = playback.frame
        time.sleep(0.2)
        assert playback.frame == frame and playback.button.label == "Play"
        page.close()


def test_view_robot_and_stop(browser, two_link_torque):
    view = robot_view(two_link_torque)
    port = view.port
    page = _open(browser, view)
    shown = _settled(page)
    view.set_robot_visible(False)
    assert _changed(shown, _settled(page)) > 0.005
    page.close()
    view.close()
    view.close()  # idempotent
    import socket

    with socket.socket() as s:  # the server is gone: nothing listens on its port any more
        assert s.connect_ex((LOOPBACK, port)) != 0


def _red(img: np.ndarray) -> np.ndarray:
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return (r - g > 0.3) & (r - b > 0.3)


def test_g1_wbc_replay_draws_the_contact_forces(g1, browser, tmp_path):
    from mbctl.jobs.g1_wbc import WBCParams, prepare

    record = run_job(Job("g1-wbc", partial(prepare, robot=g1)), WBCParams("stand", 0.4), tmp_path)
    assert record.status == "completed"
    # the arrows are the CSV's forces: pointing up, 2 mm per N, their heads at the CoP on the floor
    model, t, qpos, _ = load_trajectory(tmp_path)
    table = read_csv(record.files["csv"])
    rows = np.searchsorted(table["time_s"], t + 1e-9, side="right") - 1
    start, vec = contact_arrows(table, model, rows, qpos, "mj")
    i = len(t) - 1
    assert start.shape == (len(t), 2, 3) and rows[i] == len(table["time_s"]) - 1
    head = start + vec
    np.testing.assert_allclose(head[i, 0, :2],
                               [table["left_foot_cop_x_mj_m"][-1], table["left_foot_cop_y_mj_m"][-1]])
    np.testing.assert_allclose(head[i, :, 2], 0.0)  # the floor of Menagerie's scene
    np.testing.assert_allclose(vec[i, :, 2], FORCE_SCALE_M_PER_N * np.array(
        [table["left_foot_fz_mj_N"][-1], table["right_foot_fz_mj_N"][-1]]))
    assert 0.5 * 9.81 * 30 * FORCE_SCALE_M_PER_N < vec[i, :, 2].sum()  # the G1 (~35 kg) stands on them
    with run_view(tmp_path) as view:
        assert set(view.overlays) == {"/overlay/force_mj", "/overlay/force_qp"}
        page = _open(browser, view)
        view.playback.seek(0.4)
        shown = _settled(page)
        for handle in view.overlays.values():
            handle.visible = False
        hidden = _settled(page)
        assert (_red(shown) & ~_red(hidden)).sum() > 30  # red arrows, gone when hidden
        view.set_robot_visible(False)
        assert _changed(hidden, _settled(page)) > 0.005  # and the G1 itself is drawn
        page.close()


def test_the_video_and_the_browser_draw_the_floor_pushing_the_robot_up(g1, tmp_path):
    """One convention in both: the force the floor exerts on the robot, up for a standing G1 (the
    browser drew the force each foot pressed into the floor, pointing down)."""
    import mujoco

    from mbctl.jobs.g1_wbc import WBCParams, prepare
    from mbctl.sim.video import contact_force_geoms

    record = run_job(Job("g1-wbc", partial(prepare, robot=g1)), WBCParams("stand", 0.2), tmp_path)
    model, t, qpos, _ = load_trajectory(tmp_path)
    table = read_csv(record.files["csv"])
    rows = np.searchsorted(table["time_s"], t + 1e-9, side="right") - 1
    start, vec = contact_arrows(table, model, rows, qpos, "mj")
    web = vec[-1] / np.linalg.norm(vec[-1], axis=1, keepdims=True)  # the browser: one per foot
    np.testing.assert_allclose(web, [[0, 0, 1], [0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose((start + vec)[-1, :, 2], 0.0)  # up to the contact, on the floor
    data = mujoco.MjData(model)
    data.qpos[:] = qpos[-1]
    mujoco.mj_forward(model, data)
    mp4 = contact_force_geoms(model, data)  # the MP4: MuJoCo's arrows, one per contact point
    assert len(mp4.type) >= 4 and set(mp4.type) == {int(mujoco.mjtGeom.mjGEOM_ARROW)}
    up = mp4.mat.reshape(-1, 3, 3)[:, :, 2]  # an arrow points along its z axis
    assert up[:, 2].min() > 0.9, up  # up, friction tilting it by under 26 deg (measured 10-19)
    assert np.abs(mp4.pos[:, 2]).max() < 0.01  # from the contact, on the floor


def _serve(*args):
    proc = subprocess.Popen(mbctl_command(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = first_line(proc, "stdout")  # once the server is up (or the command failed)
    return proc, line


def test_cli_serves_on_loopback_and_stops_on_ctrl_c(demo_run):
    import urllib.request

    proc, line = _serve("replay", str(demo_run), "--web", "--port", "0")
    try:
        assert line.startswith(f"serving http://{LOOPBACK}:"), (line, proc.stderr.read())
        url = line.split()[1]
        with urllib.request.urlopen(url, timeout=30) as response:
            assert response.status == 200 and b"<html" in response.read(2000).lower()
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and "viewer stopped" in out, err
    assert "Traceback" not in err
    import socket

    with socket.socket() as s:
        assert s.connect_ex((LOOPBACK, int(url.rstrip("/").rsplit(":", 1)[1]))) != 0


@pytest.mark.parametrize(("args", "message"), [
    (["view", "two_link", "--web", "--port", "70000"], "port must be in [0, 65535]"),
    (["replay", "NOWHERE", "--web"], "holds no trajectory.npz"),
])
def test_cli_bad_input_exits_2(args, message, tmp_path):
    args = [str(tmp_path) if a == "NOWHERE" else a for a in args]
    proc = run_mbctl(*args, timeout=120)
    assert proc.returncode == 2 and message in proc.stderr and "Traceback" not in proc.stderr


def test_a_taken_port_is_named(two_link_torque):
    with robot_view(two_link_torque) as first:
        with pytest.raises(WebViewError, match=f"cannot serve on {LOOPBACK}:{first.port}"):
            robot_view(two_link_torque, port=first.port)


def test_robot_view_shows_the_keyframe(g1):
    with robot_view(g1, keyframe="stand") as view:
        np.testing.assert_array_equal(view.data.qpos, g1.mj_model.key_qpos[g1.keyframe_id("stand")])
    with robot_view(g1) as view:
        np.testing.assert_array_equal(view.data.qpos, g1.mj_model.qpos0)
