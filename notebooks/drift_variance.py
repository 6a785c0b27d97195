# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # How fast does the drift grow? Monte-Carlo against theory
#
# Noise in measured forces integrates like Brownian motion. Before running thousands of noisy
# simulations it pays to know what theory predicts, and where it stops predicting. jaxdrift gives
# three kinds of analytic variance next to its Monte-Carlo runner:
#
# * the seed paper's closed forms for the point mass, (2.8) and (2.11), with the Brownian intensity
#   $\sigma^2 = \sigma_M^2 \Delta t$ of (2.5): `jaxdrift.point_mass_covariance`;
# * the free-mode law of the force-driven half-car: with the tyre forces prescribed nothing ties
#   the car to the ground, so heave and pitch are double-integrated noise through the generalised
#   inertia, $\mathrm{Cov}\,q = M_r^{-1} G\,\mathrm{diag}(\sigma^2) G^T M_r^{-1} t^3/3$:
#   `jaxdrift.halfcar_free_mode_covariance`;
# * for any model, the covariance propagated along the noise-free reference,
#   $P' = A P + P A^T + B Q B^T$: `jaxdrift.propagate_covariance`.
#
# This notebook runs all three against Monte-Carlo on the point mass and on the seed's half-car
# study (class D road with $\pm 2$ m hills at 20 m/s, forces sampled at 1 kHz, noise
# $0.002 \max|f|$), with 95 % chi-square intervals on every Monte-Carlo variance. The full tables
# are `benchmarks/variance.py`; the method is `docs/variance.md`.
#
# Set `JAXDRIFT_NOTEBOOK_SMALL=1` for a small, fast configuration (the test suite does).

# %%
import json
import os

import jax

jax.config.update("jax_enable_x64", True)  # float64: the library never switches it on itself

import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

import jaxdrift
from jaxdrift.studies._notebook import notebook_output_dir

SMALL = os.environ.get("JAXDRIFT_NOTEBOOK_SMALL", "") not in ("", "0")
# outputs go to $JAXDRIFT_NOTEBOOK_OUT, by default build/notebooks/ in the repository
OUT = notebook_output_dir()

n_paths = 100 if SMALL else 1000
T = 4.0 if SMALL else 30.0
dt = 1e-3
ts = np.array([t for t in (0.5, 1, 2, 4, 5, 10, 15, 20, 25, 30) if t <= T])
print(f"{n_paths} noise samples, {T:g} s at {1 / dt:g} Hz, statistics at t = {ts.tolist()} s")


def mc(path_fn, seed=7):
    """Monte-Carlo over n_paths noise samples: variance of each saved quantity at ts."""
    res = jaxdrift.monte_carlo(path_fn, n_paths, key=jax.random.key(seed), save_ts=ts, progress=False)
    assert res.count == n_paths, "some paths failed"
    return np.asarray(res.var)


def interval(var):
    """95 % chi-square interval of a Monte-Carlo variance estimated from n_paths samples."""
    return jaxdrift.variance_interval(var, n_paths, 0.95)


# %% [markdown]
# ## The point mass
#
# $m \ddot x = f + \epsilon - m \eta \dot x$ with $f = 0$, white noise of $\sigma_M = 32$ N at 1 kHz on
# the force, $m = 750$ kg (the seed's chassis), without damping and with $\eta = 0.5$ 1/s. The
# engine integrates the noisy samples with fixed 1 ms DOPRI5 steps (linear between samples).

# %%
m, sigma_m = 750.0, 32.0
n_samples = int(round(T / dt)) + 1
pm = {}
for eta in (0.0, 0.5):

    def rhs(t, y, sig, eta=eta):
        return jnp.stack([y[1], sig(t)[0] / m - eta * y[1]])

    def path(key, i, model, rhs=rhs):
        sig = jaxdrift.SampledSignal(0.0, dt, sigma_m * jaxdrift.path_normals(key, i, n_samples, 1))
        sol = jaxdrift.solve_ode(rhs, jnp.zeros(2), 0.0, T, saveat=ts, args=sig, dt=dt)
        return sol.ys, sol.result

    var = mc(path)
    closed = np.asarray(jaxdrift.point_mass_covariance(ts, sigma_m=sigma_m, dt=dt, m=m, eta=eta))
    pm[eta] = (var, closed)
    for j, q in enumerate("xv"):
        lo, hi = interval(var[:, j])
        inside = (lo <= closed[:, j, j]) & (closed[:, j, j] <= hi)
        print(f"eta = {eta}: {q}: closed form inside the 95 % interval at {int(inside.sum())} of {ts.size} times")

# %% [markdown]
# ## The half-car: the virtual measurement
#
# Step 1 of the seed's section 4: the road-driven model gives the contact forces $f^{(0)}$. The
# noisy study adds white noise of $0.002 \max|f^{(0)}|$ on both force channels and integrates the
# force-driven model (A.3) from static equilibrium.

# %%
params = jaxdrift.HalfCarParams()
road = jaxdrift.iso8608_road("D", seed=0)
wheelbase = float(params.a + params.b)
vm = jaxdrift.virtual_measurement(params, road.sampled_wheel_inputs(20.0, wheelbase, T + 0.01), T)
f0 = jnp.asarray(vm.forces)
sigma = 0.002 * float(jnp.max(jnp.abs(f0)))
x0 = jaxdrift.static_equilibrium(params, "force")
print(f"forces {float(f0.min()) / 1e3:.1f} .. {float(f0.max()) / 1e3:.1f} kN, sigma = {sigma:.1f} N")


