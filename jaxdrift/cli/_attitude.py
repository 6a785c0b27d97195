"""Attitude subcommands: ``ins`` (Figs. 1-2), ``quaternion-drift`` ((3.11)-(3.16)), ``accel-array`` (3.1).

Thin: argument checks, library calls, figures and a JSON summary per command, written into a
temporary folder and moved into DIR at the end (nothing half-written). See docs/attitude.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os

INS_DESCRIPTION = """\
The seed's INS demonstration (section 3.2, Figs. 1-2): a plausible 10-minute, 1000 Hz vehicle
attitude history (road-induced pitch and roll, curves in yaw), body rates with white noise of
sigma_M = 0.1 rad/s per sample, the angles reconstructed by integrating q' = 0.5 Omega q, and their
errors against the envelope sigma_M sqrt(dt) sqrt(t) = 0.18 deg/sqrt(s) sqrt(t) (2.5). A third
figure puts bias instability (error O(t)) beside angle random walk (O(t^1/2)) for gyro grades.

Writes fig1_angles.png, fig2_angle_errors.png, fig_grades.png, ins_summary.json.
exit codes: 0 done, 2 bad input (nothing written)
"""

QD_DESCRIPTION = """\
Monte-Carlo of the quaternion SDE (3.13)/(3.11): the Ito norm growth exp(sigma^2 t/8) under the
explicit Euler (Euler-Maruyama) scheme against none under stochastic Heun (Stratonovich) and the
exponential map, and the angle error growing like sigma W(t) (Std sigma sqrt(t)), with the closed
forms and 99 % chi-square bands.

Writes quaternion_norm.png, quaternion_angle_error.png, quaternion_summary.json.
exit codes: 0 done, 2 bad input (nothing written)
"""

AA_DESCRIPTION = """\
Section 3.1: rigid-body motion from m+1 >= 4 triaxial accelerometers with gravity correction (3.3),
reconstructed by the six-step summary. Shows the noise-free reconstruction error, the angle error
under accelerometer noise against the closed form (integrated random walk, Std ~ t^3/2), and how the
result depends on the high-pass cut-off of remark 2.

