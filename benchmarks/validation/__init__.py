"""Validation of jaxdrift against independent references: the generators of measured runs with
known hidden effects (``gen_vehicle``, ``gen_attitude``, ``gen_campaign``: their own models,
integrators and roads, sharing no code with ``jaxdrift``), the scorer of a diagnosis report
against that truth (``scoring``), the sweep drivers that run and score them (``sweep``,
``durability_sweep``, ``campaign_validation``, ...) and the checks behind the numbers the docs
quote. ``benchmarks/README.md`` lists every script.

Run a script from the repository root as ``python benchmarks/validation/NAME.py``; import a
module as ``from benchmarks.validation import gen_vehicle``.
"""
