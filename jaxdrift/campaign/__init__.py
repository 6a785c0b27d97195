"""Campaigns: many runs of one vehicle diagnosed on Dask, the vehicle's parameters fitted jointly
over them, the campaign's damage (``docs/campaign.md``). May import every layer below the CLI
(diagnosis, durability, io, ...); only the CLI and the top-level API import it.
"""

from __future__ import annotations

from ._campaign import SCHEMA as SCHEMA, campaign as campaign
from ._manifest import RunSpec as RunSpec, read_manifest as read_manifest

__all__ = ["RunSpec", "SCHEMA", "campaign", "read_manifest"]


def _callable_package() -> None:
    """``jaxdrift.campaign(...)`` is the function, and ``jaxdrift.campaign`` is also this package:
    once the package is imported Python binds the name to the module, so the module calls the
    function."""
    import sys
    import types

    class _Package(types.ModuleType):
        def __call__(self, *args, **kwargs):
            return campaign(*args, **kwargs)

    sys.modules[__name__].__class__ = _Package


_callable_package()
