"""pdr.filters.iir against scipy.signal: the same coefficients, initial states and outputs, to the last bit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from pdr.filters import iir

#: (order, Wn) of the pipeline's filters (step detector at 50 Hz: 3 Hz, reference, gravity; speed 0.5 Hz) and more.
DESIGNS = [(o, w) for o in (1, 2, 3, 4) for w in (0.01, 0.02, 0.06, 0.1, 0.3, 0.5, 0.9)]


@pytest.mark.parametrize(("order", "wn"), DESIGNS)
def test_design_and_steady_state_equal_scipy(order: int, wn: float) -> None:
    b, a = iir.butter_lowpass(order, wn)
    b_ref, a_ref = signal.butter(order, wn)
    assert np.array_equal(b, b_ref) and np.array_equal(a, a_ref)
    assert np.array_equal(iir.lfilter_zi(b, a), signal.lfilter_zi(b_ref, a_ref))


@pytest.mark.parametrize(("order", "wn"), DESIGNS)
def test_filter_equals_scipy_across_calls(order: int, wn: float) -> None:
    rng = np.random.default_rng(order * 100 + int(wn * 100))
    x = 9.81 + 3.0 * rng.normal(size=3000)
    b, a = iir.butter_lowpass(order, wn)
    zi = iir.lfilter_zi(b, a) * x[0]
    y1, z1 = iir.lfilter(b, a, x[:1234], zi)          # two batches, the state carried between them
    y2, z2 = iir.lfilter(b, a, x[1234:], z1)
    y_ref, z_ref = signal.lfilter(b, a, x, zi=zi)
    assert np.array_equal(np.concatenate([y1, y2]), y_ref) and np.array_equal(z2, z_ref)


def test_two_dimensional_first_order_recursion_equals_scipy() -> None:
    """The magnetometer calibration's decaying sums: a (N, 3) input along axis 0, the state broadcast (1, 3)."""
    rng = np.random.default_rng(7)
    x, prev, d = rng.normal(size=(500, 3)), rng.normal(size=3), 0.97
    y, z = iir.lfilter([d], [1.0, -d], x, d * prev[None, :])
    y_ref, z_ref = signal.lfilter([d], [1.0, -d], x, axis=0, zi=d * prev[None, :])
    assert np.array_equal(y, y_ref) and np.array_equal(z, z_ref)


def test_constant_input_from_steady_state_stays_constant() -> None:
    b, a = iir.butter_lowpass(2, 0.12)
    y, _ = iir.lfilter(b, a, np.full(200, 4.0), iir.lfilter_zi(b, a) * 4.0)
    np.testing.assert_allclose(y, 4.0, rtol=1e-13)


def test_bad_arguments_are_named() -> None:
    with pytest.raises(ValueError, match="0 < wn < 1"):
        iir.butter_lowpass(2, 1.0)
    with pytest.raises(ValueError, match="order"):
        iir.butter_lowpass(0, 0.1)
    b, a = iir.butter_lowpass(2, 0.1)
    with pytest.raises(ValueError, match=r"zi must have shape \(2,\)"):
        iir.lfilter(b, a, np.zeros(10), np.zeros(3))
    with pytest.raises(ValueError, match="nonzero coefficient"):
        iir.lfilter_zi(b, [0.0, 0.0])
