"""True steps from a motion-capture trajectory of the phone (``attitude_smartphones``: no counted steps there).

The walker's body vaults over the stance leg once per step (inverted pendulum), so the phone, on the thigh or in
the hand, rises and falls once per step: :func:`mocap_step_times` finds those rises in the captured height.
Used by ``pdr eval steps`` (:func:`pdr.cli.eval_walks.eval_steps`) and ``tools/walking_steps.py``.
"""

from __future__ import annotations

import numpy as np

from pdr.errors import InputError
from pdr.evaluation.scoring import match_steps
from pdr.recording import Recording

#: Band (Hz) of the phone's vertical oscillation at the step frequency: walking (0.8-2.2 steps/s) and running.
MOCAP_STEP_BAND_HZ = (0.7, 3.0)
#: Rise of the phone (m) that makes a step in :func:`mocap_step_count`: above the motion capture's sub-millimetre noise,
#: below the 1-5 cm vault of a walk.
MOCAP_STEP_RISE_M = 0.002
#: Shortest step (s) of :func:`mocap_step_count` (the plain detector's too).
MOCAP_MIN_STEP_S = 0.3
#: Largest distance (s) between a detected step and the true step it matches (:func:`matched_steps`).
MOCAP_MATCH_S = 0.3


def mocap_step_count(t_s: np.ndarray, pos_m: np.ndarray, rise_m: float = MOCAP_STEP_RISE_M) -> int:
    """True step count from a motion-capture trajectory of the phone: the size of :func:`mocap_step_times`."""
    return int(mocap_step_times(t_s, pos_m, rise_m).size)


def mocap_step_times(t_s: np.ndarray, pos_m: np.ndarray, rise_m: float = MOCAP_STEP_RISE_M) -> np.ndarray:
    """Times (s) of the true steps in a motion-capture trajectory of the phone: one rise and fall of the phone per
    step (module doc); a step's time is the top of its rise.

    The height ``pos_m[:, 2]`` (m, z up) is put on a uniform grid at the capture's median frame rate (hidden frames
    interpolated), band-passed to :data:`MOCAP_STEP_BAND_HZ` (2nd-order Butterworth, forward and backward), and its
    peaks of prominence at least ``rise_m`` (m), at least :data:`MOCAP_MIN_STEP_S` apart, are counted. Standing moves
    the phone by less than ``rise_m`` (no step). Independent of the accelerometer. Checked against the detector where
    it is right (Jakob_Nexus5_NoDist_Texting: 180 of its 186 steps pair up with the 184 found here; the front-pocket
    walks: 160-183 of 175-190; the back pockets 140-213 of 172-228), the detector's steps on the recording's ``t_s``
    axis like the capture's.

    Parameters
    ----------
    t_s
        (K,) frame times (s), increasing.
    pos_m
        (K, 3) phone positions (m), z up; frames with a NaN are left out.
    """
    from scipy import signal

    t = np.asarray(t_s, dtype=np.float64)
    z = np.asarray(pos_m, dtype=np.float64)[:, 2]
    ok = np.isfinite(t) & np.isfinite(z)
    t, z = t[ok], z[ok]
    if t.size < 2:
        return np.zeros(0)
    rate = 1.0 / float(np.median(np.diff(t)))
    lo, hi = MOCAP_STEP_BAND_HZ
    if not hi < 0.5 * rate:
        raise InputError(f"motion capture at {rate:.1f} Hz is too slow for steps up to {hi} Hz",
                         field="t_s", source="motion-capture truth")
    grid = np.arange(t[0], t[-1], 1.0 / rate)
    b, a = signal.butter(2, [lo / (0.5 * rate), hi / (0.5 * rate)], "band")
    if grid.size <= 3 * max(a.size, b.size):
        return np.zeros(0)
    zb = signal.filtfilt(b, a, np.interp(grid, t, z))
    peaks, _ = signal.find_peaks(zb, prominence=rise_m, distance=max(1, int(MOCAP_MIN_STEP_S * rate)))
    return grid[peaks]


def matched_steps(detected_s: np.ndarray, true_s: np.ndarray, tol_s: float = MOCAP_MATCH_S) -> tuple[int, float]:
    """How many detected steps match a true step one to one, and the lag (s) applied
    (:func:`pdr.evaluation.scoring.match_steps`: each detected time, shifted by the median lag to the nearest true step,
    takes the nearest unmatched true step within ``tol_s``).
    """
    hit, _, lag = match_steps(detected_s, true_s, tol_s)
    return int(hit.sum()), lag


def mocap_trajectory(rec: Recording) -> tuple[np.ndarray, np.ndarray] | None:
    """Frame times (K,) s (the recording's ``t_s`` axis) and phone positions (K, 3) m of the recording's motion
    capture within the phone's recording (dense 3-D truth positions), or None if it has none.
    """
    pos = rec.truth.positions
    if pos is None or pos.kind != "dense" or pos.pos_m.ndim != 2 or pos.pos_m.shape[1] != 3:
        return None
    start, end = rec.time_span_s()
    inside = (pos.t_s >= start) & (pos.t_s <= end)
    return pos.t_s[inside], pos.pos_m[inside]


def true_step_count(rec: Recording) -> tuple[int | None, str]:
    """The recording's true step count and where it comes from: counted steps (``''``) or, failing them, the
    phone's motion-capture trajectory within the phone's recording (``'mocap'``, :func:`mocap_step_count`);
    ``(None, '')`` if it has neither.
    """
    if rec.truth.step_count is not None:
        return int(rec.truth.step_count), ""
    trajectory = mocap_trajectory(rec)
    if trajectory is not None:
        return mocap_step_count(*trajectory), "mocap"
    return None, ""
