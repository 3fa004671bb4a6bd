"""Simulated walking looks like real walking: statistics of simulated pocket and hand-held walks fall within
the spread of real subjects carrying the phone the same way (pdr.sim.realism).

Real pocket walks: MobiFall v2 WAL (5 subjects, acc + gyro, free pocket and orientation) and the Oxford
step-counter front-pocket trials (3 people, acc only). Real hand-held walks: IPIN 2023 track 3 training
logs (reading position, acc + gyro) and the Oxford in-hand trials (acc only). The spread of a statistic is
the range of the per-recording medians; every simulated walk (three speeds and step rates covering the
real step rates, both pockets / sides, phone turned arbitrarily) must fall inside it.

Set PDR_REALISM_FIGURE=<png> to also draw the comparison.
"""

import glob
import math
import os

import numpy as np
import pytest

from pdr.io import read_recording
from pdr.sim import simulate
from pdr.sim.realism import NAMES, recording_summary
from tests.conftest import data_path

#: (speed m/s, step frequency Hz) of the simulated walks: slow, normal, brisk.
GAITS = ((1.1, 1.7), (1.3, 1.8), (1.45, 1.9))

#: Statistics compared per placement (step_corr is reported but not asserted: the simulated gait repeats
#: exactly from stride to stride, so its step-to-step correlation sits at the top of the real range).
POCKET_CHECKED = ("step_hz", "norm_p2p", "norm_max", "norm_min", "step_power", "high_power", "vert_std",
                  "horiz_rms", "gyro_pc1", "gyro_pc2", "gyro_pc3", "gyro_peak")
HAND_CHECKED = ("step_hz", "norm_p2p", "norm_max", "norm_min", "step_power", "high_power", "vert_std", "horiz_rms",
                "gyro_pc1", "gyro_pc2", "gyro_pc3", "gyro_peak")


def _sim_walk(placement, side, speed, freq, seed):
    doc = {"placement": placement, "side": side, "mount_rpy_deg": "random" if placement == "trouser_pocket" else None,
           "sensors": {"grade": "consumer"},
           "segments": [{"type": "stand", "duration_s": 2},
                        {"type": "walk", "duration_s": 30, "speed_mps": speed, "step_frequency_hz": freq},
                        {"type": "stand", "duration_s": 2}]}
    if doc["mount_rpy_deg"] is None:
        del doc["mount_rpy_deg"]
    return recording_summary(simulate(doc, seed), 4.0, 31.0)


def _real(paths):
    out = {}
    for p in paths:
        s = recording_summary(read_recording(p))
        if s is not None:
            out[os.path.basename(p.rstrip("/")) if "WAL" not in p else p.split("/")[-3]] = s
    return out


@pytest.fixture(scope="module")
def real_pocket():
    mobifall = sorted(glob.glob(str(data_path("mobifall_v2_pocket") / "sub*" / "ADL" / "WAL")))
    oxford = sorted(glob.glob(str(data_path("oxford_step_counter", "optimisation", "data") / "*_FrontPocket_*")))
    return _real(mobifall + oxford)


@pytest.fixture(scope="module")
def real_hand():
    ipin = sorted(glob.glob(str(data_path("ipin2023_t3", "logfiles") / "*repetition01.txt")))
    oxford = sorted(glob.glob(str(data_path("oxford_step_counter", "optimisation", "data") / "*_Hard_InHand_*")))
    return _real(ipin + oxford)


@pytest.fixture(scope="module")
def sim_pocket():
    return {f"{side} {v} m/s {f} Hz": _sim_walk("trouser_pocket", side, v, f, seed)
            for seed, (side, (v, f)) in enumerate((s, g) for s in ("right", "left") for g in GAITS)}


@pytest.fixture(scope="module")
def sim_hand():
    return {f"{v} m/s {f} Hz": _sim_walk("hand", "right", v, f, seed) for seed, (v, f) in enumerate(GAITS)}


def _spread(real, name):
    vals = np.array([r[name] for r in real.values()])
    vals = vals[np.isfinite(vals)]
    return vals.min(), vals.max(), vals.size


def _check(real, sim, names):
    bad = []
    for name in names:
        lo, hi, count = _spread(real, name)
        assert count >= 4, f"too few real recordings with {name}"
        for label, s in sim.items():
            if not lo <= s[name] <= hi:
                bad.append(f"{name} of sim {label} = {s[name]:.3g} outside real [{lo:.3g}, {hi:.3g}]")
    assert not bad, "\n".join(bad)


def _figure(groups, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, math.ceil(len(NAMES) / 3), figsize=(18, 9))
    for ax, name in zip(axes.flat, NAMES, strict=False):
        for i, (_label, recs, marker) in enumerate(groups):
            vals = [r[name] for r in recs.values()]
            ax.plot(np.full(len(vals), i) + np.linspace(-0.15, 0.15, len(vals)), vals, marker, ms=6)
        ax.set_xticks(range(len(groups)), [g[0] for g in groups], rotation=30, fontsize=8)
        ax.set_title(name)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(NAMES):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


@pytest.mark.data
@pytest.mark.slow
def test_simulated_pocket_walking_lies_within_real_subjects(real_pocket, sim_pocket, real_hand, sim_hand):
    if os.environ.get("PDR_REALISM_FIGURE"):
        _figure([("real pocket", real_pocket, "ko"), ("sim pocket", sim_pocket, "r^"),
                 ("real hand", real_hand, "bo"), ("sim hand", sim_hand, "m^")], os.environ["PDR_REALISM_FIGURE"])
    assert len(real_pocket) >= 8
    _check(real_pocket, sim_pocket, POCKET_CHECKED)
    # heel strikes in a front pocket: peaks of the norm well above 1 g, thigh pitch swinging at 2-4 rad/s
    for s in sim_pocket.values():
        assert 12.0 < s["norm_max"] and 2.0 < s["gyro_peak"] < 4.5


@pytest.mark.data
@pytest.mark.slow
def test_simulated_hand_held_walking_lies_within_real_subjects(real_hand, sim_hand):
    assert len(real_hand) >= 8
    _check(real_hand, sim_hand, HAND_CHECKED)
