"""Online dual-foot fusion (DualFootFusion): any chunking and arrival order equals the whole; agrees with fuse_feet."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from pdr.errors import InputError
from pdr.foot.dual import DualFootConfig, DualFootFusion, DualFootTrack, FusedStep, fuse_feet
from pdr.foot.navigate import navigate
from pdr.foot.zupt import ZuptConfig, ZuptTrack
from pdr.sim import parse_scenario, simulate
from pdr.step_increment import StepIncrement
from tests.pdr.foot.test_dual import _feet


def _increments(track: ZuptTrack, offset_s: float) -> list[StepIncrement]:
    """The track's step increments on the common clock (as the service stores them)."""
    return [replace(s, t_s=float(track.t_s[s.index] + offset_s)) for s in track.steps]


def _walk(seeds: tuple[int, int], mount_yaw_deg: float = 0.0
          ) -> tuple[list[StepIncrement], list[StepIncrement], DualFootTrack, tuple[float, float]]:
    """Both feet's increments, fuse_feet's result and its start times (s, common clock)."""
    left, right = _feet(*seeds, mount_yaw_deg)
    imu_l, tr_l = navigate(left, "stepwise")
    imu_r, tr_r = navigate(right, "stepwise")
    fused = fuse_feet(tr_l, tr_r, imu_l.clock_offset_s, imu_r.clock_offset_s)
    t_start = (float(tr_l.t_s[tr_l.start_index] + imu_l.clock_offset_s),
               float(tr_r.t_s[tr_r.start_index] + imu_r.clock_offset_s))
    return _increments(tr_l, imu_l.clock_offset_s), _increments(tr_r, imu_r.clock_offset_s), fused, t_start


def _run_chunked(make: DualFootFusion, left: list[StepIncrement], right: list[StepIncrement],
                 rng: np.random.Generator) -> tuple[list[FusedStep], DualFootFusion]:
    """Feed random chunks of the two feet in a random interleaving, saving and restoring the state each time."""
    fusion, out = make, []
    queues = [("left", list(left)), ("right", list(right))]
    while any(q for _, q in queues):
        side, q = queues[int(rng.integers(2))]
        n = int(rng.integers(0, 4))
        chunk, q[:] = q[:n], q[n:]
        out += fusion.add_steps(side, chunk)
        fusion = DualFootFusion.from_dict(json.loads(json.dumps(fusion.to_dict())))
    return out + fusion.finish(), fusion


def _whole(fusion: DualFootFusion, left: list[StepIncrement], right: list[StepIncrement]) -> list[FusedStep]:
    return fusion.add_steps("left", left) + fusion.add_steps("right", right) + fusion.finish()


def _same(a: list[FusedStep], b: list[FusedStep]) -> None:
    assert [(u.t_s, u.side, u.constraint_active, u.stride) for u in a] == \
        [(u.t_s, u.side, u.constraint_active, u.stride) for u in b]
    for u, v in zip(a, b, strict=True):
        assert np.array_equal(u.pos_n, v.pos_n) and np.array_equal(u.heading, v.heading)
        assert np.array_equal(u.cov, v.cov) and u.midpoint_shift_m == v.midpoint_shift_m


@pytest.mark.parametrize("seed", [0, 1])
def test_chunks_in_any_interleaving_with_state_round_trips_equal_fuse_feet(seed: int) -> None:
    left, right, fused, t_start = _walk((1, 2))
    # With the batch's alignment and start times, the online object is fuse_feet's update sequence, exactly.
    got, fusion = _run_chunked(DualFootFusion(None, fused.heading_offset_rad, t_start), left, right,
                               np.random.default_rng(seed))
    assert fusion.updates == fused.updates == len(got) == len(left) + len(right)
    assert fusion.constraint_active == fused.constraint_active > 0
    np.testing.assert_array_equal([u.pos_n[0] for u in got if u.side == "left"], fused.left.step_pos_n)
    np.testing.assert_array_equal([u.pos_n[1] for u in got if u.side == "right"], fused.right.step_pos_n)
    np.testing.assert_array_equal([u.cov for u in got if u.side == "right"], fused.right.step_cov)
    # Updates come out in time order; the body is between the feet.
    t = [u.t_s for u in got]
    assert t == sorted(t)
    assert np.all(np.linalg.norm(np.diff([u.pos_n[:, :2] for u in got], axis=1)[:, 0], axis=1) < 1.3)


