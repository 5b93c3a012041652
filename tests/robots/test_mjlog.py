"""MuJoCo's warnings never leave MUJOCO_LOG.TXT in the working directory of a process using mbctl."""

from __future__ import annotations

import subprocess
import sys

NAN_STEP = """
import mujoco, numpy as np
m = mujoco.MjModel.from_xml_string(
    '<mujoco><worldbody><body><joint/><geom size="0.1"/></body></worldbody></mujoco>')
d = mujoco.MjData(m)
d.qpos[0] = np.nan
mujoco.mj_step(m, d)  # MuJoCo warns: Nan, Inf or huge value in QPOS
assert d.warning[mujoco.mjtWarning.mjWARN_BADQPOS].number == 1
"""


def _run(code: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, timeout=60)


def test_no_mujoco_log_in_the_working_directory(tmp_path):
    plain, with_mbctl = tmp_path / "plain", tmp_path / "mbctl"
    plain.mkdir()
    with_mbctl.mkdir()
    assert _run(NAN_STEP, plain).returncode == 0
    assert (plain / "MUJOCO_LOG.TXT").exists()  # what MuJoCo does on its own
    out = _run("import mbctl.sim\n" + NAN_STEP, with_mbctl)
    assert out.returncode == 0, out.stderr
    assert "Nan, Inf or huge value in QPOS" in out.stdout + out.stderr  # the console line stays
    assert list(with_mbctl.iterdir()) == []


def test_a_log_file_the_user_chose_is_kept(tmp_path):
    log = tmp_path / "mine.log"
    code = (f"import mujoco\nc = mujoco.MjLogConfig.get()\nc.logfile = {str(log)!r}\nc.set()\n"
            "import mbctl.robots\n" + NAN_STEP)
    assert _run(code, tmp_path).returncode == 0
    assert "QPOS" in log.read_text() and not (tmp_path / "MUJOCO_LOG.TXT").exists()
