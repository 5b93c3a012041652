"""The plant contract: the same bad commands get the same errors, and the same report fields, on every plant.

The three plants are the simulator, the simulator behind a link model and the G1 over DDS (a fake
robot on loopback). They bind commands with the one ``CommandBinder``, so a command that names an
unknown joint, names one actuator twice or has the wrong size fails with the same exception type
and the same message on each; a torque beyond its limit is clamped and counted under the same
actuator name; and each answers ``report()`` with a ``PlantReport`` of the same fields.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from mbctl.control.loop import run
from mbctl.hardware import DdsOptions, UnitreeG1, UnitreeHG
from mbctl.robots.commands import Command, CommandKind, torque
from mbctl.robots.edits import position_to_motor
from mbctl.robots.exceptions import CommandError, UnknownNameError
from mbctl.robots.interface import RobotInterface
from mbctl.robots.plant_report import LinkReport, PlantReport, SafetyReport, TimingReport
from mbctl.sim.link import LinkedSimulator, LinkSpec
from mbctl.sim.simulator import Simulator
from mbctl.unitree import G1_23DOF, G1_29DOF, MotorMap, MotorTableError
from tests.hardware.test_unitree_g1 import HOLD, ConstantTorque, StillBase

BAD_COMMANDS = {
    "unknown joint": (torque({"left_kne_joint": 1.0}), UnknownNameError),
    "one actuator twice": (Command(CommandKind.TORQUE, [1.0, 2.0], ("left_knee_joint", "left_knee_joint")),
                           CommandError),
    "wrong size": (torque(np.zeros(5)), CommandError),
}


@pytest.fixture(scope="module")
def motors_g1(g1):
    """The G1 with torque motors (every plant takes torques on it)."""
    return position_to_motor(g1)


@pytest.fixture
def plants(motors_g1, fake_g1, dds_domain):
    """The three plants on the same robot, each opened; closed at the end."""
    fake_g1()
    sim = Simulator(motors_g1)
    sim.reset("stand")
    linked_sim = Simulator(motors_g1)
    linked_sim.reset("stand")
    made: dict[str, RobotInterface] = {
        "sim": sim,
        "linked": LinkedSimulator(linked_sim, LinkSpec(latency_ms=2.0)),
        "dds": UnitreeG1(motors_g1, StillBase(), DdsOptions(domain=dds_domain, watchdog_periods=50)),
    }
    yield {name: plant.open() for name, plant in made.items()}
    for plant in made.values():
        plant.close()


def _failure(plant: RobotInterface, command: Command) -> tuple[type, str]:
    with pytest.raises((CommandError, UnknownNameError)) as err:
        plant.send(command)
    return type(err.value), str(err.value)


@pytest.mark.parametrize("case", sorted(BAD_COMMANDS))
def test_a_bad_command_gets_the_same_error_on_every_plant(plants, case):
    command, expected = BAD_COMMANDS[case]
    failures = {name: _failure(plant, command) for name, plant in plants.items()}
    assert {kind for kind, _ in failures.values()} == {expected}
    assert len({message for _, message in failures.values()}) == 1, failures
    message = failures["sim"][1]
    assert {"unknown joint": "left_kne_joint", "one actuator twice": "names actuator 'left_knee_joint' twice",
            "wrong size": "needs 29 values"}[case] in message


def test_a_clamped_torque_is_counted_under_the_same_name_on_every_plant(plants, motors_g1):
    limit = MotorMap.for_robot(motors_g1).tau_max[3]  # the left knee's
    for plant in plants.values():
        plant.send(torque({"left_knee_joint": 10 * limit}))
        plant.sync()
        plant.sync()  # the link model delivers it after its 2 ms
    for name, plant in plants.items():
        safety = plant.report().safety
        assert dict(safety.clamped) == {"left_knee_joint": 1}, name
        assert safety.clamped_commands == 1, name


def test_every_plant_reports_the_same_typed_fields(plants):
    for plant in plants.values():
        run(plant, ConstantTorque(plant.robot), HOLD, 0.02)
    reports = {name: plant.report() for name, plant in plants.items()}
    for name, report in reports.items():
        assert isinstance(report, PlantReport), name
        assert isinstance(report.timing, TimingReport) and isinstance(report.link, LinkReport), name
        assert isinstance(report.safety, SafetyReport), name
        assert report.timing.cycles == 10, name
        assert set(report.values()) >= {"interface", "cycles", "period_p50_ms", "period_p99_ms",
                                         "deadline_misses", "messages_lost", "watchdog_events", "clamped"}
    assert [r.link.kind for r in reports.values()] == ["direct", "simulated", "dds"]
    assert reports["sim"].timing.work_p99_ms is None  # not measured in simulation: None, never 0
    assert reports["dds"].timing.work_p99_ms is not None and reports["dds"].link.states_received > 10
    assert reports["dds"].link.commands_lost is None  # a DDS client cannot tell
    assert reports["linked"].link.latency_ms == 2.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        reports["sim"].timing.cycles = 0  # type: ignore[misc]


def test_states_carry_the_plants_tick_and_the_loop_logs_it(plants):
    for name, plant in plants.items():
        log = run(plant, ConstantTorque(plant.robot), HOLD, 0.02)
        assert log.tick.shape == (10,), name
        assert np.all(np.diff(log.tick) >= 0) and log.tick[-1] > log.tick[0], name
    sim_log = run(plants["sim"], ConstantTorque(plants["sim"].robot), HOLD, 0.01)
    assert np.array_equal(np.diff(sim_log.tick), np.ones(4))  # the simulator's physics steps (1 per cycle)


def test_dds_close_damps_and_says_so_and_a_closed_plant_does_not_reopen(plants):
    dds = plants["dds"]
    dds.send(torque(np.zeros(dds.robot.nu)))
    dds.close()
    assert dds.report().safety.damped is True
    assert plants["sim"].report().safety.damped is None  # nothing to damp in simulation
    with pytest.raises(Exception, match="was closed"):
        dds.open()


def test_the_interface_serves_a_second_motor_table(g1, fake_g1, dds_domain):
    """The 23-dof G1 is data: its table and a model with those actuators, no code."""
    spec_robot = _g1_23dof(g1)
    assert MotorMap.for_robot(spec_robot, G1_23DOF).n == 23
    with pytest.raises(MotorTableError, match="G1 29-dof motor table"):
        MotorMap.for_robot(spec_robot, G1_29DOF)
    fake = fake_g1()
    with UnitreeHG(spec_robot, StillBase(), DdsOptions(domain=dds_domain, watchdog_periods=50),
                   table=G1_23DOF) as robot:
        assert robot.motors.n == 23 and robot.read_state().q.shape == (spec_robot.nq,)
        robot.send(torque({"left_wrist_roll_joint": 0.5}))
        robot.sync()
        slot = G1_23DOF.joints.index("left_wrist_roll_joint")
        assert slot == 17
        assert _wait_for_command(fake, lambda cmd: cmd["tau"][slot] == 0.5)


def _wait_for_command(fake, predicate, timeout_s: float = 2.0) -> bool:
    from tests.hardware.test_unitree_g1 import _wait_for

    return _wait_for(lambda: any(predicate(c) for c in fake.commands), timeout_s)


def _g1_23dof(g1):
    """The Menagerie G1 with torque motors on the 23 joints the 23-dof G1 drives (the other six passive)."""
    lacking = {"waist_roll_joint", "waist_pitch_joint", "left_wrist_pitch_joint", "left_wrist_yaw_joint",
               "right_wrist_pitch_joint", "right_wrist_yaw_joint"}

    def edit(spec: mujoco.MjSpec) -> None:
        for act in [a for a in spec.actuators if a.target in lacking]:
            spec.delete(act)
        for key in spec.keys:
            key.ctrl = np.zeros(0)

    return position_to_motor(g1.with_edits("the 23-dof G1's actuators", mj_edit=edit))