Writes accel_reconstruction.png, accel_noise_growth.png, accel_highpass.png, accel_summary.json.
exit codes: 0 done, 2 bad input (nothing written)
"""


def _positive(name, v, usage):
    if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
        raise usage(f"--{name} must be a positive number, got {v!r}")


def add_parser(subparsers) -> None:
    fmt = argparse.RawDescriptionHelpFormatter
    p = subparsers.add_parser("ins", help="INS demonstration of section 3.2 (Figs. 1-2, bias instability vs ARW)",
                              description=INS_DESCRIPTION, formatter_class=fmt)
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    p.add_argument("--seed", type=int, default=0, help="seed of the motion and the noise (default 0)")
    p.add_argument("--duration", type=float, default=600.0, help="length [s] (default 600)")
    p.add_argument("--rate", type=float, default=1000.0, help="sample rate [Hz] (default 1000)")
    p.add_argument("--sigma", type=float, default=0.1, help="rate noise per sample [rad/s] (default 0.1)")
    p.add_argument("--paths", type=int, default=16, help="noise samples for the error envelope (default 16)")
    p.add_argument("--method", choices=("expmap", "euler", "dopri5"), default="expmap",
                   help="integrator of q' = 0.5 Omega q for the shown sample (default expmap; dopri5 is slow)")
    p.set_defaults(func=run_ins)

    p = subparsers.add_parser("quaternion-drift", help="Ito norm growth and angle error of the quaternion SDE (3.11)-(3.16)",
                              description=QD_DESCRIPTION, formatter_class=fmt)
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--sigma", type=float, default=0.5, help="Brownian intensity of the rate noise [rad/sqrt(s)] (default 0.5)")
    p.add_argument("--t1", type=float, default=4.0, help="end time [s] (default 4)")
    p.add_argument("--dt", type=float, default=0.004, help="step [s] (default 0.004)")
    p.add_argument("--paths", type=int, default=400, help="Monte-Carlo paths (default 400)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=run_quaternion_drift)

    p = subparsers.add_parser("accel-array", help="section 3.1 reconstruction from an accelerometer array, high-pass cut-off study",
                              description=AA_DESCRIPTION, formatter_class=fmt)
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--duration", type=float, default=60.0, help="length [s] (default 60)")
    p.add_argument("--rate", type=float, default=200.0, help="sample rate [Hz] (default 200)")
    p.add_argument("--noise", type=float, default=0.02, help="accelerometer noise per sample [m/s^2] (default 0.02)")
    p.add_argument("--paths", type=int, default=100, help="Monte-Carlo paths for the noise growth (default 100)")
    p.set_defaults(func=run_accel_array)


def _run_into(out, study, command=None, summary_name=None, options=None, names=()):
    """Check ``out`` before computing, run ``study(tmp_dir)`` and move its files into ``out`` only
    if it succeeds (:func:`jaxdrift.io.atomic_dir`); the summary JSON gets the provenance."""
    from ..io import atomic_dir, check_outputs, provenance

    check_outputs([("--out", out, "dir", names)])
    with atomic_dir(out, "--out") as tmp:
        summary = study(tmp)
        if summary_name:
            summary["provenance"] = provenance(command, [], options=options or {})
            with open(os.path.join(tmp, summary_name), "w") as fh:
                json.dump(summary, fh, indent=1)
    return summary


def _options(args) -> dict:
    return {k: v for k, v in vars(args).items() if k not in ("func", "command", "quiet", "verbose", "version")}


# ----------------------------------------------------------------------------- ins


def run_ins(args) -> int:
    from ..errors import UsageError
    from ..studies._attitude_demos import ins_study

    for k in ("duration", "rate", "sigma"):
        _positive(k, getattr(args, k), UsageError)
    if args.duration < 2.0:
        raise UsageError(f"--duration must be at least 2 s (the grade slopes are fitted from t = 1 s), got {args.duration}")
    if args.paths < 2:
        raise UsageError("--paths must be at least 2")
    summary = _run_into(args.out, lambda tmp: ins_study(tmp, seed=args.seed, duration=args.duration,
                                                        dt=1.0 / args.rate, sigma_m=args.sigma,
                                                        n_paths=args.paths, method=args.method, progress=_verbose()),
                        "ins", "ins_summary.json", _options(args))
    print(json.dumps(summary["envelope"], indent=1))
    return 0


# ----------------------------------------------------------------------------- quaternion drift


def run_quaternion_drift(args) -> int:
    from ..errors import UsageError
    from ..studies._attitude_demos import quaternion_drift_study

    for k in ("sigma", "t1", "dt"):
        _positive(k, getattr(args, k), UsageError)
    n_steps = round(args.t1 / args.dt)
    if abs(n_steps * args.dt - args.t1) > 1e-9 * args.t1 or n_steps % 40:
        raise UsageError("--t1 must be a multiple of 40 steps of --dt")
    if args.paths < 10:
        raise UsageError("--paths must be at least 10")
    summary = _run_into(args.out, lambda tmp: quaternion_drift_study(tmp, sigma=args.sigma, t1=args.t1, dt=args.dt,
                                                                     n_paths=args.paths, seed=args.seed, progress=_verbose()),
                        "quaternion-drift", "quaternion_summary.json", _options(args))
    print(json.dumps(summary, indent=1))
    return 0


# ----------------------------------------------------------------------------- accelerometer array


def run_accel_array(args) -> int:
    from ..errors import UsageError
    from ..studies._attitude_demos import accel_array_study

    for k in ("duration", "rate", "noise"):
        _positive(k, getattr(args, k), UsageError)
    if args.paths < 10:
        raise UsageError("--paths must be at least 10")
    summary = _run_into(args.out, lambda tmp: accel_array_study(tmp, seed=args.seed, duration=args.duration,
                                                                dt=1.0 / args.rate, noise=args.noise,
                                                                n_paths=args.paths, progress=_verbose()),
                        "accel-array", "accel_summary.json", _options(args))
    print(json.dumps(summary, indent=1))
    return 0


def _verbose() -> bool:
    from ._common import VERBOSITY

    return VERBOSITY >= 1
