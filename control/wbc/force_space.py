"""The whole-body QP in its contact forces alone, the accelerations eliminated through the equalities.

For fixed forces ``f`` the accelerations of :mod:`mbctl.control.wbc.qp`'s problem minimise
``1/2 vdot^T H_vv vdot + c_v^T vdot`` under ``E_v vdot = e - E_f f``: with ``H_vv = L L^T``,
``Y = L^-1 E_v^T``, ``y_c = L^-1 c_v`` and ``S = Y^T Y = Ls Ls^T``, their optimum is
``vdot = L^-T (Y y - y_c)``, ``y = S^-1 (a_0 - E_f f)``, ``a_0 = e + Y^T y_c``, and the cost there is
``1/2 |Ls^-1 (a_0 - E_f f)|^2`` plus a constant. The QP left in ``f`` (k free forces)::

    min  1/2 f^T (T^T T + w_f^2 I) f - (T^T t_0)^T f,    T = Ls^-1 E_f,  t_0 = Ls^-1 a_0
    s.t. the bounds on f and the rows over f alone (friction pyramids, each sole's torsion)

has k variables (e.g. 12 in single support on a sole's four contact points, 24 in double) and no
equality, against the whole QP's 47 or 59 variables with 12 or 18 equalities (e.g. on the G1).
It is a relaxation in one sense only: the bounds on vdot and the rows with vdot in them
(joint-limit accelerations, torque limits) are left out, so
its point is the whole QP's optimum exactly when that point satisfies them too (the whole QP is
convex; its optimum then solves the relaxation, whose optimum is unique) — the caller checks it
against every bound and row. Only the last ``m_force`` equality rows have force columns (the base's
dynamics rows), so ``T``'s other rows are zero: ``T`` is their block ``Ls_22^-1 E_fu``.

Written here because no QP library reduces a problem by its equalities this way: daqp's setup, redone
every call, grows with n^2 m, so on walking cycles (the centre of pressure on a sole's edge, an
inequality active in most of them) the whole QP took ~55-65 us in daqp against ~10 us for this one
(measured on 1676 walking cycles' problems; the points agree to 4e-5 in N and rad/s^2, daqp's
tolerance).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg.blas import dgemm, dgemv, dtrsm, dtrsv
from scipy.linalg.lapack import dpotrf

from mbctl.control.qp import solve_packed
from mbctl.robots.indexing import as_slice

#: Relative pivot [-] below which an equality row counts as dependent on the others (in the metric
#: of ``E H^-1 E^T``; the fast path's too, :mod:`mbctl.control.wbc.qp`).
RANK_RTOL = 1e-10

# the ufuncs' reductions: ndarray.max and .min's Python wrappers left out (~0.3 us a call)
_max, _min = np.maximum.reduce, np.minimum.reduce


class _Pattern:
    """The free forces and the force-only rows over them, and the daqp packing (per pin pattern and m)."""

    def __init__(self, free: np.ndarray, rows: np.ndarray, nv: int, n_x: int, m_f: int):
        k, r = len(free), len(rows)
        self.k, self.n_rows = k, r
        self.free = as_slice(free)  # (slices where contiguous: a foot's forces and its rows are)
        self.cols = as_slice(nv + free)  # the free forces' columns of x
        self.rows = as_slice(rows)
        self.bounds_at = np.concatenate([nv + free, n_x + rows])  # in [x; G x]
        self.Tb = np.zeros((m_f, k), order="F")  # Ls_22^-1 E_fu over the free forces
        self.Hf = np.zeros((k, k), order="F")
        self.HfT = self.Hf.T  # (symmetric: the C-ordered array daqp reads)
        self.Hf_diagonal = np.einsum("ii->i", self.Hf)
        self.cf = np.zeros(k)
        self.A = np.zeros((r, k))
        self.upper = np.zeros(k + r)
        self.lower = np.zeros(k + r)
        self.sense = np.zeros(k + r, dtype=np.intc)


class _Equalities:
    """Buffers for ``m`` equality rows, ``m_f`` of them with force columns."""

    def __init__(self, m: int, m_f: int):
        self.P = np.zeros((m + 1, m + 1), order="F")  # Z_v^T Z_v: [S, Y^T y_c; ., |y_c|^2]
        self.S = np.zeros((m, m), order="F")  # S, then its Cholesky factor Ls in place
        self.S_diagonal = self.S.diagonal()
        self.P_S, self.P_c = self.P[:m, :m], self.P[:m, m]
        self.y_ext = np.zeros(m + 1)  # [a_0 -> t -> y; -1]
        self.y_ext[m] = -1.0
        self.y = self.y_ext[:m]
        self.t_b = self.y[m - m_f:]  # the rows with force columns


class ForceSpace:
    """The QP over the free forces, on a :class:`~mbctl.control.wbc.qp.WholeBodyQP`'s buffers.

    Args:
        nv: Number of accelerations.
        E: (m_eq_max, n_x) the equality rows; only the last ``m_force`` of those in use have force
            columns.
        e: (m_eq_max,) their right-hand side.
        G: (m_in, n_x) the inequality rows.
        lo, up: (n_x + m_in,) the bounds on x, then on ``G x``.
        m_force: How many of the last equality rows may have force columns.
    (Views of the QP's buffers, read at every solve: never rebound.)
    """

    def __init__(self, nv: int, E: np.ndarray, e: np.ndarray, G: np.ndarray, lo: np.ndarray, up: np.ndarray,
                 m_force: int):
        self.nv, self.n_x = nv, E.shape[1]
        self.E, self.e, self.G, self.lo, self.up = E, e, G, lo, up
        self.m_force = m_force
        self._equalities: dict[int, _Equalities] = {}
        self._patterns: dict[tuple[bytes, int], _Pattern] = {}

    def _pattern(self, free_f: np.ndarray, m: int) -> _Pattern:
        """The free forces and the rows over them alone, for the present pins (made once per pattern).

        Taken with G's pattern of non-zeros at the time: a stale pattern gives a point that fails
        the caller's check against every row, never a wrong optimum.
        """
        key = (free_f.tobytes(), m)
        pattern = self._patterns.get(key)
        if pattern is None:
            nv = self.nv
            free = np.flatnonzero(free_f)
            G_f = self.G[:, nv:][:, free]
            rows = np.flatnonzero(~self.G[:, :nv].any(axis=1) & (G_f != 0.0).any(axis=1))
            pattern = self._patterns[key] = _Pattern(free, rows, nv, self.n_x, min(self.m_force, m))
        return pattern

    def solve(self, Z: np.ndarray, L: np.ndarray, m: int, free_f: np.ndarray, force_weight: float,
              x: np.ndarray) -> tuple[int, np.ndarray] | None:
        """The QP over the free forces; ``x`` (n_x,) receives ``[vdot; f]`` (pinned forces 0).

        Args:
            Z: (n_x, m + 1) C-ordered, whose first nv rows are ``[Y, y_c] = L^-1 [E_v^T, c_v]`` for
                the first ``m`` equality rows (the fast path's buffer, filled by the caller).
            L: (nv, nv) ``H_vv``'s Cholesky factor (lower triangle).
            m: Equality rows in use (the first m).
            free_f: (n_f,) 1.0 for a free force, 0.0 for one pinned at zero.
            force_weight: ``w_f``.
            x: (n_x,) contiguous, the output.

        Returns:
            ``(iterations, duals)`` (daqp's, over the free forces' bounds then the rows), or None
            when the equality rows are dependent or daqp finds no solution (x then undefined).
        """
        nv = self.nv
        p = self._pattern(free_f, m)
        m_f = p.Tb.shape[0]
        q = self._equalities.get(m)
        if q is None:
            q = self._equalities[m] = _Equalities(m, m_f)
        # BLAS and LAPACK positionally (f2py's keyword parsing costs ~0.7 us a call). [S, Y^T y_c] =
        # Z_v^T Z_v by gemm in place (beta, c, trans_a, trans_b, overwrite_c); Z_v^T is Fortran-contiguous
        Z_vT = Z[:nv].T
        dgemm(1.0, Z_vT, Z_vT, 0.0, q.P, 0, 1, 1)
        np.copyto(q.S, q.P_S)
        scale = _max(q.S_diagonal)
        Ls, info = dpotrf(q.S, 1, 0, 1)  # in place (lower, clean=0, overwrite_a)
        if info != 0 or _min(q.S_diagonal) ** 2 <= RANK_RTOL * scale:
            return None
        # t = Ls^-1 a_0 in place (incx, offx, lower, trans, diag, overwrite_x): its bottom block needs
        # the top; T's block Ls_22^-1 E_fu in place (side, lower, trans_a, diag, overwrite_b)
        y = q.y
        np.add(self.e[:m], q.P_c, out=y)
        dtrsv(Ls, y, 1, 0, 1, 0, 0, 1)
        Tb = p.Tb
        np.copyto(Tb, self.E[m - m_f:m, nv:][:, p.free])
        dtrsm(1.0, Ls[m - m_f:, m - m_f:], Tb, 0, 1, 0, 0, 1)
        dgemm(1.0, Tb, Tb, 0.0, p.Hf, 1, 0, 1)  # T^T T
        p.Hf_diagonal += force_weight * force_weight
        # -T^T t_0 (beta, y, offx, incx, offy, incy, trans, overwrite_y)
        dgemv(-1.0, Tb, q.t_b, 0.0, p.cf, 0, 1, 0, 1, 1, 1)
        if p.n_rows:
            np.copyto(p.A, self.G[p.rows, p.cols] if isinstance(p.rows, slice) and isinstance(p.cols, slice)
                      else self.G[p.rows][:, p.cols])
        # (the method, in clip mode: ~0.4 us against np.take's ~1.5-2 in raise mode; the indices are valid)
        self.up.take(p.bounds_at, out=p.upper, mode="clip")
        self.lo.take(p.bounds_at, out=p.lower, mode="clip")
        result = solve_packed(p.HfT, p.cf, p.A, p.upper, p.lower, p.sense)
        f = result.x
        if f is None or result.duals is None:
            return None
        # y = Ls^-T (t_0 - T f) (T's top rows are zero), then vdot = L^-T (Y y - y_c), all in place
        dgemv(-1.0, Tb, f, 1.0, q.t_b, 0, 1, 0, 1, 0, 1)
        dtrsv(Ls, y, 1, 0, 1, 1, 0, 1)
        vdot = x[:nv]
        np.dot(Z[:nv], q.y_ext, out=vdot)
        dtrsv(L, vdot, 1, 0, 1, 1, 0, 1)
        if p.k != self.n_x - nv:
            x[nv:] = 0.0
        x[p.cols] = f
        return result.iterations, result.duals
