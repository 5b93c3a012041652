"""Column names of streamed control-loop rows: one per q and v entry, every joint type."""

from __future__ import annotations

from mbctl.jobs.recording import q_columns, v_columns
from mbctl.robots import load_robot

MJCF = """
<mujoco>
  <worldbody>
    <body name="base" pos="0 0 1">
      <freejoint name="root"/>
      <geom type="box" size="0.1 0.1 0.1" mass="1"/>
      <body name="a" pos="0.2 0 0">
        <joint name="ball" type="ball"/>
        <geom type="sphere" size="0.05" mass="0.5"/>
        <body name="b" pos="0.2 0 0">
          <joint name="slider" type="slide" axis="1 0 0"/>
          <geom type="sphere" size="0.05" mass="0.5"/>
          <body name="c" pos="0.2 0 0">
            <joint name="hinge" axis="0 0 1"/>
            <geom type="sphere" size="0.05" mass="0.5"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator><motor joint="hinge"/><motor joint="slider"/></actuator>
</mujoco>
"""


def test_columns_cover_q_and_v_for_every_joint_type(tmp_path):
    path = tmp_path / "robot.xml"
    path.write_text(MJCF)
    robot = load_robot(path)
    q, v = q_columns(robot), v_columns(robot)
    assert (len(q), len(v)) == (robot.nq, robot.nv) == (7 + 4 + 1 + 1, 6 + 3 + 1 + 1)
    assert q == ["root_x_m", "root_y_m", "root_z_m", "root_qx", "root_qy", "root_qz", "root_qw",
                 "ball_qx", "ball_qy", "ball_qz", "ball_qw", "q_slider_m", "q_hinge_rad"]
    assert v == ["root_vx_m_s", "root_vy_m_s", "root_vz_m_s", "root_wx_rad_s", "root_wy_rad_s",
                 "root_wz_rad_s", "ball_wx_rad_s", "ball_wy_rad_s", "ball_wz_rad_s", "v_slider_m_s",
                 "v_hinge_rad_s"]
