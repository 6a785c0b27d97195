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
# # Section 2 of the seed paper: integrating noisy forces
#
# A point mass at rest, driven by a force that is measured every $\Delta t$ with Gaussian errors
# of standard deviation $\sigma_M$ (2.2), integrated by the explicit Euler scheme (2.3):
#
# $$\tilde v_{n+1} = \tilde v_n + \Big(\frac{f(n\Delta t) + \epsilon_n}{m} - \eta \tilde v_n\Big)\Delta t,
# \qquad \tilde x_{n+1} = \tilde x_n + \tilde v_n \Delta t .$$
#
# This is a path of the Ito SDE (2.4) with $\sigma^2 = \sigma_M^2 \Delta t$ (2.5). Without damping
# the errors grow like Brownian motion and integrated Brownian motion, (2.8):
# $\mathrm{Var}\,\tilde v = \sigma^2 t / m^2$, $\mathrm{Var}\,\tilde x = \sigma^2 t^3 / (3 m^2)$,
# i.e. $\mathrm{Std} = O(t^{1/2})$ and $O(t^{3/2})$. With damping $\eta > 0$ the velocity error is
# bounded (Ornstein-Uhlenbeck) but the position error still grows like $t^{1/2}$, (2.11).
#
# Here we simulate many noise samples with jaxdrift's engine (`solve_ode` with `method="euler"`
# at the sample step, the noisy force as a zero-order-hold `SampledSignal`, `monte_carlo` over the
# samples) and compare the empirical standard deviations with the closed forms.
#
# Set `JAXDRIFT_NOTEBOOK_SMALL=1` for a small, fast configuration (the test suite does).

# %%
import os

import jax

jax.config.update("jax_enable_x64", True)  # float64: the library never switches it on itself

import matplotlib.pyplot as plt
import numpy as np

import jaxdrift
from jaxdrift.studies._notebook import notebook_output_dir
from jaxdrift.studies._pointmass import chi2_interval, plot_pointmass, run_pointmass_study

SMALL = os.environ.get("JAXDRIFT_NOTEBOOK_SMALL", "") not in ("", "0")
# outputs go to $JAXDRIFT_NOTEBOOK_OUT, by default build/notebooks/ in the repository
OUT = notebook_output_dir()

n_paths = 200 if SMALL else 2000
duration = 5.0 if SMALL else 100.0
dt, sigma_m = 0.01, 1.0
print(f"{n_paths} noise samples, {duration:g} s at dt = {dt} s, sigma_M = {sigma_m} N")

# %% [markdown]
# ## One noise sample
# The noisy force is integrated once to the velocity and twice to the position.

# %%
p = jaxdrift.PointMassParams(m=1.0, eta=0.0)
n = int(round(duration / dt))
t = np.arange(n + 1) * dt
true_force = np.sin(0.5 * t[:-1])
noise = sigma_m * np.asarray(jaxdrift.path_normals(jax.random.key(1), 0, n, 1))[:, 0]
ys_true, _ = jaxdrift.pointmass_path(p, true_force, dt, t)
ys_noisy, _ = jaxdrift.pointmass_path(p, true_force + noise, dt, t)
fig, ax = plt.subplots(1, 2, figsize=(10, 3.5))
ax[0].plot(t, ys_true[:, 1], "k", label="true v")
ax[0].plot(t, ys_noisy[:, 1], "C3", lw=0.8, label="from noisy forces")
ax[1].plot(t, ys_true[:, 0], "k", label="true x")
ax[1].plot(t, ys_noisy[:, 0], "C3", lw=0.8, label="from noisy forces")
for a in ax:
    a.set_xlabel("t [s]")
    a.legend()
plt.show()

# %% [markdown]
# ## Many noise samples against (2.8) and (2.11)

# %%
study = run_pointmass_study(sigma_m=sigma_m, dt=dt, duration=duration, n_paths=n_paths, etas=(0.0, 0.5), progress=False)
plot_pointmass(study, os.path.join(OUT, "fig2_pointmass_std.png"))
lo, hi = chi2_interval(n_paths)
for c in study["cases"]:
    late = np.asarray(c["t"]) >= 2.0  # after >= 200 Euler steps the O(dt/t) bias is < 1 %
    rx, rv = np.asarray(c["var_ratio_x"])[late], np.asarray(c["var_ratio_v"])[late]
    print(f"eta = {c['eta']}: Var ratio x in [{rx.min():.3f}, {rx.max():.3f}], v in [{rv.min():.3f}, {rv.max():.3f}];"
          f" 99 % chi-square interval [{lo:.3f}, {hi:.3f}]")
    print(f"   log-log slopes of Std x, Std v: early {c['slope_std_x_early']:.2f}, {c['slope_std_v_early']:.2f};"
          f" late {c['slope_std_x_late']:.2f}, {c['slope_std_v_late']:.2f}")

# %%
fig = plt.figure(figsize=(11, 4.2))
img = plt.imread(os.path.join(OUT, "fig2_pointmass_std.png"))
plt.imshow(img)
plt.axis("off")
plt.show()

# %% [markdown]
# Without damping the slopes are 3/2 and 1/2, as (2.9) says; with damping the velocity error
# saturates at the Ornstein-Uhlenbeck level $\sigma^2/(2\eta m^2)$ and the position error turns
# from $t^{3/2}$ to $t^{1/2}$ (2.14). No integration scheme removes this: a better scheme only
# rescales $\sigma$.
