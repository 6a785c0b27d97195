"""Undisturbed force-driven half-car at the seed's loose and tight tolerances: jaxdrift DOPRI5 vs scipy RK45.

Found (printed only, no result file; run 2026-12-02 on the loaded 2-core machine, about 19 minutes):
at the seed's loose tolerance (rtol 1e-4) the undisturbed pitch error at 10, 20, 30 s is 0.20, 2.9,
39 deg with scipy's RK45 and 0.43, 6.2, 75 deg with jaxdrift's DOPRI5 (the same controller; 1 deg
passed at 16 s and 13 s); at rtol 1e-8 it is 0.0002, 0.003, 0.043 deg and 0.0009, 0.009, 0.12 deg,
never reaching 1 deg: the loose-tolerance drift is integration error, and its size depends on the
step sequence.

Reproduce: python benchmarks/experiments/solver_drift_check.py   (prints steps and pitch error in degrees at 10, 20, 30 s)
"""
import numpy as np, jax, jax.numpy as jnp
jax.config.update("jax_enable_x64", True)
from scipy.integrate import solve_ivp
from jaxdrift.studies._study import StudyConfig, virtual_measurement, simulate_forces, SOLVER_LOOSE
from jaxdrift.models._road import iso8608_road
from jaxdrift.models._halfcar import force_driven_rhs, static_equilibrium
from jaxdrift import SampledSignal
cfg = StudyConfig()
p = cfg.params
road = iso8608_road(cfg.road_class, seed=cfg.road_seed, hill_height=cfg.hill_height, hill_wavelength=cfg.hill_wavelength)
inputs = road.sampled_wheel_inputs(cfg.speed, cfg.wheelbase, cfg.duration)
vm = virtual_measurement(p, inputs, cfg.duration, cfg.sample_rate, cfg.measurement_rtol, cfg.measurement_atol)
F = np.asarray(vm.forces); ts = np.asarray(vm.ts)
save = ts[::100]
beta_ref = np.asarray(vm.x[::100, 3])
x0 = np.asarray(static_equilibrium(p))
rhs = jax.jit(lambda t, x, f: force_driven_rhs(t, x, p, f[0], f[1]))
def fs(t, x):
    f = np.array([np.interp(t, ts, F[:, 0]), np.interp(t, ts, F[:, 1])])
    return np.asarray(rhs(t, x, f))
for rtol, atol in [(1e-4, 1e-6), (1e-8, 1e-10)]:
    r = solve_ivp(fs, (0, ts[-1]), x0, method="RK45", rtol=rtol, atol=atol, t_eval=save)
    err = np.degrees(np.abs(r.y[3] - beta_ref))
    print("scipy", rtol, "steps", (r.nfev-2)//6, "err at 10,20,30 s", err[[100,200,-1]], "first >1deg", save[np.argmax(err > 1)] if (err>1).any() else None)
    sig = SampledSignal(0.0, ts[1]-ts[0], F)
    from jaxdrift import solve_ode
    sol = solve_ode(lambda t, x, s: force_driven_rhs(t, x, p, s(t)[0], s(t)[1]), x0, 0.0, float(ts[-1]), saveat=save, args=sig, rtol=rtol, atol=atol, max_steps=2_000_000)
    e2 = np.degrees(np.abs(np.asarray(sol.ys[:, 3]) - beta_ref))
    print("ours ", rtol, "steps", int(sol.num_accepted + sol.num_rejected), "err", e2[[100,200,-1]], "first>1", save[np.argmax(e2 > 1)] if (e2>1).any() else None)
