"""The whole-body QP with its structure: a block-diagonal Hessian, equalities, two-sided rows, bounds.

The controller's problem over ``x = [vdot (nv); f (n_f)]``::

    min  1/2 x^T H x + c^T x,    H = blockdiag(H_vv, w_f^2 I),   c = [c_v; 0]
    s.t. E x = e                              (base dynamics, feet in contact)
         g_lo <= G x <= g_up                  (friction pyramids, torque limits)
         lb <= x <= ub                        (joint-limit accelerations, normal forces)

Solved in three ways, tried in this order:

* **Equality-constrained fast path.** The optimum of the QP without its inequalities comes from
  the KKT system, by the Schur complement on the equalities: with ``H_vv = L L^T``,
  ``S = E H^-1 E^T`` (m_eq x m_eq, SPD when E has full row rank),
  ``lambda = -S^-1 (e + E H^-1 c)`` and ``x = -H^-1 (c + E^T lambda)``. If that point satisfies
  every inequality and bound (to :data:`FEASIBILITY_TOL`), it is the QP's optimum (the problem is
  convex and no inequality is active). This is the first iteration of any active-set method,
  written here because daqp's setup with 18 equality rows costs ~60 us (e.g. on the G1; measured,
  ``bench/bench_wbc.py``) while this costs a Cholesky of the 35 x 35 block and an 18 x 18 solve.
  Standing and squatting never leave it (no inequality is active there). Force variables pinned
  at zero (:attr:`WholeBodyQP.force_free` False: a foot whose force ramp is at 0, so its normal
  force's bounds are [0, 0] and its friction pyramid pins the tangential forces too) are left out
  of the Schur complement and set to zero: fixing them is the QP's own constraint, so the point is
  still the optimum when it satisfies every other inequality, and single support (one foot
  released) stays on this path too.
* **The QP in the free forces alone** (:mod:`.force_space`): vdot eliminated through the
  equalities, daqp on the forces with the rows over them alone (friction, torsion), the point
  kept when it satisfies every bound and row (it is then the optimum). Not tried while the last
  point had a bound on vdot or a row with vdot in it binding (:data:`ACTIVE_TOL`).
* **daqp** (the dual active-set solver) on the QP without its pinned forces and deferred rows
  (:mod:`.reduced_qp`), else on the whole problem, through the control layer's QP floor
  (:mod:`mbctl.control.qp`: daqp called directly, its buffers reused, two-sided torque rows
  instead of qpsolvers' two one-sided rows each), whenever the ways above fail or E is
  rank-deficient. Calling ``daqp.solve`` directly instead of through ``qpsolvers.solve_problem``
  saves the wrapper's conversions (~17 us per solve, measured).

Other QP backends (``proxqp``, ``osqp``...) go through ``qpsolvers`` on the same problem
(:meth:`WholeBodyQP.solve_with`), for comparison. Every solve returns the floor's
:class:`~mbctl.control.qp.QPResult`.
"""

from __future__ import annotations

import time
from typing import cast

import numpy as np
import qpsolvers
from scipy.linalg.blas import dgemm, dtrsm, dtrsv
from scipy.linalg.lapack import dposv, dpotrf, dpotrs, dpstrf

from mbctl.control.qp import (
    CONTRADICTORY,
    OPTIMAL,
    QPData,
    QPResult,
    QPSolver,
    solve_qpsolvers,
)
from mbctl.control.wbc.force_space import RANK_RTOL, ForceSpace
from mbctl.control.wbc.reduced_qp import DEFERRED_TOL, ReducedQP

#: Largest violation [problem units: rad/s^2, N, N m] of an inequality or bound that the fast
#: path's point may have and still count as feasible (daqp's own primal tolerance is 1e-6).
FEASIBILITY_TOL = 1e-9

# the ufuncs' reductions: ndarray.max and .min's Python wrappers left out (~0.3 us a call)
_max, _min, _all = np.maximum.reduce, np.minimum.reduce, np.logical_and.reduce


#: Distance [problem units] from its bound within which a bound or row counts as active when no
#: duals tell (the skip of the force-space QP, :attr:`WholeBodyQP.use_force_space`).
ACTIVE_TOL = 1e-7


