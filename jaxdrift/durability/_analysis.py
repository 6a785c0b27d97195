"""The durability analysis of a measured run: section forces of every variant, their damage, and
the Monte-Carlo noise band (``jaxdrift durability``; method and numbers in ``docs/durability.md``).
"""

from __future__ import annotations

import dataclasses
import datetime
import hashlib
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..ensemble._montecarlo import monte_carlo
from ..errors import InputError
from ..diagnosis.vehicle import FORCE_NOISE
from ..io._corrections import NO_CORRECTION, Corrections
from ..io._csvio import DEFAULT_MODEL, MODEL_KEYS, VehicleRun
from ..io._outputs import sha256_file
from ..io._provenance import jaxdrift_version
from ._damage import load_statistics, rainflow_cycles, pseudo_damage, range_histogram
from ._derivative import filtered_derivatives, noise_level
from ._variants import (OUTPUT_COLUMNS, SIMULATED, build_section_forces, integration_step,
                        pitch_spring_rule)

__all__ = ["DurabilityResult", "section_forces", "durability_analysis", "SCHEMA", "QUANTILES"]

SCHEMA = "jaxdrift.durability/1"
QUANTILES = (0.05, 0.5, 0.95)
FORCES = ("f3", "f4")
N_BINS = 40

_NO_CORRECTION = NO_CORRECTION.to_json()


@dataclasses.dataclass
class DurabilityResult:
    """What :func:`durability_analysis` returns: the report (``summary``, strict-JSON-able, the
    content of ``durability.json``) and the arrays behind it.

    ``t (n,)``; ``forces``: {variant: (n, 2) f3, f4 [N]} for the variants computed;
    ``pitch_spring_torque (n,)`` [N m]; ``enforced_moment``: {"stabilised", "extended": (n,)} [N m];
    ``cycles``: {variant: {force: (ranges, counts)}}; ``mc_damage``: {variant: (paths, 2)} pseudo-
    damage of every Monte-Carlo path (None without paths); ``histogram_edges`` [N].
    """

    summary: dict
    t: np.ndarray
    forces: dict
    pitch_spring_torque: np.ndarray
    enforced_moment: dict
    cycles: dict
    mc_damage: dict | None
    histogram_edges: np.ndarray


def _params_dict(model) -> dict:
    model = dict(DEFAULT_MODEL if model is None else model)
    missing = [k for k in MODEL_KEYS if k not in model]
    if missing:
        raise InputError(f"model: missing parameter {missing[0]!r}")
    return {k: float(model[k]) for k in MODEL_KEYS}


def _derivative_of_measured(x, dt):
    """(filtered x, its derivative, filter info) of a measured spring travel."""
    xs, dx, _, info = filtered_derivatives(x, dt)
    return xs, dx, info["signals"][0]