def force_rhs(t, x, sig):
    f = sig(t)
    return jaxdrift.force_driven_rhs(t, x, params, f[0], f[1])


def halfcar_path(key, i, model):
    sig = jaxdrift.SampledSignal(0.0, dt, f0 + sigma * jaxdrift.path_normals(key, i, f0.shape[0], 2))
    sol = jaxdrift.solve_ode(force_rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt)
    return sol.ys[:, jnp.array([2, 3])], sol.result  # heave z3, pitch beta


var_hc = mc(halfcar_path)

# %% [markdown]
# ## The half-car: free-mode law and propagated covariance
#
# The free-mode law needs only the masses and the geometry; the propagated covariance linearises
# the model around the trajectory under the undisturbed forces and integrates
# $P' = A P + P A^T + B Q B^T$ with $Q = \mathrm{diag}(\sigma^2 \Delta t)$ (`inputs` is the
# noise-free force signal, `noise_sigma`/`noise_dt` describe the noise on it).

# %%
law = np.asarray(jaxdrift.halfcar_free_mode_covariance(ts, params, sigma_m=sigma, dt=dt))
prop = jaxdrift.propagate_covariance(
    lambda t, x, u, a: jaxdrift.force_driven_rhs(t, x, params, u[0], u[1]), x0, 0.0, T, saveat=ts,
    inputs=jaxdrift.SampledSignal(0.0, dt, f0), noise_sigma=sigma, noise_dt=dt, dt=dt,
)
pv = np.asarray(prop.var)
rows = []
for k, t in enumerate(ts):
    row = {"t": float(t)}
    for j, (q, col, fm) in enumerate((("z3", 2, 0), ("beta", 3, 1))):
        lo, hi = interval(var_hc[k, j])
        row[q] = {"mc_var": float(var_hc[k, j]), "ci": [float(lo), float(hi)],
                  "law_std_ratio": float(np.sqrt(law[k, fm, fm] / var_hc[k, j])),
                  "propagated_std_ratio": float(np.sqrt(pv[k, col] / var_hc[k, j])),
                  "propagated_inside": bool(lo <= pv[k, col] <= hi)}
    rows.append(row)
    print(f"t = {t:5.1f} s  pitch std MC {np.sqrt(var_hc[k, 1]):.3g} rad: law/MC {row['beta']['law_std_ratio']:.2f}, "
          f"propagated/MC {row['beta']['propagated_std_ratio']:.2f} "
          f"({'inside' if row['beta']['propagated_inside'] else 'outside'} the 95 % interval); "
          f"heave propagated/MC {row['z3']['propagated_std_ratio']:.2f}")
with open(os.path.join(OUT, "drift_variance.json"), "w") as fh:
    json.dump({"n_paths": n_paths, "T": T, "sigma_N": sigma, "halfcar": rows}, fh, indent=1)

# %% [markdown]
# ## The picture
#
# Standard deviations against time, log-log; the shaded bands are the 95 % intervals of the
# Monte-Carlo estimates.

# %%
fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
ax = axes[0]
for eta, (var, closed) in pm.items():
    lo, hi = interval(var[:, 0])
    ax.fill_between(ts, np.sqrt(lo), np.sqrt(hi), alpha=0.25, label=f"Monte-Carlo x, eta = {eta:g} (95 %)")
    ax.plot(ts, np.sqrt(closed[:, 0, 0]), "--", label=f"closed form (2.{8 if eta == 0 else 11})")
ax.set(xscale="log", yscale="log", xlabel="t [s]", ylabel="std of the position error [m]", title="point mass")
ax.legend(fontsize=7)
for ax, (j, q, col, fm, unit) in zip(axes[1:], ((1, "pitch beta", 3, 1, "rad"), (0, "heave z3", 2, 0, "m"))):
    lo, hi = interval(var_hc[:, j])
    ax.fill_between(ts, np.sqrt(lo), np.sqrt(hi), color="C0", alpha=0.3, label="Monte-Carlo (95 %)")
    ax.plot(ts, np.sqrt(law[:, fm, fm]), "k--", label="free-mode law (t^3/2)")
    ax.plot(ts, np.sqrt(pv[:, col]), "C3", label="propagated covariance")
    ax.set(xscale="log", yscale="log", xlabel="t [s]", ylabel=f"std [{unit}]", title=f"half-car, {q}")
    ax.legend(fontsize=7)
fig.tight_layout()
fig.savefig(os.path.join(OUT, "drift_variance.png"), dpi=90)
plt.close(fig)
print("wrote", os.path.join(OUT, "drift_variance.png"))

# %% [markdown]
# ## What it shows
#
# * The point mass follows its closed forms within the Monte-Carlo interval: without damping the
#   position error grows like $t^{3/2}$, with damping like $t^{1/2}$.
# * The half-car's heave follows the free-mode law: it is double-integrated noise through the
#   total mass.
# * The pitch follows the law only for the first seconds: on a hilly road the reference pitch
#   follows the slope, and the weight carried by the springs gives a pitch stiffness that changes
#   sign along the road. The propagated covariance accounts for that and follows the
#   Monte-Carlo pitch as long as the pitch deviations stay in the linear range (on this class D
#   road to about 15 s, with deviations of a quarter radian; on class C over the whole 30 s).
#   Beyond that the noisy paths spread over radians and no first-order method follows them; a
#   Gaussian moment closure does worse (`benchmarks/experiments/moment_closure.py`). There the Monte-Carlo run
#   is the tool, and the propagated covariance tells when its linear regime ends.
