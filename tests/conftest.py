import os

os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")
os.environ.setdefault("MPLBACKEND", "Agg")

import jax  # noqa: E402

# Tests run in float64; the library never switches x64 on at import.
jax.config.update("jax_enable_x64", True)
