"""``jaxdrift paper`` and ``jaxdrift pointmass``: the seed paper's studies in one command each.

Thin: parses and checks the arguments and the output folder (before computing), calls
:mod:`jaxdrift.studies._study` / :mod:`jaxdrift.studies._pointmass`, writes figures and JSON through
:func:`jaxdrift.io.atomic_dir` (a temporary folder, moved into place at the end with a manifest).
See ``docs/paper-study.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

PAPER_DESCRIPTION = """\
Reproduce section 4 of the seed paper on the half-car: (1) virtual measurement on an ISO 8608
road with hills, (2) simulation with the undisturbed wheel forces, (3) with noisy forces
(sigma = 0.002 f_max, many samples), (4) with perturbed models (the paper's and random factors in
[0.9, 1.1] on k3, k4, d3, d4, I), (5) stabilised simulation with the pitch angle prescribed and the
enforced moment; plus the section-3 pitch spring and a solver/tolerance comparison.

Writes to DIR: fig4_road_forces.png, fig5_z3_beta.png, fig6_noise_samples.png,
fig7_perturbed_models.png, fig8_enforced_moment.png, fig_pitch_spring.png, summary.json,
solver_comparison.md. Drift-off time: the first time |beta - beta_measured| exceeds
--threshold-deg (default 1 deg). The headline drift-off statistics are taken where the
integration has converged (fixed 1 ms steps, checked at 0.5 ms and with jnp.sin/jnp.cos in place
of the polynomial sin/cos), with 95 % bootstrap intervals over the noise samples; the paper's
rtol 1e-4, whose drift-off times depend on rounding, is reported beside them. The defaults take about 7 minutes on 2 busy CPU cores; --quick takes
about a minute; scale up with --samples, --models, --duration.

exit codes: 0 done, 2 bad input or unwritable --out (nothing written), 130 interrupted
"""

PAPER_FILES = ("fig4_road_forces.png", "fig5_z3_beta.png", "fig6_noise_samples.png", "fig7_perturbed_models.png",
               "fig8_enforced_moment.png", "fig_pitch_spring.png", "summary.json", "solver_comparison.md")

POINTMASS_DESCRIPTION = """\
Section 2 of the seed paper: the point mass (2.1) integrated by the explicit Euler scheme (2.3)
with noisy force samples (2.2). Plots the empirical Std of the position and velocity errors over
many noise samples against the closed forms (2.8) (eta = 0) and (2.11) (eta > 0) on log-log axes
with the t^1/2 and t^3/2 slopes, and writes pointmass_summary.json (variance ratios with the 99 %
chi-square interval, fitted slopes).

