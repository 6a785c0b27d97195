"""Model parameters as equinox Modules: the half-car of the seed paper and the point mass.

The defaults are the seed paper's parameter table (Appendix A). Every field is a float (or, for a
batch of perturbed models, an array with a leading batch axis), so a batch of models is just a
batched pytree under ``vmap``. Validation is an explicit call (:meth:`HalfCarParams.validate`),
never part of construction: constructing or unflattening a Module inside ``jit``/``vmap`` must not
run Python checks on tracers.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

import equinox as eqx
import numpy as np

__all__ = [
    "HalfCarParams",
    "PointMassParams",
    "PAPER_PERTURBATION",
    "PERTURBABLE_KEYS",
    "random_perturbed_models",
    "stack_models",
]

#: The seed paper's fixed perturbed model (Appendix A, "Model parameters"): factors on the chassis
#: spring stiffness/damping and the chassis moment of inertia.
PAPER_PERTURBATION: dict[str, float] = {"k3": 1.05, "k4": 0.95, "d3": 0.95, "d4": 1.05, "I": 0.95}

#: The parameters the paper perturbs (random factors in [0.9, 1.1] in its Fig. 7).
PERTURBABLE_KEYS: tuple[str, ...] = ("k3", "k4", "d3", "d4", "I")


def _check_positive(owner: str, values: Mapping[str, Any], allow_zero: tuple[str, ...] = ()) -> None:
    """Raise ValueError naming the first key whose value is non-finite or not positive."""
    for key, value in values.items():
        arr = np.asarray(value, dtype=float)
        if arr.size == 0:
            raise ValueError(f"{owner}: parameter {key!r} is empty")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{owner}: parameter {key!r} must be finite, got {value!r}")
        if key in allow_zero:
            if np.any(arr < 0):
                raise ValueError(f"{owner}: parameter {key!r} must be >= 0, got {value!r}")
        elif np.any(arr <= 0):
            raise ValueError(f"{owner}: parameter {key!r} must be > 0, got {value!r}")


class HalfCarParams(eqx.Module):
    """Parameters of the seed paper's half-car (Fig. 3, Appendix A); defaults are its table.

    Coordinates point down (z positive downward, gravity ``+g``). Wheel 1 sits at distance ``b``
    from the chassis centre of mass, wheel 2 at distance ``a`` (A.1).

    Fields (SI units): ``a, b`` [m] lever arms; ``m1, m2`` [kg] wheel masses, ``m3`` [kg] chassis
    mass, ``I`` [kg m^2] chassis pitch inertia; ``k1, k2`` [N/m] tyre stiffness, ``k3, k4`` [N/m]
    chassis (suspension) springs; ``d1, d2, d3, d4`` [N s/m] the matching dampers; ``g`` [m/s^2].

    Construction does not validate (so the Module can be built and unflattened under ``jit`` and
    ``vmap``); call :meth:`validate` on user input, or build with :meth:`from_dict`, which does.
    """

    a: float = 1.0
    b: float = 1.0
    m1: float = 15.0
    m2: float = 15.0
    m3: float = 750.0
    I: float = 500.0  # noqa: E741 (the paper's name)
    k1: float = 2.0e5
    k2: float = 2.0e5
    k3: float = 1.0e5
    k4: float = 1.0e5
    d1: float = 2.0e2
    d2: float = 2.0e2
    d3: float = 1.0e4
    d4: float = 1.0e4
    g: float = 9.81

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def from_dict(cls, values: Mapping[str, Any], *, validate: bool = True) -> "HalfCarParams":
        """Build from a mapping; missing keys take the seed defaults, unknown keys are an error."""
        names = cls.field_names()
        unknown = [k for k in values if k not in names]
        if unknown:
            raise ValueError(
                f"HalfCarParams: unknown parameter {unknown[0]!r} (known: {', '.join(names)})"
            )
        kwargs = {}
        for k, v in values.items():
            try:
                kwargs[k] = float(v)
            except (TypeError, ValueError):
                raise ValueError(f"HalfCarParams: parameter {k!r} is not a number: {v!r}") from None
        out = cls(**kwargs)
        if validate:
            out.validate()
        return out

    def to_dict(self) -> dict[str, Any]:
        """Field values as plain Python floats (lists for a batched Module)."""
        out = {}
        for name in self.field_names():
            arr = np.asarray(getattr(self, name), dtype=float)
            out[name] = float(arr) if arr.ndim == 0 else arr.tolist()
        return out

    def validate(self) -> "HalfCarParams":
        """Check every field is finite and positive; raise ValueError naming the bad key.

        Works on concrete values only (call it outside ``jit``); returns ``self`` for chaining.
        """
        _check_positive("HalfCarParams", {n: getattr(self, n) for n in self.field_names()})
        return self

    def perturbed(self, **factors: Any) -> "HalfCarParams":
        """A copy with fields multiplied by the given factors, e.g. ``p.perturbed(k3=1.05)``.

        Factors may be arrays (a leading batch axis gives a batch of models for those fields).
        """
        names = self.field_names()
        for k in factors:
            if k not in names:
                raise ValueError(f"HalfCarParams.perturbed: unknown parameter {k!r}")
        return dataclasses.replace(self, **{k: getattr(self, k) * f for k, f in factors.items()})

    def paper_perturbed(self) -> "HalfCarParams":
        """The seed paper's fixed perturbed model (k3 x1.05, k4 x0.95, d3 x0.95, d4 x1.05, I x0.95)."""
        return self.perturbed(**PAPER_PERTURBATION)

    @property
    def total_mass(self):
        return self.m1 + self.m2 + self.m3

    @property
    def pitch_inertia_whole(self):
        """Inertia J = I + m1 b^2 + m2 a^2 of the free pitch mode of the whole vehicle."""
        return self.I + self.m1 * self.b**2 + self.m2 * self.a**2


