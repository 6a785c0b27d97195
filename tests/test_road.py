"""Road profiles: ISO 8608 spectra against the standard's closed forms, seeds, hills, the
wheelbase delay and the tabulated (Hermite) wheel inputs."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.signal import welch

from jaxdrift.models._road import (
    ISO8608_GD0,
    WheelInputs,
    iso8608_psd,
    iso8608_road,
    iso8608_variance,
)


def test_class_values_are_the_standard_at_n0_0p1():
    # ISO 8608 geometric means, 1e-6 m^3 at n0 = 0.1 cycles/m; each class is 4x the previous
    assert ISO8608_GD0["A"] == pytest.approx(16e-6)
    assert ISO8608_GD0["H"] == pytest.approx(262144e-6)
    vals = [ISO8608_GD0[c] for c in "ABCDEFGH"]
    np.testing.assert_allclose(np.array(vals[1:]) / np.array(vals[:-1]), 4.0)
    assert iso8608_psd(0.1, "C") == pytest.approx(256e-6)
    assert iso8608_psd(1.0, "C") == pytest.approx(256e-6 / 100)


def test_same_seed_same_road_other_seed_other_road():
    a, b, c = iso8608_road("C", seed=3), iso8608_road("C", seed=3), iso8608_road("C", seed=4)
    s = jnp.linspace(0, 500, 2001)
    ev = jax.jit(lambda road, x: road(x))
    np.testing.assert_array_equal(np.asarray(ev(a, s)), np.asarray(ev(b, s)))
    assert np.max(np.abs(np.asarray(ev(a, s)) - np.asarray(ev(c, s)))) > 1e-3
    # class D is class C scaled by 2 in amplitude (PSD x4) with the same phases
    d = iso8608_road("D", seed=3, hill_height=0.0)
    c3 = iso8608_road("C", seed=3, hill_height=0.0)
    np.testing.assert_allclose(np.asarray(ev(d, s)), 2 * np.asarray(ev(c3, s)), atol=1e-12)


def test_component_variance_matches_the_psd_integral():
    r = iso8608_road("E", seed=0, hill_height=0.0, n_components=512)
    want = iso8608_variance("E", 0.011, 2.83)
    assert float(jnp.sum(r.amp**2) / 2) == pytest.approx(want, rel=2e-3)


def test_welch_psd_matches_iso8608():
    """The sampled profile's PSD (Welch, 10 km) lies on Gd(n) = Gd(n0) (n/n0)^-2 within 25 %
    averaged over octave bands inside the generated band."""
    r = iso8608_road("C", seed=1, hill_height=0.0, ramp_length=0.0, n_components=512)
    dx = 0.2
    s = np.arange(0, 10_000, dx)
    f_eval = jax.jit(lambda x: r(x))
    z = np.concatenate([np.asarray(f_eval(jnp.asarray(b))) for b in np.split(s, 10)])  # bounded memory
    f, pxx = welch(z, fs=1 / dx, nperseg=2**13)  # one-sided, m^2 / (cycles/m)
    for lo in (0.05, 0.1, 0.2, 0.4, 0.8):
        band = (f >= lo) & (f < 2 * lo)
        ratio = np.mean(pxx[band]) / np.mean(iso8608_psd(f[band], "C"))
        assert 0.75 < ratio < 1.25, (lo, ratio)
    # and the variance over the whole run matches the integral within 5 %
    assert np.var(z) == pytest.approx(iso8608_variance("C", 0.011, 2.83), rel=0.05)


def test_road_starts_flat_at_zero_and_slope_is_the_derivative():
    r = iso8608_road("D", seed=2)
    zs = jax.jit(lambda x: r.zeta_and_slope(x))
    s = jnp.asarray([-5.0, -1e-3, 0.0])
    z, dz = zs(s)
    np.testing.assert_array_equal(np.asarray(z), 0.0)
    np.testing.assert_array_equal(np.asarray(dz), 0.0)
    # slope = derivative (central differences), across the ramp and beyond
    x = jnp.linspace(0.5, 60.0, 400)
    h = 1e-5
    fd = (zs(x + h)[0] - zs(x - h)[0]) / (2 * h)
    _, dz = zs(x)
    np.testing.assert_allclose(np.asarray(dz), np.asarray(fd), atol=1e-6)


def test_hills_span_about_plus_minus_two_metres():
    r = iso8608_road("C", seed=0, roughness=False, hill_height=2.0, hill_wavelength=250.0)
    s = np.linspace(0, 600, 6001)
    ev = jax.jit(lambda road, x: road(x))
    z = np.asarray(ev(r, jnp.asarray(s)))
    assert z[0] == 0.0
    assert z.min() == pytest.approx(-2.0, abs=1e-3) and z.max() == pytest.approx(2.0, abs=1e-3)
    assert z[np.searchsorted(s, 62.5)] == pytest.approx(-2.0, abs=1e-6)  # z down: first a climb
    full = iso8608_road("C", seed=0)
    zf = np.asarray(ev(full, jnp.asarray(s)))
    assert -2.3 < zf.min() < -1.7 and 1.7 < zf.max() < 2.3


def test_rear_wheel_follows_front_with_wheelbase_delay():
    r = iso8608_road("C", seed=5)
    speed, wb = 15.0, 2.4
    t = jnp.linspace(0, 10, 101)
    inputs = jax.jit(lambda t: r.wheel_inputs(t, speed, wb))
    z, dz = inputs(t)
    z_later, dz_later = inputs(t + wb / speed)
    np.testing.assert_allclose(np.asarray(z_later[:, 1]), np.asarray(z[:, 0]), atol=1e-12)
    np.testing.assert_allclose(np.asarray(dz_later[:, 1]), np.asarray(dz[:, 0]), atol=1e-9)
    assert float(z[1, 1]) == 0.0  # t = 0.1 s: the rear wheel has not reached the start yet
    assert float(z[50, 0]) != 0.0
    # time derivative = speed * slope
    _, slope = jax.jit(lambda x: r.zeta_and_slope(x))(speed * t)
    np.testing.assert_allclose(np.asarray(dz[:, 0]), speed * np.asarray(slope), rtol=1e-12)


def test_tabulated_wheel_inputs_match_the_profile():
    r = iso8608_road("D", seed=0)
    wi = r.sampled_wheel_inputs(20.0, 2.0, 5.0, dt=5e-4)
    tq = np.random.default_rng(0).uniform(0, 5, 500)
    exact = jax.jit(lambda t: r.wheel_inputs(t, 20.0, 2.0))
    ze, dze = exact(jnp.asarray(tq))
    zi, dzi = jax.jit(jax.vmap(wi))(jnp.asarray(tq))
    assert float(jnp.max(jnp.abs(ze - zi))) < 1e-7  # Hermite error bound dt^4 |zeta''''| / 384
    assert float(jnp.max(jnp.abs(dze - dzi))) < 1e-3 * float(jnp.max(jnp.abs(dze)))
    # nodes are exact
    z0, d0 = jax.jit(lambda t: wi(t))(jnp.asarray(1.0))
    ze1, de1 = exact(jnp.asarray(1.0))
    np.testing.assert_allclose(np.asarray(z0), np.asarray(ze1), atol=1e-15)
    np.testing.assert_allclose(np.asarray(d0), np.asarray(de1), atol=1e-12)


def test_bad_roads_raise():
    with pytest.raises(ValueError, match="A-H"):
        iso8608_road("Z")
    with pytest.raises(ValueError, match="n_min"):
        iso8608_road("C", n_min=3.0, n_max=1.0)
    with pytest.raises(ValueError, match="empty road"):
        iso8608_road("C", roughness=False, hill_height=0.0)
    with pytest.raises(ValueError, match="n_components"):
        iso8608_road("C", n_components=0)
    with pytest.raises(ValueError, match="speed"):
        iso8608_road("C").sampled_wheel_inputs(0.0, 2.0, 1.0)
    with pytest.raises(ValueError, match="shape"):
        WheelInputs(zeta=np.zeros((10, 2)), dzeta=np.zeros((9, 2)), t0=0.0, dt=0.01)
    with pytest.raises(ValueError, match="shape"):
        WheelInputs(zeta=np.zeros((1, 2)), dzeta=np.zeros((1, 2)), t0=0.0, dt=0.01)