def section_forces(t, f1, f2, model=None, *, beta=None, beta_rate=None, s1=None, s2=None,
                   extended: dict | None = None, spring: dict | None = None,
                   filter_pitch: bool = True) -> dict:
    """Nominal section forces ``f3, f4`` of every variant the run allows (no added noise).

    ``extended``: the diagnosis's ``extended_model`` (``parameters``, ``corrections``, and
    ``nonlinear`` where the diagnosis confirmed a nonlinear suspension cause); None uses the model
    itself. ``spring``: :func:`~jaxdrift.durability.pitch_spring_rule`'s dict (default:
    the rule). ``filter_pitch=False``: plain central differences of the measured pitch (for
    comparison only). Returns ``{"forces": {variant: (n, 2)}, "pitch_spring_torque", "enforced_moment",
    "derivative_filter", "pitch_spring", "integration", "section_forces_fn"}``.
    """
    p = _params_dict(model)
    t = np.asarray(t, float)
    dt = float((t[-1] - t[0]) / (t.size - 1))
    spring = pitch_spring_rule(p) if spring is None else spring
    ext = extended or {"parameters": p, "corrections": _NO_CORRECTION}
    p_ext = _params_dict(ext.get("parameters", p))
    h, m = integration_step(p, dt)
    h_ext, m_ext = integration_step(p_ext, dt, ext.get("nonlinear"))
    if m_ext > m:
        h, m = h_ext, m_ext
    pitch, dfilter = None, None
    if beta is not None:
        if filter_pitch:
            b, db, ddb, dfilter = filtered_derivatives(beta, dt, beta_rate)
        else:
            b = np.asarray(beta, float)
            db = np.gradient(b, dt) if beta_rate is None else np.asarray(beta_rate, float)
            ddb = np.gradient(db, dt)
            dfilter = {"kind": "none: plain central differences (filter_pitch=False)", "cutoff_hz": None}
        pitch = np.stack([b, db, ddb], axis=1)
    sf = build_section_forces(t, np.stack([f1, f2], axis=1), pitch, p, p_ext, Corrections.from_json(ext["corrections"]),
                              spring, h, ext.get("nonlinear"))
    out, code = _nominal(sf)
    out = np.asarray(out)
    if int(code) != 0:
        raise RuntimeError(f"durability: a variant's simulation failed (result code {int(code)})")
    col = {c: i for i, c in enumerate(OUTPUT_COLUMNS)}
    forces = {}
    for v in SIMULATED:
        if v in ("stabilised", "extended") and pitch is None:
            continue
        forces[v] = out[:, [col[f"{v}_f3"], col[f"{v}_f4"]]]
    travel_filters = []
    if s1 is not None or s2 is not None:
        meas = np.full((t.size, 2), np.nan)
        for j, (s, k, d) in enumerate(((s1, "k3", "d3"), (s2, "k4", "d4"))):
            if s is not None:
                xs, dx, info = _derivative_of_measured(np.asarray(s, float), dt)
                meas[:, j] = p[k] * xs + p[d] * dx
                travel_filters.append({**info, "signal": ("s1", "s2")[j]})
        forces["measured"] = meas
    moments = {}
    if pitch is not None:
        moments = {"stabilised": out[:, col["stabilised_moment"]], "extended": out[:, col["extended_moment"]]}
    return {"forces": forces, "pitch_spring_torque": out[:, col["pitch_spring_torque"]],
            "enforced_moment": moments, "derivative_filter": dfilter, "spring_travel_filter": travel_filters,
            "pitch_spring": spring, "integration": {"method": "dopri5 fixed step", "step_s": h,
                                                    "substeps_per_sample": m},
            "section_forces_fn": sf}


@eqx.filter_jit
def _nominal(sf):
    return sf(jax.random.key(0), jnp.int32(0), jnp.asarray(0.0, sf.forces.dtype))


class _MCPath(eqx.Module):
    """``path_fn`` for :func:`jaxdrift.monte_carlo`: the per-path model is ``(global index, sigma)``;
    outputs the 8 section-force columns (the path's noise is drawn from its global index, so it does
    not depend on how the paths are split into calls)."""

    sf: eqx.Module

    def __call__(self, key, idx, batch):
        gidx, sigma = batch
        out, code = self.sf(key, gidx, sigma)
        return out[:, :2 * len(SIMULATED)], code


def _damages(out, variants, k):
    """(len(variants), 2) pseudo-damage of one path's section forces."""
    col = {c: i for i, c in enumerate(OUTPUT_COLUMNS)}
    d = np.full((len(variants), 2), np.nan)
    for i, v in enumerate(variants):
        for j, f in enumerate(FORCES):
            x = out[:, col[f"{v}_{f}"]]
            if np.all(np.isfinite(x)):
                d[i, j] = pseudo_damage(*rainflow_cycles(x), k)
    return d


def monte_carlo_damage(sf, sigma: float, paths: int, *, variants, basquin_k=5.0, seed=0, chunk=16,
                       progress=True) -> np.ndarray:
    """``(paths, len(variants), 2)`` pseudo-damage of ``f3, f4`` under ``paths`` force-noise draws.

    Each host-side chunk is one :func:`jaxdrift.monte_carlo` call (vmapped over its paths; every
    chunk has the same size, the last one padded, so one compilation serves all); its section
    forces are counted (rainflow) and dropped, so memory stays at two chunks. The next chunk is
    simulated in a worker thread while the host counts the current one.
    """
    from concurrent.futures import ThreadPoolExecutor

    from tqdm import tqdm

    fn = _MCPath(sf)
    key = jax.random.key(seed)
    n = sf.ts.shape[0]
    size = max(1, min(int(chunk), int(paths)))
    out = np.full((paths, len(variants), 2), np.nan)

    def simulate(start):
        gidx = np.minimum(np.arange(start, start + size), paths - 1).astype(np.int32)
        res = monte_carlo(fn, size, key=key, save_ts=np.asarray(sf.ts), keep_paths=True,
                          models=(gidx, np.full(size, float(sigma))), chunk_size=size, progress=False)
        return res.ys, res.result

    starts = list(range(0, paths, size))
    bar = tqdm(total=paths, unit="path", desc="durability noise paths", disable=not progress)
    try:
        with ThreadPoolExecutor(max_workers=1) as pool:
            pending = pool.submit(simulate, starts[0]) if starts else None
            for k, start in enumerate(starts):
                ys, result = pending.result()
                if k + 1 < len(starts):
                    pending = pool.submit(simulate, starts[k + 1])
                real = min(size, paths - start)
                for i in range(real):
                    if result[i] == 0:
                        out[start + i] = _damages(ys[i].reshape(n, -1), variants, basquin_k)
                bar.update(real)
    finally:
        bar.close()
    return out


