"""Durability: section forces of the simulation variants, their fatigue pseudo-damage and its
noise band (``docs/durability.md``). May import models, analysis, solvers, ensemble,
io, diagnosis and studies (it reuses the paper study's simulations); only the CLI imports it.
"""

from __future__ import annotations

from ._analysis import (
    DurabilityResult as DurabilityResult,
    durability_analysis as durability_analysis,
    monte_carlo_damage as monte_carlo_damage,
    section_forces as section_forces,
    SCHEMA as SCHEMA,
)
from ._damage import (
    load_statistics as load_statistics,
    pseudo_damage as pseudo_damage,
    rainflow_cycles as rainflow_cycles,
    range_histogram as range_histogram,
    turning_points as turning_points,
)
from ._derivative import (
    choose_cutoff as choose_cutoff,
    filtered_derivatives as filtered_derivatives,
    lowpass as lowpass,
    noise_from_differences as noise_from_differences,
)
from ._variants import (
    SectionForces as SectionForces,
    integration_step as integration_step,
    pitch_spring_rule as pitch_spring_rule,
)

__all__ = ["DurabilityResult", "SCHEMA", "SectionForces", "choose_cutoff", "durability_analysis",
           "filtered_derivatives", "integration_step", "load_statistics", "lowpass",
           "monte_carlo_damage", "noise_from_differences", "pitch_spring_rule", "pseudo_damage",
           "rainflow_cycles", "range_histogram", "section_forces", "turning_points"]