@pytest.mark.parametrize(("seeds", "mount_yaw_deg"), [((1, 2), 0.0), ((3, 4), 0.0), ((1, 2), 30.0)])
def test_online_alignment_agrees_with_the_batch_alignment(seeds: tuple[int, int], mount_yaw_deg: float) -> None:
    left, right, fused, _ = _walk(seeds, mount_yaw_deg)
    whole = _whole(DualFootFusion(), left, right)
    chunked, fusion = _run_chunked(DualFootFusion(), left, right, np.random.default_rng(7))
    _same(chunked, whole)
    # The relative heading from the first 3 m of resets is the batch one (per-sample positions) within 1 deg,
    # and a turned right shoe is found.
    assert fusion.heading_offset_rad is not None
    assert abs(math.degrees(fusion.heading_offset_rad - fused.heading_offset_rad)) < 1.0
    assert abs(math.degrees(fusion.heading_offset_rad) - mount_yaw_deg) < 3.0
    # Starting the joint state at the first step instead of at the stationary start changes the fused feet by
    # centimetres on a 70 m walk.
    lp = np.array([u.pos_n[0] for u in whole if u.side == "left"])
    rp = np.array([u.pos_n[1] for u in whole if u.side == "right"])
    assert np.max(np.linalg.norm(lp - fused.left.step_pos_n, axis=1)) < 0.1
    assert np.max(np.linalg.norm(rp - fused.right.step_pos_n, axis=1)) < 0.1


def test_steps_are_held_until_both_feet_have_reported() -> None:
    left, right, _, _ = _walk((1, 2))
    fusion = DualFootFusion(heading_offset_rad=0.0)
    assert fusion.add_steps("left", left[:6]) == []           # the right foot may still report older steps
    out = fusion.add_steps("right", right[:1])
    assert [u.t_s for u in out] == sorted(s.t_s for s in left[:6] + right[:1] if s.t_s <= right[0].t_s)
    assert fusion.add_steps("right", []) == []
    rest = fusion.finish()
    assert len(out) + len(rest) == 7 and rest[-1].t_s == max(left[5].t_s, right[0].t_s)


def test_alignment_waits_for_the_distance_and_gives_up_after_max_steps() -> None:
    left, right, _, _ = _walk((1, 2))
    # Never 1 km away: after 3 left steps the fusion starts without turning the right foot.
    fusion = DualFootFusion(DualFootConfig(align_distance_m=1000.0, align_max_steps=3))
    out = fusion.add_steps("left", left[:5]) + fusion.add_steps("right", right[:5])
    assert fusion.aligned and fusion.heading_offset_rad == 0.0
    assert sum(u.side == "left" for u in out) >= 3
    # A short walk ends before the distance: finish() starts it unaligned.
    short = DualFootFusion(DualFootConfig(align_distance_m=1000.0))
    assert short.add_steps("left", left[:4]) + short.add_steps("right", right[:4]) == []
    assert len(short.finish()) == 8 and short.heading_offset_rad == 0.0


def test_a_fused_step_carries_its_increments_stride_flag_also_through_a_saved_state() -> None:
    """The fused track's 'standing' rows come from FusedStep.stride, not from looking the foot rows up by time: the
    flag goes in with the increment, out with its update, and through to_dict/from_dict while the step is held."""
    left, right, _, _ = _walk((1, 2))
    left = [replace(s, stride=k % 3 != 1) for k, s in enumerate(left[:9])]
    right = [replace(s, stride=k % 4 != 2) for k, s in enumerate(right[:9])]
    flags = {("left", s.t_s): s.stride for s in left} | {("right", s.t_s): s.stride for s in right}
    whole = _whole(DualFootFusion(), left, right)
    assert [u.stride for u in whole] == [flags[(u.side, u.t_s)] for u in whole]
    assert {u.stride for u in whole} == {True, False} and len(whole) == len(flags)

    # Saved while steps of both kinds are held (before the alignment) or wait for the other foot.
    fusion = DualFootFusion()
    out = fusion.add_steps("left", left[:6]) + fusion.add_steps("right", right[:3])
    saved = json.loads(json.dumps(fusion.to_dict()))
    waiting = [inc for p in saved["pending"] for inc in p] + [inc for _, inc in saved["held"]]
    assert {inc["stride"] for inc in waiting} == {True, False}
    restored = DualFootFusion.from_dict(saved)
    rest = restored.add_steps("left", left[6:]) + restored.add_steps("right", right[3:]) + restored.finish()
    _same(out + rest, whole)

    # A state saved before the flag was carried reads its waiting steps as strides; the others keep theirs.
    for inc in waiting:
        del inc["stride"]
    old = DualFootFusion.from_dict(saved)
    again = out + old.add_steps("left", left[6:]) + old.add_steps("right", right[3:]) + old.finish()
    was_waiting = {u.t_s for u in whole} - {u.t_s for u in out} - {s.t_s for s in left[6:] + right[3:]}
    assert was_waiting and [u.t_s for u in again] == [u.t_s for u in whole]
    assert [u.stride for u in again] == [u.stride or u.t_s in was_waiting for u in whole]


