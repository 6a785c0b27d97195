"""The integrators: Dormand-Prince 5(4) (adaptive, fixed step, dense output), explicit Euler,
Euler-Maruyama and stochastic Heun, sampled inputs, and the float32 fast path. Imports jax and
equinox only.
"""

from __future__ import annotations

from ._fast import (
    solve_fixed_fast as solve_fixed_fast,
    save_grid as save_grid,
)
from ._inputs import (
    SampledSignal as SampledSignal,
)
from ._sde import (
    solve_sde as solve_sde,
)
from ._solution import (
    RESULTS as RESULTS,
    Result as Result,
    Solution as Solution,
)
from ._solve import (
    RESULTS as RESULTS,
    Result as Result,
    Solution as Solution,
    StepController as StepController,
    solve_ode as solve_ode,
)
from ._tableau import (
    ButcherTableau as ButcherTableau,
)

__all__ = ['ButcherTableau', 'RESULTS', 'Result', 'SampledSignal', 'Solution', 'StepController', 'save_grid', 'solve_fixed_fast', 'solve_ode', 'solve_sde']