exit codes: 0 done, 2 bad input or unwritable --out (nothing written), 130 interrupted
"""


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "paper",
        help="reproduce the seed paper's section-4 study (figures 4-8, JSON summary)",
        description=PAPER_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    p.add_argument("--params", metavar="MODEL.json",
                   help="half-car parameters as JSON {\"m3\": 800, ...}; missing keys: the seed's table")
    p.add_argument("--duration", type=float, default=30.0, help="simulated time [s] (default 30)")
    p.add_argument("--samples", type=int, default=32, help="noise samples in step 3 (default 32)")
    p.add_argument("--models", type=int, default=32, help="random perturbed models in step 4 (default 32)")
    p.add_argument("--compare-samples", type=int, default=8,
                   help="noise samples per solver in the solver comparison and in step 5 (default 8)")
    p.add_argument("--spring-samples", type=int, default=4, help="noise samples per pitch-spring stiffness (default 4)")
    p.add_argument("--road-class", default="D", help="ISO 8608 class A-H (default D)")
    p.add_argument("--speed", type=float, default=20.0, help="vehicle speed [m/s] (default 20)")
    p.add_argument("--hill-height", type=float, default=2.0, help="hill amplitude [m] (default 2)")
    p.add_argument("--road-seed", type=int, default=0, help="seed of the road's random phases")
    p.add_argument("--seed", type=int, default=0, help="seed of the force noise and the random models")
    p.add_argument("--noise-rel", type=float, default=0.002, help="noise sigma relative to max|f| (default 0.002)")
    p.add_argument("--threshold-deg", type=float, default=1.0, help="pitch drift-off threshold [deg] (default 1)")
    p.add_argument("--no-compare", action="store_true", help="skip the solver/tolerance comparison")
    p.add_argument("--no-rounding-check", action="store_true",
                   help="skip the headline's rounding check (the study again with jnp.sin/jnp.cos)")
    p.add_argument("--linear", action="store_true",
                   help="simulate with the small-angle (linear) form of the model; the measurement stays nonlinear")
    p.add_argument("--quick", action="store_true",
                   help="small configuration: 10 s, 8 samples, 8 models, 4 per comparison")
    p.add_argument("--dpi", type=int, default=90, help="figure resolution (default 90)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=run_paper)

    q = subparsers.add_parser(
        "pointmass",
        help="section 2: Monte-Carlo Std of the point mass against (2.8)/(2.11), log-log figure",
        description=POINTMASS_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    q.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    q.add_argument("--paths", type=int, default=2000, help="noise samples (default 2000)")
    q.add_argument("--duration", type=float, default=100.0, help="simulated time [s] (default 100)")
    q.add_argument("--dt", type=float, default=0.01, help="force sample period = Euler step [s] (default 0.01)")
    q.add_argument("--sigma-m", type=float, default=1.0, help="force noise standard deviation sigma_M [N] (default 1)")
    q.add_argument("--mass", type=float, default=1.0, help="mass m [kg] (default 1)")
    q.add_argument("--eta", type=float, nargs="+", default=[0.0, 0.5], help="damping values eta >= 0 (default 0 0.5)")
    q.add_argument("--seed", type=int, default=0, help="seed of the force noise")
    q.add_argument("--dpi", type=int, default=90, help="figure resolution (default 90)")
    q.add_argument("--no-progress", action="store_true", help="no progress bars")
    q.set_defaults(func=run_pointmass)


def _usage(msg):
    from ..errors import UsageError

    return UsageError(msg)


def _load_params(path):
    from ..models._params import HalfCarParams

    if path is None:
        return HalfCarParams()
    try:
        with open(path) as fh:
            data = json.load(fh)
    except OSError as e:
        raise _usage(f"{path}: cannot read: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise _usage(f"{path}, line {e.lineno}, column {e.colno}: invalid JSON: {e.msg}") from None
    if not isinstance(data, dict):
        raise _usage(f"{path}: expected a JSON object of parameters, got {type(data).__name__}")
    try:
        return HalfCarParams.from_dict(data)
    except ValueError as e:
        raise _usage(f"{path}: {e}") from None


def _enable_x64():
    import jax

    jax.config.update("jax_enable_x64", True)


def _check_out(path, names=(), inputs=()):
    """Before computing: --out is a folder (or can be made), writable, and overwrites no input."""
    from ..io import check_outputs

    check_outputs([("--out", path, "dir", names)], inputs)


def _show_progress(args) -> bool:
    from . import _common

    return not args.no_progress and _common.VERBOSITY >= 1


def _options(args, skip=("func", "command", "quiet", "verbose", "version")) -> dict:
    return {k: v for k, v in vars(args).items() if k not in skip}


def run_paper(args) -> int:
    _check_out(args.out, PAPER_FILES, [args.params])
    params = _load_params(args.params)
    if args.quick:
        args = argparse.Namespace(**{**vars(args), "duration": min(args.duration, 10.0),
                                     "samples": min(args.samples, 8), "models": min(args.models, 8),
                                     "compare_samples": min(args.compare_samples, 4),
                                     "spring_samples": min(args.spring_samples, 2)})
    for name in ("samples", "models", "compare_samples"):
        if getattr(args, name) < 2:
            raise _usage(f"--{name.replace('_', '-')} must be >= 2, got {getattr(args, name)}")
    if args.spring_samples < 1:
        raise _usage(f"--spring-samples must be >= 1, got {args.spring_samples}")
    for name in ("duration", "speed", "threshold_deg"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v > 0):
            raise _usage(f"--{name.replace('_', '-')} must be positive, got {v}")
    if not (math.isfinite(args.noise_rel) and args.noise_rel >= 0):
        raise _usage(f"--noise-rel must be >= 0, got {args.noise_rel}")
    if not (math.isfinite(args.hill_height) and args.hill_height >= 0):
        raise _usage(f"--hill-height must be >= 0, got {args.hill_height}")
    if str(args.road_class).upper() not in tuple("ABCDEFGH"):
        raise _usage(f"--road-class must be one of A-H, got {args.road_class!r}")
    if args.duration < 1.0:
        raise _usage(f"--duration must be at least 1 s, got {args.duration}")

    _enable_x64()
    from ..studies._study import SOLVER_FIXED, SOLVER_LOOSE, SOLVER_TIGHT, StudyConfig, run_paper_study, write_paper_outputs

    cfg = StudyConfig(
        params=params, duration=args.duration, speed=args.speed, road_class=str(args.road_class).upper(),
        road_seed=args.road_seed, hill_height=args.hill_height, noise_rel=args.noise_rel,
        n_noise=args.samples, n_models=args.models, n_compare=args.compare_samples, n_spring=args.spring_samples,
        seed=args.seed, drift_threshold_deg=args.threshold_deg,
        compare_solvers=(SOLVER_LOOSE,) if args.no_compare else (SOLVER_LOOSE, SOLVER_TIGHT, SOLVER_FIXED),
        progress=_show_progress(args), linear=args.linear, rounding_check=not args.no_rounding_check,
    )
    try:
        cfg.validate()
    except ValueError as e:
        raise _usage(str(e)) from None
    from ..io import atomic_dir, provenance
    from . import _common

    res = run_paper_study(cfg, log=lambda m: print(m, flush=True) if _common.VERBOSITY >= 1 else None)
    s = res["summary"]
    s["provenance"] = provenance("paper", [args.params], model={"file": args.params} if args.params else
                                 {"default": "the seed's table (HalfCarParams())"}, options=_options(args))
    with atomic_dir(args.out, "--out") as tmp:
        files = write_paper_outputs(res, tmp, dpi=args.dpi)
    print(_paper_report(s))
    print(f"wrote {', '.join(files)} to {args.out} ({s['timings_s']['total']:.0f} s)")
    return 0


def _t(v, ci=False):
    if v is None or v == "inf":
        return "never"
    if isinstance(v, dict):
        def c(name):
            lo_hi = v.get(f"ci_{name}")
            return f" [{_t(lo_hi[0])}, {_t(lo_hi[1])}]" if ci and lo_hi else ""

        return (f"median {_t(v['median'])}{c('median')}, q10 {_t(v['q10'])}{c('q10')}, q90 {_t(v['q90'])}{c('q90')} "
                f"(min {_t(v['min'])}, max {_t(v['max'])}, never {v['n_never']}/{v['n']})")
    return f"{v:.2f} s"


def _paper_report(s) -> str:
    d = s["drift_off_beta_s"]
    m = s["enforced_moment_Nm"]
    lines = [
        f"measured forces {s['measurement']['force_min_N'] / 1e3:.1f} .. {s['measurement']['force_max_N'] / 1e3:.1f} kN,"
        f" sigma = {s['measurement']['sigma_N']:.1f} N",
    ]
    h = s.get("headline")
    if h:
        hd = h["drift_off_beta_s"]
        lines += [
            f"drift-off of beta (> {s['config']['drift_threshold_deg']:g} deg), converged ({h['solver']}; "
            f"[95 % bootstrap intervals]):",
            f"  undisturbed forces      {_t(hd['undisturbed'])}",
            f"  noisy forces            {_t(hd['noisy'], ci=True)}",
            f"  paper's perturbed model {_t(hd['perturbed_paper'])}",
            f"  random perturbed models {_t(hd['perturbed_random'], ci=True)}",
            f"  change at {h['check_solver']}: at most {h['step_check']['max_abs_s']:.3f} s"
            + (f"; with jnp.sin/jnp.cos: at most {h['rounding_check']['max_abs_s']:.3f} s" if "rounding_check" in h else ""),
        ]
    lines += [
        f"drift-off of beta at {s['config']['solver']['name']} (the paper's setting; rounding-sensitive):",
        f"  undisturbed forces      {_t(d['undisturbed'])}",
        f"  noisy forces            {_t(d['noisy'])}",
        f"  paper's perturbed model {_t(d['perturbed_paper'])}",
        f"  random perturbed models {_t(d['perturbed_random'])}",
        f"enforced moment |lambda| max: original model + undisturbed forces {m['unperturbed_undisturbed']['abs_max']:.0f} Nm,"
        f" perturbed model + noisy forces {m['perturbed_noisy']['abs_max']:.0f} Nm;"
        f" inertia term |I beta''| max {m['inertia_term']['abs_max'] / 1e3:.1f} kNm",
    ]
    return "\n".join(lines)


def run_pointmass(args) -> int:
    _check_out(args.out, ("fig2_pointmass_std.png", "pointmass_summary.json"))
    if args.paths < 2:
        raise _usage(f"--paths must be >= 2, got {args.paths}")
    for name in ("duration", "dt", "mass"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v > 0):
            raise _usage(f"--{name} must be positive, got {v}")
    if not (math.isfinite(args.sigma_m) and args.sigma_m > 0):
        raise _usage(f"--sigma-m must be positive, got {args.sigma_m}")
    if any(not (math.isfinite(e) and e >= 0) for e in args.eta):
        raise _usage(f"--eta values must be >= 0, got {args.eta}")
    if args.duration / args.dt < 20:
        raise _usage(f"--duration / --dt must give at least 20 steps, got {args.duration / args.dt:g}")

    _enable_x64()
    from ..io import atomic_dir, provenance
    from ..studies._pointmass import plot_pointmass, run_pointmass_study

    study = run_pointmass_study(sigma_m=args.sigma_m, dt=args.dt, duration=args.duration, n_paths=args.paths,
                                etas=tuple(args.eta), mass=args.mass, seed=args.seed, progress=_show_progress(args))
    study["provenance"] = provenance("pointmass", [], model={"mass_kg": args.mass}, options=_options(args))
    files = ["fig2_pointmass_std.png", "pointmass_summary.json"]
    with atomic_dir(args.out, "--out") as tmp:
        plot_pointmass(study, os.path.join(tmp, files[0]), dpi=args.dpi)
        with open(os.path.join(tmp, files[1]), "w") as fh:
            json.dump(study, fh, indent=1)
    lo, hi = study["chi2_99_interval"]
    print(f"99 % chi-square interval of Var ratios for {args.paths} paths: [{lo:.3f}, {hi:.3f}]")
    for c in study["cases"]:
        t = [ti for ti in c["t"] if ti >= 200 * args.dt]
        rx = c["var_ratio_x"][-len(t):] if t else []
        rv = c["var_ratio_v"][-len(t):] if t else []
        rng = (f"x in [{min(rx):.3f}, {max(rx):.3f}], v in [{min(rv):.3f}, {max(rv):.3f}] at t >= 200 dt"
               if t else "no save time at t >= 200 dt")
        print(f"eta = {c['eta']:g}: Var ratio Monte-Carlo / closed form: {rng}; "
              f"inside: {100 * c['fraction_inside_chi2_99']:.0f} % (vs the exact Euler variance, all times: "
              f"{100 * c['fraction_inside_chi2_99_euler_all_times']:.0f} %); "
              f"slopes of Std x, v: early {c['slope_std_x_early']:.2f}, {c['slope_std_v_early']:.2f}, "
              f"late {c['slope_std_x_late']:.2f}, {c['slope_std_v_late']:.2f}")
    print(f"wrote {', '.join(files)} to {args.out}", file=sys.stdout)
    return 0
