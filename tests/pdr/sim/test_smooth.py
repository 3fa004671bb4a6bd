import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pdr.sim.smooth import Jet, StepProfile, bump, ringing, smoothstep, smoothstep_integral


def _fd(f, t, h=1e-5):
    return (f(t + h) - f(t - h)) / (2 * h)


def test_smoothstep_ends_and_derivatives():
    x = np.linspace(-0.5, 1.5, 2001) + 1.3e-3  # off the breakpoints (S''' jumps there)
    s, ds, dds = smoothstep(x)
    assert s[0] == 0.0 and s[-1] == 1.0
    np.testing.assert_allclose(ds, _fd(lambda u: smoothstep(u)[0], x), atol=1e-6)
    np.testing.assert_allclose(dds, _fd(lambda u: smoothstep(u)[1], x), atol=1e-5)
    np.testing.assert_allclose(_fd(smoothstep_integral, x), s, atol=1e-6)


def test_bump_is_c2_and_peaks_at_half():
    b, db, ddb = bump(np.array([0.0, 0.5, 1.0]))
    np.testing.assert_allclose(b, [0, 1, 0])
    np.testing.assert_allclose(db[[0, 2]], 0)
    np.testing.assert_allclose(ddb[[0, 2]], 0)
    x = np.linspace(0.01, 0.99, 99)
    np.testing.assert_allclose(bump(x)[1], _fd(lambda u: bump(u)[0], x), atol=1e-6)


def test_step_profile_derivatives_and_integral():
    p = StepProfile.from_levels([0.0, 2.0, 5.0, 6.0], [0.0, 1.3, 0.4], 1.0)
    t = np.linspace(0.0, 6.0, 601) + 1.3e-3  # off the transition ends
    v = p.value(t)
    np.testing.assert_allclose(v.d1, _fd(lambda u: p.value(u).value, t), atol=1e-5)
    np.testing.assert_allclose(v.d2, _fd(lambda u: p.value(u).d1, t), atol=1e-4)
    integ = p.integral(t)
    np.testing.assert_allclose(integ.d1, v.value)
    np.testing.assert_allclose(_fd(lambda u: p.integral(u).value, t[1:-1]), v.value[1:-1], atol=1e-6)
    # centred transitions keep the integral of the sharp levels: 1.3 * 3 + 0.4 * 1
    assert p.integral(np.array([6.0])).value[0] == pytest.approx(1.3 * 3 + 0.4 * 1)


def test_jet_product_and_trig_rules():
    t = np.linspace(0.0, 2.0, 201)
    a = Jet(t**2, 2 * t, 2 * np.ones_like(t))
    b = Jet(np.sin(t), np.cos(t), -np.sin(t))
    prod = a * b
    np.testing.assert_allclose(prod.d2, 2 * np.sin(t) + 4 * t * np.cos(t) - t**2 * np.sin(t))
    c = a.cos()
    np.testing.assert_allclose(c.d2, -np.sin(t**2) * 2 - np.cos(t**2) * 4 * t**2)


def test_ringing_is_c2_and_vanishes_outside():
    x = np.linspace(0.005, 0.995, 199)
    f, df, ddf = ringing(x, 2.5)
    np.testing.assert_allclose(df, _fd(lambda u: ringing(u, 2.5)[0], x), atol=1e-5)
    np.testing.assert_allclose(ddf, _fd(lambda u: ringing(u, 2.5)[1], x), atol=1e-3)
    ends = ringing(np.array([-0.5, 0.0, 1.0, 1.5]), 2.5)
    for part in ends:
        np.testing.assert_allclose(part, 0.0, atol=1e-12)
    assert 0.5 < np.abs(f).max() <= 1.0


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 300))
def test_step_profile_is_the_same_on_any_samples_in_any_order(seed, n):
    # Overlapping transitions, some starting before t = 0; samples sorted, shuffled, or one at a time agree, and the
    # integral is the quadrature of the level.
    rng = np.random.default_rng(seed)
    starts = rng.uniform(-2.0, 50.0, 12)
    p = StepProfile.build(rng.normal(), [(a, a + rng.uniform(0.1, 5.0), rng.normal()) for a in starts])
    t = np.sort(rng.uniform(-1.0, 60.0, n))
    perm = rng.permutation(n)
    for f in (p.value, p.integral):
        whole = f(t)
        shuffled = f(t[perm])
        single = [f(t[i:i + 1]) for i in range(n)]
        for part in ("value", "d1", "d2"):
            np.testing.assert_allclose(getattr(shuffled, part), getattr(whole, part)[perm], rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(np.concatenate([getattr(j, part) for j in single]), getattr(whole, part),
                                       rtol=1e-12, atol=1e-12)
    grid = np.linspace(-1.0, 60.0, 610_001)
    v = p.value(grid).value
    quad = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(grid))])
    quad -= np.interp(0.0, grid, quad)                  # the integral runs from t = 0
    np.testing.assert_allclose(p.integral(t).value, np.interp(t, grid, quad), atol=1e-6)
