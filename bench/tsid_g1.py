"""The same G1 standing task set in TSID, for bench_wbc.py (TSID 1.10 runs on pin 4.1, as we do).

Tasks as in ``jobs/g1_wbc.g1_whole_body``: CoM (weight 10, omega 10 rad/s), pelvis and torso
orientation (5 and 2, omega 10), posture (0.05, omega 10), and two 6-D contacts on the same four
sole points per foot with the same friction and force bounds. TSID weights are squared in its
cost as ours are, so weights are passed squared. Install: ``pip install tsid`` (it pins the same
Pinocchio).
"""

from __future__ import annotations

import numpy as np
import tsid

from mbctl.control.wbc import WholeBodyController


class TsidG1:
    """TSID's ``InverseDynamicsFormulationAccForce`` with the G1 standing tasks.

    Args:
        ours: Our controller on the same robot (its model, feet and config are reused).
        q: The configuration (nq,) the references are taken from (Pinocchio convention).
    """

    def __init__(self, ours: WholeBodyController, q: np.ndarray):
        model = ours.model
        self.robot = tsid.RobotWrapper(model, tsid.FLOATING_BASE_SYSTEM, False)
        self.formulation = tsid.InverseDynamicsFormulationAccForce("tsid", self.robot, False)
        v = np.zeros(model.nv)
        self.formulation.computeProblemData(0.0, q, v)
        data = self.formulation.data()
        cfg = ours.config
        self.contacts = []
        for name, cs in ours.contacts.items():
            c = tsid.Contact6d(f"contact_{name}", self.robot, cs.contact.frame,
                               np.asarray(cs.contact.points_F).T.copy(), np.array([0.0, 0.0, 1.0]),
                               cs.contact.mu, cfg.f_min_n, cfg.f_max_n)
            c.setKp(cfg.contact_omega_rad_s**2 * np.ones(6))
            c.setKd(2.0 * cfg.contact_omega_rad_s * np.ones(6))
            c.setReference(self.robot.framePosition(data, model.getFrameId(cs.contact.frame)))
            self.formulation.addRigidContact(c, cfg.force_weight**2)
            self.contacts.append(c)
        omega = 10.0
        com = tsid.TaskComEquality("com", self.robot)
        com.setKp(omega**2 * np.ones(3))
        com.setKd(2 * omega * np.ones(3))
        self.formulation.addMotionTask(com, 10.0**2, 1, 0.0)
        self._com_ref = tsid.TrajectoryEuclidianConstant("com", self.robot.com(data))
        com.setReference(self._com_ref.computeNext())
        self.tasks = [com]
        for frame, weight in (("pelvis", 5.0), ("torso_link", 2.0)):
            task = tsid.TaskSE3Equality(f"{frame}_orientation", self.robot, frame)
            task.setKp(omega**2 * np.ones(6))
            task.setKd(2 * omega * np.ones(6))
            task.setMask(np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]))
            self.formulation.addMotionTask(task, weight**2, 1, 0.0)
            ref = tsid.TrajectorySE3Constant(frame, self.robot.framePosition(data, model.getFrameId(frame)))
            task.setReference(ref.computeNext())
            self.tasks.append(task)
        posture = tsid.TaskJointPosture("posture", self.robot)
        posture.setKp(omega**2 * np.ones(self.robot.na))
        posture.setKd(2 * omega * np.ones(self.robot.na))
        self.formulation.addMotionTask(posture, 0.05**2, 1, 0.0)
        posture.setReference(tsid.TrajectoryEuclidianConstant("posture", q[7:].copy()).computeNext())
        self.tasks.append(posture)
        bounds = tsid.TaskActuationBounds("torque_bounds", self.robot)
        bounds.setBounds(ours.tau_low, ours.tau_high)
        self.formulation.addActuationTask(bounds, 1.0, 0, 0.0)
        self.tasks.append(bounds)  # TSID holds C++ references: every task must outlive the formulation
        self.solver = tsid.SolverHQuadProgFast("qp")
        self.solver.resize(self.formulation.nVar, self.formulation.nEq, self.formulation.nIn)
        self.mass = float(data.mass[0])

    def compute(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """One control cycle: problem data and solve; returns tau (na,) [N m]."""
        hqp = self.formulation.computeProblemData(0.0, q, v)
        self.last = self.solver.solve(hqp)
        if self.last.status != 0:
            raise RuntimeError(f"TSID QP failed with status {self.last.status}")
        return self.formulation.getActuatorForces(self.last)

    def normal_force_n(self) -> float:
        """Sum of the contact normal forces [N] of the last solution (world z)."""
        total = 0.0
        for c in self.contacts:
            f = self.formulation.getContactForce(c.name, self.last)
            total += float(c.getNormalForce(f))
        return total

