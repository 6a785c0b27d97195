"""Noise as a pure function of (key, path, sample), input effects, and the chunked, sharded
Monte-Carlo runner with streaming statistics. Imports the solvers.
"""

from __future__ import annotations

from ._montecarlo import (
    MCResult as MCResult,
    monte_carlo as monte_carlo,
    DEFAULT_MAX_MEMORY_BYTES as DEFAULT_MAX_MEMORY_BYTES,
)
from ._noise import (
    BLOCK_SIZE as BLOCK_SIZE,
    path_normals as path_normals,
    white_noise as white_noise,
    apply_input_effects as apply_input_effects,
    remove_input_effects as remove_input_effects,
)

__all__ = ['BLOCK_SIZE', 'DEFAULT_MAX_MEMORY_BYTES', 'MCResult', 'apply_input_effects', 'monte_carlo', 'path_normals', 'remove_input_effects', 'white_noise']
