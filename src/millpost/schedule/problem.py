"""One canonical sparse conic problem and its Clarabel solve. Knows no physics.

    minimise  qᵀx   subject to   A x + s = h,   s ∈ K = K_1 × … × K_m

with K_j a zero cone (equalities), a nonnegative cone (A x ≤ h) or a second-order cone
(‖s[1:]‖ ≤ s[0]). Blocks are appended in any order; consecutive blocks of the same kind are merged
when the problem is handed to Clarabel (`clarabel.DefaultSolver`, scipy CSC matrices).
"""

from __future__ import annotations

import enum
import time
from dataclasses import dataclass, field

import clarabel
import numpy as np
import scipy.sparse as sp

ZERO, NONNEG, SOC = "zero", "nonneg", "soc"


class Status(enum.Enum):
    """Outcome of a solve. SOLVED and ALMOST_SOLVED carry a usable x (residuals checked by callers)."""

    SOLVED = "solved"
    ALMOST_SOLVED = "almost_solved"
    INFEASIBLE = "infeasible"
    MAX_ITERATIONS = "max_iterations"
    NUMERICAL_ERROR = "numerical_error"
    FALLBACK = "fallback"  # the conic solve failed; the O(N) reachability profile was used instead

    @property
    def ok(self) -> bool:
        return self in (Status.SOLVED, Status.ALMOST_SOLVED)


_CLARABEL_STATUS = {
    "Solved": Status.SOLVED,
    "AlmostSolved": Status.ALMOST_SOLVED,
    "PrimalInfeasible": Status.INFEASIBLE,
    "AlmostPrimalInfeasible": Status.INFEASIBLE,
    "DualInfeasible": Status.NUMERICAL_ERROR,
    "AlmostDualInfeasible": Status.NUMERICAL_ERROR,
    "MaxIterations": Status.MAX_ITERATIONS,
    "MaxTime": Status.MAX_ITERATIONS,
}


@dataclass
class SolverOptions:
    """Clarabel settings measured on this problem class (see notes/SCHEDULE-PROTOTYPE.md):
    the default 1e-8 stalls at N ≥ 1e4, 1e-7 does not; iterative refinement costs ~40 % of the time
    and may be switched off when the caller checks residuals."""

    tol: float = 1e-7
    tol_ktratio: float = 1e-6
    max_iter: int = 200
    iterative_refinement: bool = True
    verbose: bool = False
    time_limit_s: float = float("inf")


@dataclass
class ConicSolution:
    status: Status
    x: np.ndarray | None
    objective: float
    iterations: int
    solve_s: float
    raw_status: str
    primal_residual: float = float("nan")  # the largest violation of a row at x (`ConicProblem.residual`)
    z: np.ndarray | None = None  # dual variables (for KKT checks)
    s: np.ndarray | None = None  # primal slacks


@dataclass
class ConicProblem:
    """Accumulates rows `A x (+ s) = h` block by block; `solve()` hands them to Clarabel."""

    n: int
    q: np.ndarray = field(default=None)  # type: ignore[assignment]
    _blocks: list = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.q is None:
            self.q = np.zeros(self.n)

    @property
    def m(self) -> int:
        return sum(A.shape[0] for _, A, _, _ in self._blocks)

    def add(self, kind: str, A: sp.spmatrix, h: np.ndarray, cone_dim: int = 0) -> None:
        """Append rows. kind ZERO: A x = h; NONNEG: A x ≤ h; SOC: h − A x in cones of size cone_dim,
        rows ordered cone after cone."""
        A = sp.csr_matrix(A)
        h = np.asarray(h, float).ravel()
        if A.shape != (len(h), self.n):
            raise ValueError(f"block shape {A.shape} does not match ({len(h)}, {self.n})")
        if len(h) == 0:
            return
        if kind == SOC and (cone_dim < 2 or len(h) % cone_dim):
            raise ValueError("SOC rows must be whole cones")
        self._blocks.append((kind, A, h, cone_dim))

    def add_le(self, A, h) -> None:
        self.add(NONNEG, A, h)

    def add_eq(self, A, h) -> None:
        self.add(ZERO, A, h)

    def matrices(self) -> tuple[sp.csc_matrix, np.ndarray, list]:
        """Stacked (A, h, cones) in Clarabel's form."""
        A = sp.vstack([b[1] for b in self._blocks], format="csc") if self._blocks else \
            sp.csc_matrix((0, self.n))
        h = np.concatenate([b[2] for b in self._blocks]) if self._blocks else np.zeros(0)
        cones: list = []
        for kind, Ab, _, dim in self._blocks:
            rows = Ab.shape[0]
            if kind == SOC:
                cones.extend(clarabel.SecondOrderConeT(dim) for _ in range(rows // dim))
            elif cones and kind == ZERO and isinstance(cones[-1], clarabel.ZeroConeT):
                cones[-1] = clarabel.ZeroConeT(cones[-1].dim + rows)
            elif cones and kind == NONNEG and isinstance(cones[-1], clarabel.NonnegativeConeT):
                cones[-1] = clarabel.NonnegativeConeT(cones[-1].dim + rows)
            else:
                cones.append(clarabel.ZeroConeT(rows) if kind == ZERO else clarabel.NonnegativeConeT(rows))
        return A, h, cones

    def residual(self, x: np.ndarray) -> float:
        """Largest violation of any row at x (same units as the rows; a cone's relative to its size
        max(1, s_0): the time epigraph d ≥ 1/(c_i + c_{i+1}) reaches 1e4 where the path nearly stops,
        and 1e-4 on it is round-off)."""
        worst = 0.0
        for kind, A, h, dim in self._blocks:
            s = h - A @ x
            if kind == ZERO:
                worst = max(worst, float(np.abs(s).max()))
            elif kind == NONNEG:
                worst = max(worst, float(max(0.0, -s.min())))
            else:
                s = s.reshape(-1, dim)
                over = (np.linalg.norm(s[:, 1:], axis=1) - s[:, 0]) / np.maximum(1.0, s[:, 0])
                worst = max(worst, float(max(0.0, over.max())))
        return worst

    def solve(self, options: SolverOptions | None = None) -> ConicSolution:
        opt = options or SolverOptions()
        A, h, cones = self.matrices()
        st = clarabel.DefaultSettings()
        st.verbose = opt.verbose
        st.tol_gap_abs = st.tol_gap_rel = st.tol_feas = opt.tol
        st.tol_ktratio = opt.tol_ktratio
        st.max_iter = opt.max_iter
        st.iterative_refinement_enable = opt.iterative_refinement
        st.time_limit = opt.time_limit_s
        P = sp.csc_matrix((self.n, self.n))
        t0 = time.perf_counter()
        try:
            solver = clarabel.DefaultSolver(P, self.q, A, h, cones, st)
            sol = solver.solve()
        except BaseException as exc:  # Clarabel raises PanicException (not an Exception) on bad data
            if isinstance(exc, (KeyboardInterrupt, SystemExit)):
                raise
            return ConicSolution(Status.NUMERICAL_ERROR, None, float("nan"), 0, time.perf_counter() - t0,
                                 f"clarabel error: {exc}")
        raw = str(sol.status)
        status = _CLARABEL_STATUS.get(raw, Status.NUMERICAL_ERROR)
        x = np.asarray(sol.x) if status.ok else None
        res = self.residual(x) if x is not None else float("nan")
        return ConicSolution(status, x, float(sol.obj_val), int(sol.iterations), time.perf_counter() - t0,
                             raw, res, np.asarray(sol.z) if x is not None else None,
                             np.asarray(sol.s) if x is not None else None)
