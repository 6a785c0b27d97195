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
# # Section 4 of the seed paper: drift of the force-driven half-car
#
# The half-car of Appendix A (chassis heave $z_3$ and pitch $\beta$, two wheels, z pointing down)
# is excited in three ways: by the road (A.4), by the contact forces (A.3), and by the forces with
# the pitch angle prescribed (A.5). The study of section 4.1:
#
# 1. **virtual measurement**: drive the model over a road, record the wheel forces $f^{(0)}$;
# 2. **undisturbed forces**: drive the force model with $f^{(0)}$;
# 3. **noisy forces**: $f^{(0)} + \varepsilon$, $\sigma = 0.002 f_{max}$, many samples;
# 4. **perturbed models**: $k_3, k_4, d_3, d_4, I$ changed by a few per cent;
# 5. **stabilised simulation**: perturbed model, noisy forces, $\beta$ prescribed; the enforced
#    moment $\lambda = I\ddot\beta - \cos\beta\,(b f_3 - a f_4)$ measures the inconsistency.
#
# `jaxdrift paper --out DIR` runs all of it; this notebook runs the same library calls and shows
# the figures. Set `JAXDRIFT_NOTEBOOK_SMALL=1` for a small, fast configuration.

# %%
import json
import os

import jax

jax.config.update("jax_enable_x64", True)  # float64: the library never switches it on itself

import matplotlib.pyplot as plt
import numpy as np

import jaxdrift
from jaxdrift.studies._notebook import notebook_output_dir

SMALL = os.environ.get("JAXDRIFT_NOTEBOOK_SMALL", "") not in ("", "0")
# outputs go to $JAXDRIFT_NOTEBOOK_OUT, by default build/notebooks/ in the repository
OUT = notebook_output_dir()

params = jaxdrift.HalfCarParams()  # the seed's table; e.g. HalfCarParams(m3=800.0) for your own
print(params.to_dict())

# %% [markdown]
# ## The model and its static equilibrium
# Every simulation starts at rest in static equilibrium: the tyres carry the whole weight,
# $f_1 + f_2 = (m_1 + m_2 + m_3) g$.

# %%
x0 = jaxdrift.static_equilibrium(params, "force")
f1, f2, f3, f4 = jaxdrift.equilibrium_forces(params)
print("x0 =", np.round(np.asarray(x0), 5))
print(f"f1 + f2 = {f1 + f2:.2f} N = (m1 + m2 + m3) g = {params.total_mass * params.g:.2f} N")
print("rhs at rest:", np.abs(np.asarray(jaxdrift.force_driven_rhs(0.0, x0, params, f1, f2))).max())

# %% [markdown]
# ## Steps 1-5 in one call
# The defaults are the CLI's: class D road with $\pm 2$ m hills at 20 m/s, forces sampled at
# 1 kHz, adaptive Dormand-Prince at the paper's looser tolerance (rtol $10^{-4}$, atol $10^{-6}$).

# %%
if SMALL:
    cfg = jaxdrift.StudyConfig(params=params, duration=3.0, n_noise=2, n_models=2, n_compare=2, n_spring=1,
                               pitch_spring_stiffness=(1e3,), compare_solvers=(jaxdrift.SOLVER_LOOSE,),
                               rounding_check=False, progress=False)
else:
    cfg = jaxdrift.StudyConfig(params=params)
res = jaxdrift.run_paper_study(cfg)
files = jaxdrift.write_paper_outputs(res, OUT)
summary = res["summary"]
print("wrote", files)


# %%
def show(name, size=(11, 4.5)):
    plt.figure(figsize=size)
    plt.imshow(plt.imread(os.path.join(OUT, name)))
    plt.axis("off")
    plt.show()


show("fig4_road_forces.png", (9, 8))

# %% [markdown]
# ## Drift of $z_3$ and $\beta$ (Figs. 5-7)
# The drift-off time is the first time the pitch error exceeds the threshold.

# %%
show("fig5_z3_beta.png")
show("fig6_noise_samples.png")
show("fig7_perturbed_models.png")
print(summary["drift_definition"])
print(json.dumps(summary["drift_off_beta_s"], indent=1))

# %% [markdown]
# ## Enforced moment of the stabilised simulation (Fig. 8)

# %%
show("fig8_enforced_moment.png")
m = summary["enforced_moment_Nm"]
print(f"|lambda| max, original model + undisturbed forces: {m['unperturbed_undisturbed']['abs_max']:.1f} Nm")
print(f"|lambda| max, perturbed model + noisy forces:      {m['perturbed_noisy']['abs_max']:.1f} Nm")
print(f"|I beta''| max (inertia term):                     {m['inertia_term']['abs_max']:.1f} Nm")

# %% [markdown]
# ## The section-3 remedy and the solvers
# A rotational spring-damper to ground bounds the drift but pulls the car towards $\beta = 0$,
# which a hilly road does not allow; its reaction torque is the price.

# %%
show("fig_pitch_spring.png", (7, 4.5))
print(open(os.path.join(OUT, "solver_comparison.md")).read())
