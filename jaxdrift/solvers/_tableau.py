"""Butcher tableaux as frozen numpy dataclasses that check themselves at construction."""

from __future__ import annotations

import dataclasses
from fractions import Fraction as Fr

import numpy as np


@dataclasses.dataclass(frozen=True)
class ButcherTableau:
    """An explicit Runge-Kutta method with an embedded error estimate and a dense output.

    ``a`` is the strictly lower triangular stage matrix (s x s), ``b`` the weights of the
    propagated solution, ``b_error`` = b - b_hat (weights of the embedded error estimate,
    including the FSAL stage when ``fsal``), ``c`` the nodes, and ``p`` the dense-output matrix:
    y(t + theta h) = y + h * sum_i k_i * sum_j p[i, j] theta^(j+1).
    """

    name: str
    order: int
    error_order: int
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    b_error: np.ndarray
    p: np.ndarray | None = None
    fsal: bool = False

    def __post_init__(self):
        s = len(self.c)
        a, b, c, e = (np.asarray(v, dtype=np.float64) for v in (self.a, self.b, self.c, self.b_error))
        if a.shape != (s, s):
            raise ValueError(f"{self.name}: a must be ({s}, {s}), got {a.shape}")
        if np.any(np.triu(a) != 0):
            raise ValueError(f"{self.name}: a must be strictly lower triangular (explicit method)")
        if not np.allclose(a.sum(axis=1), c, atol=1e-14, rtol=0):
            raise ValueError(f"{self.name}: row sums of a must equal c")
        if not np.isclose(b.sum(), 1.0, atol=1e-14, rtol=0):
            raise ValueError(f"{self.name}: weights b must sum to 1")
        if not np.isclose(e.sum(), 0.0, atol=1e-14, rtol=0):
            raise ValueError(f"{self.name}: error weights must sum to 0")
        if self.fsal and len(e) != s + 1:
            # First same as last: the (s+1)-th stage is f(t + h, y_new), reused by the next step.
            raise ValueError(f"{self.name}: FSAL error weights need s + 1 entries")
        if not self.fsal and len(e) != s:
            raise ValueError(f"{self.name}: error weights need s entries")
        # Order conditions up to order 5 for the propagated weights (the ones that matter here).
        if self.order >= 1 and not np.isclose(b @ np.ones(s), 1.0):
            raise ValueError(f"{self.name}: order-1 condition fails")
        if self.order >= 2 and not np.isclose(b @ c, 1 / 2, atol=1e-14):
            raise ValueError(f"{self.name}: order-2 condition fails")
        if self.order >= 3 and not (
            np.isclose(b @ c**2, 1 / 3, atol=1e-14) and np.isclose(b @ a @ c, 1 / 6, atol=1e-14)
        ):
            raise ValueError(f"{self.name}: order-3 conditions fail")
        if self.order >= 4 and not (
            np.isclose(b @ c**3, 1 / 4, atol=1e-14)
            and np.isclose((b * c) @ a @ c, 1 / 8, atol=1e-14)
            and np.isclose(b @ a @ c**2, 1 / 12, atol=1e-14)
            and np.isclose(b @ a @ a @ c, 1 / 24, atol=1e-14)
        ):
            raise ValueError(f"{self.name}: order-4 conditions fail")
        if self.p is not None:
            p = np.asarray(self.p, dtype=np.float64)
            n_k = s + 1 if self.fsal else s
            if p.shape[0] != n_k:
                raise ValueError(f"{self.name}: dense-output matrix needs {n_k} rows")
            # At theta = 1 the dense output must reproduce the step.
            bw = np.concatenate([b, [0.0]]) if self.fsal else b
            if not np.allclose(p.sum(axis=1), bw, atol=1e-12):
                raise ValueError(f"{self.name}: dense output at theta=1 must equal the step weights")
        for name, v in (("a", a), ("b", b), ("c", c), ("b_error", e)):
            object.__setattr__(self, name, v)
        if self.p is not None:
            object.__setattr__(self, "p", np.asarray(self.p, dtype=np.float64))


def _f(rows):
    return np.array([[float(Fr(x)) for x in row] for row in rows])


# Dormand & Prince (1980), with the continuous extension of Shampine (1986) as in scipy's RK45.
DOPRI5 = ButcherTableau(
    name="Dormand-Prince 5(4)",
    order=5,
    error_order=4,
    c=np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1]),
    a=_f(
        [
            [0, 0, 0, 0, 0, 0],
            ["1/5", 0, 0, 0, 0, 0],
            ["3/40", "9/40", 0, 0, 0, 0],
            ["44/45", "-56/15", "32/9", 0, 0, 0],
            ["19372/6561", "-25360/2187", "64448/6561", "-212/729", 0, 0],
            ["9017/3168", "-355/33", "46732/5247", "49/176", "-5103/18656", 0],
        ]
    ),
    b=_f([["35/384", 0, "500/1113", "125/192", "-2187/6784", "11/84"]])[0],
    # b - b_hat over the 7 stages (the 7th is f(t+h, y_new), first-same-as-last).
    b_error=_f([["-71/57600", 0, "71/16695", "-71/1920", "17253/339200", "-22/525", "1/40"]])[0],
    p=_f(
        [
            [1, "-8048581381/2820520608", "8663915743/2820520608", "-12715105075/11282082432"],
            [0, 0, 0, 0],
            [0, "131558114200/32700410799", "-68118460800/10900136933", "87487479700/32700410799"],
            [0, "-1754552775/470086768", "14199869525/1410260304", "-10690763975/1880347072"],
            [0, "127303824393/49829197408", "-318862633887/49829197408", "701980252875/199316789632"],
            [0, "-282668133/205662961", "2019193451/616988883", "-1453857185/822651844"],
            [0, "40617522/29380423", "-110615467/29380423", "69997945/29380423"],
        ]
    ),
    fsal=True,
)