def _noise_level(report, run) -> tuple[float, str]:
    level = FORCE_NOISE.level_in((report or {}).get("findings"))
    if level is not None:
        return level, f"diagnosis {FORCE_NOISE.name} finding"
    fs = 1.0 / run.dt
    s = 0.5 * (noise_level(run["f1"], fs) + noise_level(run["f2"], fs))
    return s, ("the measured forces' own noise level (4th differences / high-band PSD; the diagnosis "
               "reported no force noise)")


def _quantiles(x):
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return [float(q) for q in np.quantile(x, QUANTILES)] if x.size else None


def _ratios(damage: dict, ref: str) -> tuple[dict, dict]:
    """Damage ratio to ``ref`` per variant (f3 + f4 summed) and per force."""
    total, by_force = {}, {}
    if ref not in damage:
        return total, by_force
    r = damage[ref]
    for v, d in damage.items():
        if v == ref:
            continue
        total[v] = float((d[0] + d[1]) / (r[0] + r[1])) if (r[0] + r[1]) > 0 else None
        by_force[v] = {f: (float(d[j] / r[j]) if r[j] > 0 else None) for j, f in enumerate(FORCES)}
    return total, by_force


def _sha256(run: VehicleRun) -> str:
    try:
        return sha256_file(run.path)
    except (OSError, TypeError):
        h = hashlib.sha256(np.ascontiguousarray(run.t).tobytes())
        for k in sorted(run.channels):
            h.update(k.encode() + np.ascontiguousarray(run.channels[k]).tobytes())
        return h.hexdigest()


def _variant_stats(forces, k, edges):
    runs, cycles, hist = {}, {}, {}
    for v, F in forces.items():
        runs[v], cycles[v], hist[v] = {}, {}, {}
        for j, f in enumerate(FORCES):
            x = F[:, j]
            if not np.all(np.isfinite(x)):
                continue
            runs[v][f] = load_statistics(x, k)
            cycles[v][f] = rainflow_cycles(x)
            hist[v][f] = range_histogram(*cycles[v][f], edges).tolist()
    return runs, cycles, hist