class _Schur:
    """The fast path's buffers for ``m_eq`` equality rows, and the views of them and of E it reads.

    Made once per count (no slicing per solve). ``Z`` (n_x, m_eq + 1) in C order (its top block is
    contiguous), ``[y; -1]`` (m_eq + 1,) and ``Z^T Z`` (m_eq + 1, m_eq + 1) in Fortran order (BLAS
    writes it in place); see :meth:`WholeBodyQP._kkt`.
    """

    def __init__(self, qp: WholeBodyQP, m_eq: int):
        nv, m_f = qp.nv, min(qp.m_force, m_eq)
        self.Z = np.zeros((qp.n_x, m_eq + 1))
        self.ZT = self.Z.T
        self.Z_vT = self.Z[:nv].T  # Fortran-contiguous: solved in place
        self.Z_vE, self.Z_c = self.Z[:nv, :m_eq], self.Z[:nv, m_eq]
        self.Z_f = self.Z[nv:, m_eq - m_f:m_eq]  # (the force rows' other columns stay zero)
        self.E_vT, self.E_fT = qp.E[:m_eq, :nv].T, qp.E[m_eq - m_f:m_eq, nv:].T
        self.e, self.rows = qp.e[:m_eq], qp._rows[:m_eq]
        self.y_ext = np.zeros(m_eq + 1)
        self.y_ext[m_eq] = -1.0
        self.y = self.y_ext[:m_eq]
        self.ZtZ = np.zeros((m_eq + 1, m_eq + 1), order="F")
        self.S, self.EHc = self.ZtZ[:m_eq, :m_eq], self.ZtZ[:m_eq, m_eq]
        self.S_diagonal = self.S.diagonal()


