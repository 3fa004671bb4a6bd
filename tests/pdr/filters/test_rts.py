"""RTS smoother: equal to the batch least-squares solution of a linear-Gaussian system (analytic truth)."""

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.filters.rts import error_state_rts, rts_smooth


def _system(seed: int = 0, n_steps: int = 40) -> dict[str, np.ndarray]:
    """Constant-velocity model (position, velocity) with position measurements at every other sample."""
    rng = np.random.default_rng(seed)
    dt = 0.1
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]]) * 0.5
    H = np.array([[1.0, 0.0]])
    R = np.array([[0.04]])
    m0, P0 = np.array([0.0, 1.0]), np.diag([0.1, 0.2])
    x = rng.multivariate_normal(m0, P0)
    xs, ys, has = [], [], []
    for k in range(n_steps):
        if k > 0:
            x = F @ x + rng.multivariate_normal(np.zeros(2), Q)
        xs.append(x)
        has.append(k % 2 == 0)
        ys.append(H @ x + rng.normal(0.0, 0.2, 1))
    return {"F": F, "Q": Q, "H": H, "R": R, "m0": m0, "P0": P0, "y": np.array(ys), "has": np.array(has),
            "x": np.array(xs)}


def _kalman(s: dict[str, np.ndarray], feedback: bool) -> dict[str, np.ndarray]:
    """Forward filter; with ``feedback`` as an error-state filter whose estimate is fed into a nominal state."""
    N = s["y"].shape[0]
    F, Q, H, R = s["F"], s["Q"], s["H"], s["R"]
    out = {k: np.zeros((N, 2)) for k in ("xf", "xp", "dx", "nominal")}
    out |= {k: np.zeros((N, 2, 2)) for k in ("Pf", "Pp", "F")}
    x, P = s["m0"].copy(), s["P0"].copy()
    for k in range(N):
        if k > 0:
            x, P = F @ x, F @ P @ F.T + Q
        out["F"][k] = F
        out["xp"][k], out["Pp"][k] = x, P
        if s["has"][k]:
            S = H @ P @ H.T + R
            K = P @ H.T @ np.linalg.inv(S)
            dx = K @ (s["y"][k] - H @ x)
            x = x + dx
            P = (np.eye(2) - K @ H) @ P
            out["dx"][k] = dx
        out["xf"][k], out["Pf"][k] = x, P
    out["nominal"] = out["xf"] if feedback else out["nominal"]
    return out


def _batch(s: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Batch least squares (MAP) over all states at once: mean and the marginal covariances."""
    N, n = s["y"].shape[0], 2
    Qi, Ri, P0i = np.linalg.inv(s["Q"]), np.linalg.inv(s["R"]), np.linalg.inv(s["P0"])
    Lam = np.zeros((N * n, N * n))
    eta = np.zeros(N * n)
    Lam[:n, :n] += P0i
    eta[:n] += P0i @ s["m0"]
    for k in range(1, N):
        # Residual x_k - F x_{k-1} with information Qi.
        A = np.zeros((n, N * n))
        A[:, k * n:(k + 1) * n] = np.eye(n)
        A[:, (k - 1) * n:k * n] = -s["F"]
        Lam += A.T @ Qi @ A
    for k in range(N):
        if s["has"][k]:
            A = np.zeros((1, N * n))
            A[:, k * n:(k + 1) * n] = s["H"]
            Lam += A.T @ Ri @ A
            eta += A.T @ Ri @ s["y"][k]
    cov = np.linalg.inv(Lam)
    mean = cov @ eta
    return mean.reshape(N, n), np.array([cov[k * n:(k + 1) * n, k * n:(k + 1) * n] for k in range(N)])


def test_rts_equals_batch_least_squares() -> None:
    s = _system()
    f = _kalman(s, feedback=False)
    x_s, P_s = rts_smooth(f["xf"], f["Pf"], f["xp"], f["Pp"], f["F"])
    mean, cov = _batch(s)
    np.testing.assert_allclose(x_s, mean, atol=1e-9)
    np.testing.assert_allclose(P_s, cov, atol=1e-10)
    # The last sample is the filter's own; earlier samples gain from the later measurements.
    np.testing.assert_allclose(x_s[-1], f["xf"][-1])
    assert np.all(P_s[:-1, 0, 0] <= f["Pf"][:-1, 0, 0] + 1e-15)
    assert np.mean(P_s[:-1, 1, 1]) < 0.8 * np.mean(f["Pf"][:-1, 1, 1])


def test_error_state_form_equals_direct_form_on_a_linear_system() -> None:
    s = _system(seed=4)
    f = _kalman(s, feedback=True)
    e_s, P_s = error_state_rts(f["Pf"], f["Pp"], f["F"], f["dx"])
    mean, cov = _batch(s)
    np.testing.assert_allclose(f["nominal"] + e_s, mean, atol=1e-9)
    np.testing.assert_allclose(P_s, cov, atol=1e-10)
    # Smoothing reduces the error against the simulated truth.
    err_f = np.mean(np.sum((f["xf"] - s["x"]) ** 2, axis=1))
    err_s = np.mean(np.sum((f["nominal"] + e_s - s["x"]) ** 2, axis=1))
    assert err_s < err_f


def test_bad_shapes_are_refused() -> None:
    s = _system(n_steps=5)
    f = _kalman(s, feedback=False)
    with pytest.raises(InputError, match="expected shape"):
        rts_smooth(f["xf"], f["Pf"][:-1], f["xp"], f["Pp"], f["F"])
    with pytest.raises(InputError, match="finite"):
        rts_smooth(f["xf"] * np.nan, f["Pf"], f["xp"], f["Pp"], f["F"])
    with pytest.raises(InputError, match="expected shape"):
        error_state_rts(f["Pf"], f["Pp"], f["F"], f["dx"][:, 0])