def test_bad_input_is_refused() -> None:
    left, _, _, _ = _walk((1, 2))
    fusion = DualFootFusion()
    with pytest.raises(InputError, match="side"):
        fusion.add_steps("middle", left[:1])
    fusion.add_steps("left", left[:3])
    with pytest.raises(InputError, match="not after the previous one"):
        fusion.add_steps("left", left[2:3])
    with pytest.raises(InputError, match=r"left\[0\]\.dp"):
        fusion.add_steps("left", [replace(left[3], dp=np.array([np.nan, 0.0, 0.0]))])
    with pytest.raises(InputError, match="malformed dual-foot fusion state"):
        DualFootFusion.from_dict({"config": {}})
    with pytest.raises(InputError, match="align_max_steps"):
        DualFootConfig(align_max_steps=0)


def _midpoint_errors(seed_left: int, seed_right: int) -> tuple[float, float, float]:
    """Mean horizontal errors (m) of the left foot, the right foot (own step-wise tracks, at their resets) and
    the fused walker (midpoint, against the midpoint of the two feet's current footprints) on a 65 s walk.
    """
    segments = [{"type": "stand", "duration_s": 2}, {"type": "walk", "duration_s": 40, "speed_mps": 1.4},
                {"type": "turn", "angle_deg": 90, "duration_s": 2, "speed_mps": 1.0},
                {"type": "walk", "duration_s": 20, "speed_mps": 1.4}, {"type": "stand", "duration_s": 2}]
    recs, tracks, incs = [], [], []
    for side, seed in (("left", seed_left), ("right", seed_right)):
        rec = simulate(parse_scenario({"placement": "foot", "side": side, "rates_hz": {"acc": 200, "gyro": 200},
                                       "sensors": {"grade": "consumer"}, "segments": segments}), seed)
        # Drift elimination off: the test is about the separation constraint averaging the feet's heading drifts.
        imu, tr = navigate(rec, "stepwise", zupt=ZuptConfig(hde_directions=0))
        recs.append(rec)
        tracks.append(tr)
        incs.append(_increments(tr, imu.clock_offset_s))

    def truth(k: int, t: np.ndarray) -> np.ndarray:
        pos = recs[k].truth.positions
        assert pos is not None
        return np.stack([np.interp(t, pos.t_s, pos.pos_m[:, i]) - pos.pos_m[0, i] for i in range(2)], axis=1)

    alone = []
    for k, tr in enumerate(tracks):
        idx = np.array([s.index for s in tr.steps])
        alone.append(float(np.mean(np.linalg.norm(tr.pos_n[idx, :2] - truth(k, tr.t_s[idx]), axis=1))))
    ups = _whole(DualFootFusion(), *incs)
    t = np.array([u.t_s for u in ups])
    footprints = []
    for k, side in enumerate(("left", "right")):
        ft = np.array([u.t_s for u in ups if u.side == side])
        j = np.searchsorted(ft, t, side="right") - 1
        footprints.append(truth(k, np.where(j >= 0, ft[np.maximum(j, 0)], 0.0)))
    mid = np.array([u.midpoint_n[:2] for u in ups])
    return alone[0], alone[1], float(np.mean(np.linalg.norm(mid - 0.5 * (footprints[0] + footprints[1]), axis=1)))


def test_the_fused_walker_beats_the_feet_alone_over_independent_shoes() -> None:
    # Eight walks, each shoe with its own sensor errors (seed): the constraint averages the two heading drifts,
    # so the fused walker is never worse than the worse shoe and, over the walks, better than either shoe.
    errors = np.array([_midpoint_errors(s, s + 1) for s in range(1, 17, 2)])
    assert np.all(errors[:, 2] < errors[:, :2].max(axis=1))
    median = np.median(errors, axis=0)
    assert median[2] < median[0] and median[2] < median[1], median