class WholeBodyQP:
    """Buffers and solver for the whole-body QP of a fixed size (see the module docstring).

    The caller fills the public buffers each cycle, then calls :meth:`solve`.

    Args:
        nv: Number of accelerations.
        n_f: Number of force variables.
        m_in: Number of two-sided inequality rows.
        m_eq_max: The most equality rows a cycle may have.
        force_weight: ``w_f`` [cost]/[N]: the force block of H is ``w_f^2 I``.
        m_force: Only the last ``m_force`` of the equality rows in use (``E[m_eq - m_force:m_eq]``)
            have non-zero force columns (default: any row may); the others are skipped in
            ``E_f E_f^T``.

    Attributes:
        H_vv: (nv, nv) the acceleration block of H (symmetric positive definite).
        c_v: (nv,) the acceleration part of c.
        E: (m_eq_max, n_x) equality rows; the first ``m_eq`` are used.
        e: (m_eq_max,) their right-hand side.
        G: (m_in, n_x) inequality rows; ``g_lo``, ``g_up`` (m_in,) their bounds (+-inf: none).
        rows: (m_eq_max + m_in, n_x) ``E`` then ``G``: the buffer both are views of.
        lb, ub: (n_x,) bounds on x (+-inf: none).
        (g_lo, g_up, lb and ub are views into two buffers: write into them, never rebind them.)
    """

    def __init__(self, nv: int, n_f: int, m_in: int, m_eq_max: int, force_weight: float,
                 m_force: int | None = None):
        self.nv, self.n_f, self.n_x = nv, n_f, nv + n_f
        self.m_force = m_eq_max if m_force is None else m_force
        self.m_in, self.m_eq_max = m_in, m_eq_max
        self.H_vv = np.zeros((nv, nv), order="F")  # Fortran order: copied as is into the Cholesky factor's
        self.c_v = np.zeros(nv)
        # E and G in one buffer: a caller may write a block that spans both (e.g. [M, -Jc^T]'s rows)
        self.rows = np.zeros((m_eq_max + m_in, self.n_x))
        self.E, self.G = self.rows[:m_eq_max], self.rows[m_eq_max:]
        self.e = np.zeros(m_eq_max)
        # the bounds, then the rows' bounds, in one array per side (one comparison checks them all)
        self._lo = np.full(self.n_x + m_in, -np.inf)
        self._up = np.full(self.n_x + m_in, np.inf)
        self.lb, self.g_lo = self._lo[:self.n_x], self._lo[self.n_x:]
        self.ub, self.g_up = self._up[:self.n_x], self._up[self.n_x:]
        self._xg = np.zeros(self.n_x + m_in)  # [x; G x]
        self._excess = np.zeros(self.n_x + m_in)  # the feasibility check's violations
        #: (n_f,) False for a force variable the caller has pinned at zero (its bounds [0, 0], or a
        #: tangential force whose pyramid's normal force is pinned): the fast path leaves it out
        self.force_free = np.ones(n_f, dtype=bool)
        self._free_f = np.ones(n_f)  # force_free as 0/1, read by the fast path
        self.force_weight = force_weight
        # the whole Hessian and linear term for daqp (its packing buffers are the floor's)
        self._H = np.zeros((self.n_x, self.n_x))
        self._c = np.zeros(self.n_x)
        self._daqp_solver = QPSolver(self.n_x, "daqp")
        self._rows = np.arange(m_eq_max)
        self._schur: dict[int, _Schur] = {}  # the fast path's buffers, by number of equality rows
        # H_vv's Cholesky factor, made in place: Fortran order, or f2py copies it before LAPACK sees it
        self._L = np.zeros((nv, nv), order="F")
        self._pinned = False
        self._skip_fast = False  # the last solve was daqp's with an inequality active
        #: (m_in,) G x at the last solve's x when the fast path gave it (its feasibility check
        #: computed it; a view of a new array each solve), else None
        self.Gx: np.ndarray | None = None
        #: Inequality rows (a slice of G's) that daqp first solves without: rows that are rarely
        #: active (the controller's torque limits), checked at the reduced QP's optimum
        self.deferred_rows: slice | None = None
        self._reduced = ReducedQP(self)  # daqp without the pinned forces and the deferred rows
        #: Whether daqp first solves the QP in the free forces alone (:mod:`.force_space`)
        self.use_force_space = True
        self._force = ForceSpace(nv, self.E, self.e, self.G, self._lo, self._up, self.m_force)
        self._skip_force = False  # the last point had an acceleration bound or a row with vdot active
        self._v_ineq: np.ndarray | None = None  # those bounds' and rows' indices in [x; G x]

    @property
    def force_weight(self) -> float:
        """``w_f`` [cost]/[N] (assignable)."""
        return self._w_f

    @force_weight.setter
    def force_weight(self, value: float) -> None:
        self._w_f = float(value)
        self._inv_wf = 1.0 / self._w_f

    def solve(self, m_eq: int) -> QPResult:
        """Solve with the first ``m_eq`` equality rows: the fast path, else daqp.

        Contradictory bounds (a lower above its upper) are reported before daqp is called (status
        :data:`~mbctl.control.qp.CONTRADICTORY`, one comparison over the contiguous bounds): the
        fast path's point cannot satisfy them (it is accepted within :data:`FEASIBILITY_TOL` of every
        bound, so only bounds crossed by less than twice that pass, as any point within it would).
        Linearly dependent equality rows (e.g. the feet of legs without a hip yaw, which cannot
        yaw relative to each other) are reduced to an independent subset (the pivots of
        ``E H^-1 E^T``), and the result says how many were dropped: the dropped rows hold only as
        far as they agree with the kept ones.

        The fast path is tried first unless the last solve was daqp's with an inequality or bound
        active (other than on pinned forces) and no dependent row: then the fast point would most
        likely violate it again (as in most of a walk's cycles, where the CMP sits on the support
        polygon's edge), and the try (e.g. ~70 us on the G1, half a daqp solve) is skipped. Should daqp
        then find no solution, the solve is repeated the full way, so the result is the same.

        Returns:
            The floor's result: ``x`` (n_x,) finite or None, ``fast_path`` True when no
            inequality is active (``iterations`` 0), ``dependent_rows`` the rows dropped.
        """
        t0 = time.perf_counter()
        self.Gx = None
        pinned = not _all(self.force_free)
        if pinned or self._pinned:  # (_free_f stays all ones while no force is pinned)
            np.copyto(self._free_f, self.force_free)
        self._pinned = pinned
        if self._skip_fast:
            if (self._lo > self._up).any():
                return QPResult(None, CONTRADICTORY, 0, 0.0)
            result, self._skip_fast = self._daqp(self._rows[:m_eq], 0, False)
            if result.x is not None:
                return result
        x, rows = self._kkt(m_eq)
        dropped = m_eq - len(rows)
        if x is not None and self._feasible(x, xg=cast(np.ndarray, x.base)):
            self._skip_fast = False
            self.Gx = cast(np.ndarray, x.base)[self.n_x:]
            return QPResult(x, OPTIMAL, 0, time.perf_counter() - t0, True, dropped)
        if (self._lo > self._up).any():
            return QPResult(None, CONTRADICTORY, 0, 0.0)
        result, active = self._daqp(rows, dropped, x is not None)
        self._skip_fast = dropped == 0 and active
        return result

    def _inequality_active(self, result: QPResult) -> bool:
        """Whether daqp's solution has an inequality or bound active, other than one on pinned forces only."""
        if result.x is None or result.duals is None:
            return False
        lam = result.duals[:self.n_x + self.m_in]
        if not self._pinned:
            return bool(lam.any())
        return bool(np.any((lam != 0.0) & ~self._reduced.reduction().pinned_rows))

    def _factor(self, m_eq: int) -> _Schur | None:
        """``H_vv = L L^T`` (in ``_L``) and Z's rows of vdot, ``[L^-1 E_v^T, L^-1 c_v]``, for ``m_eq`` rows.

        Returns:
            The buffers of ``m_eq`` rows, or None if H_vv is not positive definite.
        """
        b = self._schur.get(m_eq)
        if b is None:
            b = self._schur[m_eq] = _Schur(self, m_eq)
        # LAPACK and BLAS directly: numpy.linalg's wrappers cost several us of Python per call here
        np.copyto(b.Z_vE, b.E_vT)
        np.copyto(b.Z_c, self.c_v)
        np.copyto(self._L, self.H_vv)
        # H_vv = L L^T in place (positional: lower, clean=0, overwrite_a; the upper triangle is left
        # as it was, never read: every solve with L reads its lower one)
        L, info = dpotrf(self._L, 1, 0, 1)
        if info != 0:
            return None
        # Z_v^T (Fortran order) L^-T = (L^-1 Z_v)^T: solved in place
        # (positional: side=1, lower=1, trans_a=1, diag=0, overwrite_b=1; f2py's keyword parsing cost
        # 0.6-0.8 us a call, measured on this and the dtrsv below)
        dtrsm(1.0, L, b.Z_vT, 1, 1, 1, 0, 1)
        return b

    def _kkt(self, m_eq: int) -> tuple[np.ndarray | None, np.ndarray]:
        """The minimiser under the first ``m_eq`` equalities only (KKT by Schur complement).

        With ``H_vv = L L^T``, one buffer ``Z = [L^-1 E_v^T, L^-1 c_v; E_f^T / w_f, 0]`` (one
        triangular solve, in place) gives ``Z^T Z = [S, E H^-1 c; ...]`` in one product:
        ``S = E H^-1 E^T = Y_E^T Y_E + E_f E_f^T / w_f^2``. Then ``y = -lambda = S^-1 (e + E H^-1 c)``,
        ``vdot = L^-T (Y_E y - Y_c)`` (a second solve, one column) and ``f = E_f^T y / w_f^2``: both
        from ``Z [y; -1]`` (Z's force rows are 0 in its last column).

        Returns:
            ``(x, rows)``: x (n_x,) or None if H_vv is not positive definite (x: the first n_x
            entries of a new (n_x + m_in,) array, ``x.base``); ``rows`` the indices of a maximal
            independent subset of the equality rows (x satisfies those). Pinned forces
            (``force_free`` False, as read by :meth:`solve`) are left out and zero.
        """
        nv = self.nv
        b = self._factor(m_eq)
        if b is None:
            return None, self._rows[:m_eq]
        all_rows, L = b.rows, self._L
        np.multiply(b.E_fT, self._inv_wf, out=b.Z_f)
        if self._pinned:
            b.Z_f *= self._free_f[:, None]  # the pinned forces' columns left out (they stay at zero)
        # [S, E H^-1 c; ., .] (c_f = 0, H_ff = w_f^2 I) by BLAS's gemm, Z^T (Z^T)^T, in place (positional:
        # beta, c, trans_a, trans_b, overwrite_c): ~0.9 us less than np.dot's syrk and its mirror
        dgemm(1.0, b.ZT, b.ZT, 0.0, b.ZtZ, 0, 1, 1)
        S = b.S
        np.add(b.EHc, b.e, out=b.y)  # e + E H^-1 c
        # S: a plain Cholesky when E has full row rank (pivots well above round-off), else a
        # pivoted one, whose rank is E's and whose pivots pick independent rows
        scale = _max(b.S_diagonal)
        # y = -lambda in place (positional: lower, overwrite_a=0, overwrite_b; info > 0 when S is not
        # positive definite)
        Ls, _, info = dposv(S, b.y, 1, 0, 1)
        # x in a new array's first n_x entries, G x to follow (the feasibility check's [x; G x])
        x = np.empty(self.n_x + self.m_in)[:self.n_x]
        if info == 0 and _min(Ls.diagonal()) ** 2 > RANK_RTOL * scale:
            rows = all_rows
            np.dot(b.Z, b.y_ext, out=x)  # [Y_E y - Y_c; E_f^T y / w_f]: Z whole is contiguous (~1 us less)
        else:
            rhs = b.EHc + b.e  # (y holds what dposv left)
            _, piv, rank, _ = dpstrf(S, tol=RANK_RTOL * max(float(scale), 1e-300), lower=1)
            rows = np.sort(piv[:rank] - 1)
            Ls, _ = dpotrf(S[np.ix_(rows, rows)], lower=1)
            y_rows, _ = dpotrs(Ls, rhs[rows], lower=1)
            np.dot(b.Z[:, rows], y_rows, out=x)
            x[:nv] -= b.Z_c
        # x = -H^-1 (c + E^T lambda): vdot = L^-T (Y_E y - Y_c), f = E_f^T y / w_f^2
        vdot = x[:nv]
        # in place (vdot is contiguous); positional: incx=1, offx=0, lower=1, trans=1, diag=0, overwrite_x=1
        dtrsv(L, vdot, 1, 0, 1, 1, 0, 1)
        x[nv:] *= self._inv_wf
        return x, rows

    def _feasible(self, x: np.ndarray, tol: float = FEASIBILITY_TOL, xg: np.ndarray | None = None) -> bool:
        """Whether ``x`` satisfies every bound and inequality row to ``tol``.

        Args:
            x: (n_x,) the point.
            tol: The largest violation allowed [problem units].
            xg: (n_x + m_in,) an array whose first n_x entries are ``x`` (G x is written after
                them), or None (a buffer of the QP's, x copied into it).
        """
        if xg is None:
            xg = self._xg
            xg[:self.n_x] = x
        np.dot(self.G, x, out=xg[self.n_x:])
        excess = self._excess  # (a held buffer: no allocation per check)
        return bool(_max(np.subtract(self._lo, xg, out=excess)) <= tol
                    and _max(np.subtract(xg, self._up, out=excess)) <= tol)

    def _daqp(self, eq_rows: np.ndarray, dropped: int, factored: bool) -> tuple[QPResult, bool]:
        """The QP by daqp, with the equality rows ``eq_rows`` (the first ones if ``dropped`` is 0).

        First the QP in the free forces alone (:meth:`_solve_forces`; not while the last point had
        an acceleration bound or a row with vdot in it active, where it would fail its check again),
        then the reduced QP when there is something to leave out (:mod:`.reduced_qp`: without the
        deferred rows and the pinned forces, then with the pins, without the pinned forces only),
        else or when those fail, the whole one.

        Args:
            eq_rows: The equality rows' indices.
            dropped: How many rows the fast path dropped as dependent (0: ``eq_rows`` are the first).
            factored: The fast path has just factored ``H_vv`` for these rows (:meth:`_factor`).

        Returns:
            The result and whether an inequality or bound (other than a pinned force's) is active.
        """
        if dropped == 0 and self.use_force_space and not self._skip_force:
            solved = self._solve_forces(len(eq_rows), factored)
            if solved is not None:
                return solved
        # without the deferred rows (and the pinned forces), then without the pinned forces alone: daqp
        # can fail on the whole QP's degenerate vertex of a released foot's pinned forces (ReducedQP.solve)
        defers = [True] if self.deferred_rows is not None else []
        if self._pinned:
            defers.append(False)
        for defer in defers:
            reduced = self._reduced.solve(eq_rows, dropped == 0, defer)
            if reduced is not None:  # (its check left [x; G x] in _xg)
                self._note_acceleration_limits(reduced[0], measured=True)
                return reduced[0]._replace(dependent_rows=dropped), reduced[1]
        result = self._daqp_solver.solve(self.data(eq_rows, dropped == 0))
        self._note_acceleration_limits(result)
        return result._replace(dependent_rows=dropped), self._inequality_active(result)

    def _solve_forces(self, m_eq: int, factored: bool) -> tuple[QPResult, bool] | None:
        """The QP over the free forces (:mod:`.force_space`), if its point satisfies every bound and row.

        Returns:
            ``(result, active)`` as :meth:`_daqp`'s (``Gx`` set, as the fast path's), or None: the
            equality rows dependent, no solution, or a bound or row with vdot in it violated (then
            the next solves skip it until a point has none of those active).
        """
        t0 = time.perf_counter()
        b = self._schur[m_eq] if factored else self._factor(m_eq)
        if b is None or not self._free_f.any():
            return None
        xg = np.empty(self.n_x + self.m_in)
        x = xg[:self.n_x]
        solved = self._force.solve(b.Z, self._L, m_eq, self._free_f, self._w_f, x)
        if solved is None:
            return None
        if not self._feasible(x, DEFERRED_TOL, xg=xg):
            self._skip_force = True
            return None
        self.Gx = xg[self.n_x:]
        iterations, duals = solved
        return QPResult(x, OPTIMAL, iterations, time.perf_counter() - t0), bool(duals.any())

    def _note_acceleration_limits(self, result: QPResult, measured: bool = False) -> None:
        """Skip the force-space QP next time exactly when a bound or row with vdot in it binds at ``result``.

        Binding: within :data:`ACTIVE_TOL` of its limit (daqp's duals are the reduced QP's, or absent).
        """
        if not self.use_force_space or result.x is None:
            return
        if self._v_ineq is None:  # (G's pattern at the first daqp solve: its rows are filled by then)
            rows_v = np.flatnonzero(self.G[:, :self.nv].any(axis=1))
            self._v_ineq = np.concatenate([np.arange(self.nv), self.n_x + rows_v])
        xg = self._xg
        if not measured:  # (measured: the reduced QP's check wrote [x; G x] there)
            xg[:self.n_x] = result.x
            np.dot(self.G, result.x, out=xg[self.n_x:])
        at = self._v_ineq
        gap = np.minimum(xg[at] - self._lo[at], self._up[at] - xg[at])
        self._skip_force = bool(_min(gap) <= ACTIVE_TOL)

    def data(self, eq_rows: np.ndarray | int, consecutive: bool = True) -> QPData:
        """The whole QP for the floor: views of the buffers, H and c assembled in reused buffers.

        Args:
            eq_rows: The equality rows to use: their indices, or a count ``m_eq`` (the first ones).
            consecutive: ``eq_rows`` are ``0..m_eq-1`` (then E and e are sliced, not copied).
        """
        nv = self.nv
        H = self._H
        H[:nv, :nv] = self.H_vv
        np.einsum("ii->i", H)[nv:] = self._w_f * self._w_f
        self._c[:nv] = self.c_v
        if isinstance(eq_rows, int) or consecutive:
            m_eq = eq_rows if isinstance(eq_rows, int) else len(eq_rows)
            E, e = self.E[:m_eq], self.e[:m_eq]
        else:
            E, e = self.E[eq_rows], self.e[eq_rows]
        return QPData(H, self._c, self.lb, self.ub, self.G, self.g_up, E, e, self.g_lo)

    def solve_with(self, solver: str, m_eq: int) -> QPResult:
        """Solve with another backend through qpsolvers (for comparison; no fast path)."""
        self.Gx = None
        return solve_qpsolvers(self.data(m_eq), solver)

    def problem(self, m_eq: int) -> qpsolvers.Problem:
        """The same QP as a ``qpsolvers.Problem`` (copies; for other backends and for diagnosis)."""
        return self.data(m_eq).problem()