def stack_models(models: list[HalfCarParams]) -> HalfCarParams:
    """Stack scalar-valued Modules into one batched Module (every leaf gets a leading axis)."""
    if not models:
        raise ValueError("stack_models: empty list of models")
    names = HalfCarParams.field_names()
    return HalfCarParams(
        **{n: np.asarray([float(getattr(m, n)) for m in models]) for n in names}
    )


def random_perturbed_models(
    n: int,
    seed: int = 0,
    *,
    base: HalfCarParams | None = None,
    low: float = 0.9,
    high: float = 1.1,
    keys: tuple[str, ...] = PERTURBABLE_KEYS,
) -> HalfCarParams:
    """``n`` models with independent uniform factors in ``[low, high]`` on ``keys`` (paper Fig. 7).

    Returns one batched :class:`HalfCarParams`: every field is a float64 numpy array of shape
    ``(n,)`` (unperturbed fields broadcast), ready for ``vmap`` or ``jaxdrift.monte_carlo``'s
    ``models=``. Reproducible from ``seed`` (numpy ``default_rng``); model ``i`` depends only on
    ``(seed, i)``'s position in the stream, so the first ``n`` models of a larger batch agree.
    """
    if n < 1:
        raise ValueError(f"random_perturbed_models: n must be >= 1, got {n}")
    if not (0 < low <= high):
        raise ValueError(f"random_perturbed_models: need 0 < low <= high, got {low}, {high}")
    base = HalfCarParams() if base is None else base
    names = HalfCarParams.field_names()
    for k in keys:
        if k not in names:
            raise ValueError(f"random_perturbed_models: unknown parameter {k!r}")
    rng = np.random.default_rng(seed)
    factors = rng.uniform(low, high, size=(n, len(keys)))  # row i = model i
    fields = {}
    for name in names:
        v = np.full(n, float(getattr(base, name)))
        if name in keys:
            v = v * factors[:, keys.index(name)]
        fields[name] = v
    return HalfCarParams(**fields)


class PointMassParams(eqx.Module):
    """Point mass of the seed's section 2: mass ``m`` > 0 and damping ``eta`` >= 0 in (2.1)."""

    m: float = 1.0
    eta: float = 0.0

    def validate(self) -> "PointMassParams":
        _check_positive("PointMassParams", {"m": self.m, "eta": self.eta}, allow_zero=("eta",))
        return self
