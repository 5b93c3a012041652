"""How the DDS interface reaches a robot and how strict it is: :class:`DdsOptions` and its defaults."""

from __future__ import annotations

import math
from dataclasses import dataclass

from mbctl.hardware.exceptions import HardwareError
from mbctl.unitree import LOOPBACK
from mbctl.unitree.channel import DISCOVERY_S

#: Periods without a new state after which the link counts as lost, by default.
WATCHDOG_PERIODS = 25
#: How long the interface waits for the robot's state stream by default [s].
CONNECT_TIMEOUT_S = 1.0


@dataclass(frozen=True)
class DdsOptions:
    """How to reach the robot and how strict to be.

    Attributes:
        domain: DDS domain id (the robot's is 0).
        network_interface: The interface wired to the robot (default ``lo``: the bridge on this
            machine).
        rate_hz: The robot's state rate [Hz], which paces the loop; None measures it at connect.
        connect_timeout_s: How long to wait for the robot's state stream [s].
        watchdog_periods: Periods without a new LowState after which the link counts as lost.
        limit_tolerance_rad: How far [rad] a joint may be past its limit at start (encoder slack
            at the end stops).
        dry_run: Read and report the state, never command.
        quiet_loop: During the loop: no garbage collection (the objects made before it frozen) and
            real-time priority where permitted (see the module docstring).
        check_state_crc: Refuse LowStates with CRC 0 too (the real G1 signs its states); False
            accepts those unchecked (Unitree's simulator leaves the CRC 0), never a wrong non-zero one.
        cyclone_config: A Cyclone DDS configuration file of the user's, used as written (None:
            the one mbctl makes for ``network_interface``).
        discovery_s: How long [s] from the start connecting waits at least for discovery to show
            another ``rt/lowcmd`` writer (another client): the interface then refuses to start.
        stable_gains: Lower the position-target gains and the damping command's kd where a plant
            applying the motor law once per state period, a period late (Unitree's simulator), would
            not keep them stable with margin (:mod:`mbctl.hardware.motor_law`); each lowered gain is
            reported (``gains_lowered``). False sends the gains as given (the G1's own drivers run
            the law far faster).
    """

    domain: int = 0
    network_interface: str = LOOPBACK
    rate_hz: float | None = None
    connect_timeout_s: float = CONNECT_TIMEOUT_S
    watchdog_periods: int = WATCHDOG_PERIODS
    limit_tolerance_rad: float = 0.01
    dry_run: bool = False
    quiet_loop: bool = True
    check_state_crc: bool = True
    cyclone_config: str | None = None
    discovery_s: float = DISCOVERY_S
    stable_gains: bool = True

    def __post_init__(self) -> None:
        if self.rate_hz is not None and not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise HardwareError(f"rate_hz must be a positive number of Hz (the G1's is 500); "
                                f"got {self.rate_hz}")
        if not (math.isfinite(self.connect_timeout_s) and self.connect_timeout_s > 0):
            raise HardwareError(f"connect_timeout_s must be > 0 s; got {self.connect_timeout_s}")
        if self.watchdog_periods < 1:
            raise HardwareError(f"watchdog_periods must be >= 1; got {self.watchdog_periods}")