def durability_analysis(run: VehicleRun, model=None, *, paths: int = 64, basquin_k: float = 5.0,
                        seed: int = 0, pitch_spring_k: float | None = None,
                        pitch_spring_d: float | None = None, report: dict | None = None,
                        progress: bool = True, chunk: int = 16) -> DurabilityResult:
    """Section forces, fatigue pseudo-damage and its noise band for a measured vehicle run.

    ``run``: a :class:`~jaxdrift.VehicleRun` (``jaxdrift.read_vehicle_run``); ``model``: dict of
    the seed's keys (default: the seed's table). ``report``: the vehicle diagnosis of this run
    (``jaxdrift.diagnose_vehicle_run``); None runs it. Its ``extended_model`` gives the
    ``extended`` variant, its ``force_noise`` finding the Monte-Carlo noise level. ``paths``:
    Monte-Carlo force-noise draws (0: none). Returns a :class:`DurabilityResult`; its ``summary``
    is ``durability.json`` (schema ``jaxdrift.durability/1``, ``docs/durability.md``).
    """
    if not (isinstance(paths, (int, np.integer)) and paths >= 0):
        raise InputError(f"paths must be a whole number >= 0, got {paths!r}")
    if not (math.isfinite(basquin_k) and basquin_k > 0):
        raise InputError(f"basquin_k must be a positive number, got {basquin_k!r}")
    for name, v in (("pitch_spring_k", pitch_spring_k), ("pitch_spring_d", pitch_spring_d)):
        if v is not None and not (math.isfinite(v) and v >= 0):
            raise InputError(f"{name} must be a number >= 0, got {v!r}")
    p = _params_dict(model)
    started = datetime.datetime.now(datetime.timezone.utc)
    if report is None:
        from ..diagnosis.vehicle import diagnose_vehicle_run

        report = diagnose_vehicle_run(run, p)
    extended = report.get("extended_model") if report else None
    spring = pitch_spring_rule(p, pitch_spring_k, pitch_spring_d)
    ch = run.channels
    nom = section_forces(run.t, ch["f1"], ch["f2"], p, beta=ch.get("beta"), beta_rate=ch.get("beta_rate"),
                         s1=ch.get("s1"), s2=ch.get("s2"), extended=extended, spring=spring)
    forces = nom["forces"]
    max_range = max(float(np.nanmax(F) - np.nanmin(F)) for F in forces.values())
    edges = np.linspace(0.0, max_range * 1.0001, N_BINS + 1)
    runs, cycles, hist = _variant_stats(forces, basquin_k, edges)
    damage = {v: [runs[v].get(f, {}).get("damage", math.nan) for f in FORCES] for v in runs}
    ref = "stabilised" if "stabilised" in damage else None
    ratio, ratio_by_force = _ratios(damage, ref) if ref else ({}, {})

    sigma, noise_src = _noise_level(report, run)
    mc_variants = [v for v in SIMULATED if v in forces]
    mc_damage, mc = None, {"paths": int(paths), "noise_N": sigma, "noise_source": noise_src, "seed": int(seed)}
    if paths > 0:
        d = monte_carlo_damage(nom["section_forces_fn"], sigma, int(paths), variants=mc_variants,
                               basquin_k=basquin_k, seed=seed, chunk=chunk, progress=progress)
        mc_damage = {v: d[:, i, :] for i, v in enumerate(mc_variants)}
        tot = {v: mc_damage[v].sum(axis=1) for v in mc_variants}
        nominal_tot = {v: damage[v][0] + damage[v][1] for v in mc_variants}
        mc["failed_paths"] = int(np.sum(~np.isfinite(d[:, 0, 0])))
        mc["quantile_levels"] = list(QUANTILES)
        if ref:
            mc["damage_ratio_quantiles"] = {v: _quantiles(tot[v] / tot[ref]) for v in mc_variants if v != ref}
        mc["damage_ratio_to_nominal_quantiles"] = {v: _quantiles(tot[v] / nominal_tot[v]) for v in mc_variants}
        mc["damage_quantiles"] = {v: {f: _quantiles(mc_damage[v][:, j]) for j, f in enumerate(FORCES)}
                                  for v in mc_variants}
    torque = nom["pitch_spring_torque"]
    summary = {
        "schema": SCHEMA,
        "basquin_k": float(basquin_k),
        "damage_definition": "sum n_i S_i^K over rainflow cycles (ASTM E1049-85, residue as half cycles), S in N",
        "runs": runs,
        "reference": ref,
        "damage_ratio_to_stabilised": ratio,
        "damage_ratio_to_stabilised_by_force": ratio_by_force,
        "monte_carlo": mc,
        "derivative_filter": nom["derivative_filter"] or {"kind": None, "cutoff_hz": None,
                                                          "note": "the run has no beta: no stabilised variants"},
        "spring_travel_filter": nom["spring_travel_filter"],
        "pitch_spring": {**spring, "torque_rms": float(np.sqrt(np.mean(torque**2))),
                         "torque_max_abs": float(np.max(np.abs(torque)))},
        "enforced_moment": {v: {"rms": float(np.sqrt(np.mean(m**2))), "max_abs": float(np.max(np.abs(m)))}
                            for v, m in nom["enforced_moment"].items()},
        "integration": nom["integration"],
        "range_histogram": {"edges_N": edges.tolist(), "cycles": hist},
        "variants_skipped": {v: "the run has no beta" for v in ("stabilised", "extended") if v not in forces}
        | ({} if "measured" in forces else {"measured": "the run has no s1, s2"}),
        "provenance": _provenance(run, p, report, started, dict(paths=int(paths), basquin_k=float(basquin_k),
                                  seed=int(seed), pitch_spring_k=pitch_spring_k, pitch_spring_d=pitch_spring_d)),
    }
    return DurabilityResult(summary=summary, t=np.asarray(run.t), forces=forces, pitch_spring_torque=torque,
                            enforced_moment=nom["enforced_moment"], cycles=cycles, mc_damage=mc_damage,
                            histogram_edges=edges)


def _provenance(run, p, report, started, options) -> dict:
    return {"version": jaxdrift_version(), "input": str(run.path), "input_sha256": _sha256(run),
            "samples": int(run.n), "sample_rate_hz": 1.0 / run.dt, "channels": sorted(run.channels),
            "model": p, "options": options,
            "extended_model": (report or {}).get("extended_model"),
            "started_utc": started.isoformat(timespec="seconds"),
            "finished_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
