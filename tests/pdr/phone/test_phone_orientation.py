"""The phone's own attitude: sign continuity, yaw difference, the gated yaw row, the pipeline's reference
(``attitude_source="phone"``) and ``use_phone_orientation`` on simulated walks with truth and on real logs."""

import math
from dataclasses import replace

import numpy as np
import pytest

from pdr import quaternion as quat
from pdr.errors import InputError
from pdr.frames import heading_deg_to_yaw, wrap_angle
from pdr.io.registry import read_recording
from pdr.phone.attitude import yaw_of_axis
from pdr.phone.phone_orientation import phone_yaw_update, sign_continuous, yaw_difference
from pdr.phone.pipeline import PdrPipeline, PipelineConfig, track_rows
from pdr.recording import SensorStream
from pdr.sim import load_scenario, simulate
from tests.conftest import REPO_ROOT, data_path

SIM = REPO_ROOT / "mobile_logs" / "sim"


def _rz(psi):
    return quat.from_rotvec(np.array([0.0, 0.0, psi]))


def test_sign_continuous_flips_towards_the_predecessor():
    q = quat.normalize(np.array([[1.0, 0.1, 0, 0], [-1.0, -0.12, 0, 0], [-1.0, -0.14, 0, 0], [1.0, 0.16, 0, 0]]))
    out = sign_continuous(q)
    assert np.all(np.einsum("ij,ij->i", out[1:], out[:-1]) > 0)
    np.testing.assert_allclose(np.abs(out), np.abs(q))
    # Against the sample before the batch.
    assert sign_continuous(q[:1], -q[0])[0, 0] < 0


def test_yaw_difference_is_the_rotation_about_up_at_any_tilt():
    tilt = quat.from_rotvec(np.array([0.7, -0.4, 0.0]))      # a tilted device
    q_b = quat.multiply(_rz(0.3), tilt)
    q_a = quat.multiply(_rz(0.3 + 0.5), tilt)
    assert float(yaw_difference(q_a, q_b)) == pytest.approx(0.5, abs=1e-12)
    assert float(yaw_difference(-q_a, q_b)) == pytest.approx(0.5, abs=1e-12)   # sign of q does not matter
    assert float(yaw_difference(q_b, q_a)) == pytest.approx(-0.5, abs=1e-12)
    # Across +/- pi.
    assert float(yaw_difference(_rz(3.0), _rz(-3.0))) == pytest.approx(6.0 - 2 * math.pi, abs=1e-12)


def _yaw_cov(q, sigma):
    g = np.array([-q[3], -q[2], q[1], q[0]])
    return 0.25 * sigma ** 2 * np.outer(g, g) + 1e-8 * np.eye(4)


def test_yaw_row_is_a_kalman_update_and_is_gated():
    q = quat.multiply(_rz(0.2), quat.from_rotvec(np.array([0.3, 0.1, 0.0])))
    sigma, r = math.radians(20), math.radians(10)
    q_phone = quat.multiply(_rz(math.radians(15)), q)          # the phone sees 15 deg more yaw
    q2, p2, used = phone_yaw_update(q, _yaw_cov(q, sigma), q_phone, r * r, 3.0)
    assert used
    gain = sigma ** 2 / (sigma ** 2 + r * r)
    assert float(yaw_difference(q2, q)) == pytest.approx(gain * math.radians(15), rel=1e-2)   # first order
    g = np.array([-q2[3], -q2[2], q2[1], q2[0]])
    assert math.sqrt(4 * g @ p2 @ g) == pytest.approx(math.sqrt(sigma ** 2 * r * r / (sigma ** 2 + r * r)), rel=1e-2)
    # A confident filter refuses a phone heading 60 deg away (3 sigma of the predicted innovation is ~32 deg).
    q_far = quat.multiply(_rz(math.radians(60)), q)
    q3, p3, used = phone_yaw_update(q, _yaw_cov(q, math.radians(5)), q_far, r * r, 3.0)
    assert not used and np.array_equal(q3, q)
    # NaN (no phone sample) is no row.
    assert not phone_yaw_update(q, _yaw_cov(q, sigma), np.full(4, np.nan), r * r, 3.0)[2]


@pytest.fixture(scope="module")
def hand_walk():
    return simulate(load_scenario(SIM / "hand_escalator.json"), 1)


def _with_orientation(rec, q_of_t):
    """``rec`` with an ``orientation`` stream of ``q_of_t(t_s)`` at the trajectory's times, signs alternating."""
    ex = rec.truth.extra
    t = np.asarray(ex["trajectory_t_s"], dtype=np.float64)[::2]
    q = np.asarray(q_of_t(t, np.asarray(ex["q_nb"])[::2]), dtype=np.float64)
    q = q * np.where(np.arange(t.size) % 7 < 3, 1.0, -1.0)[:, None]    # q and -q: the same attitude
    t_ns = rec.origin_ns + np.round(t * 1e9).astype(np.int64)
    return rec.with_streams({"orientation": SensorStream("orientation", t_ns, q)})


def _step_errors(rows, rec):
    """Per step: the heading's error (deg) against the truth's mean device +y yaw over the step."""
    ex = rec.truth.extra
    tt = np.asarray(ex["trajectory_t_s"])
    yaw_y = np.unwrap(yaw_of_axis(np.asarray(ex["q_nb"]), np.array([0.0, 1.0, 0.0])))
    out = []
    for r in rows:
        m = (tt >= r["t_start_s"] - rec.origin_ns / 1e9) & (tt < r["t_s"] - rec.origin_ns / 1e9)
        true = math.atan2(np.sin(yaw_y[m]).mean(), np.cos(yaw_y[m]).mean())
        out.append(math.degrees(abs(float(wrap_angle(heading_deg_to_yaw(r["heading_deg"]) - true)))))
    return np.array(out)


def test_an_orientation_stream_equal_to_the_truth_gives_the_truths_heading(hand_walk):
    rec = _with_orientation(hand_walk, lambda t, q: q)
    cfg = PipelineConfig(placement="hand", drift_elimination=False)
    ours = track_rows(PdrPipeline(cfg).run(rec))
    ref = track_rows(PdrPipeline(replace(cfg, attitude_source="phone")).run(rec))
    # Everything but the attitude is the same: the same steps and lengths.
    assert [r["t_s"] for r in ref] == [r["t_s"] for r in ours]
    e_ref, e_ours = _step_errors(ref, rec), _step_errors(ours, rec)
    assert np.median(e_ref) < 0.5 and e_ref.max() < 2.0
    assert np.median(e_ours) > 2 * np.median(e_ref)          # our filter's own error is seen, not hidden
    # As a yaw measurement of our filter, the true heading brings ours closer to the truth.
    with_phone = PdrPipeline(replace(cfg, use_phone_orientation=True))
    e_with = _step_errors(track_rows(with_phone.run(rec)), rec)
    assert with_phone.phone_yaw_updates > 0
    assert e_with.mean() < e_ours.mean()


def test_a_phone_heading_that_turns_wrong_mid_walk_does_not_drag_ours(hand_walk):
    cfg = PipelineConfig(placement="hand", drift_elimination=False)
    steps = track_rows(PdrPipeline(cfg).run(hand_walk))
    t_wrong = steps[8]["t_s"] - hand_walk.origin_ns / 1e9        # the phone's heading is 70 deg off from here

    def wrong_later(t, q):
        off = np.where(t > t_wrong, math.radians(70), 0.0)
        return np.array([quat.multiply(_rz(o), qi) for o, qi in zip(off, q, strict=True)])

    right = _with_orientation(hand_walk, lambda t, q: q)
    wrong = _with_orientation(hand_walk, wrong_later)
    late = np.array([r["t_start_s"] - hand_walk.origin_ns / 1e9 > t_wrong for r in steps])
    e_right = _step_errors(track_rows(PdrPipeline(replace(cfg, use_phone_orientation=True)).run(right)), right)
    e_wrong = _step_errors(track_rows(PdrPipeline(replace(cfg, use_phone_orientation=True)).run(wrong)), wrong)
    e_ours = _step_errors(steps, hand_walk)
    assert late.sum() > 10
    # The gate keeps the 70 deg error out: no worse than our own heading, about as good as with the right phone.
    assert e_wrong[late].mean() < e_ours[late].mean() + 2.0
    assert e_wrong[late].max() < 20.0
    assert e_wrong[~late].mean() == pytest.approx(e_right[~late].mean(), abs=0.5)   # (the last row is confirmed late)


def test_use_phone_orientation_chunked_equals_one_batch_and_resumes(hand_walk):
    rec = _with_orientation(hand_walk, lambda t, q: q)
    cfg = PipelineConfig(use_phone_orientation=True)
    one = track_rows(PdrPipeline(cfg).run(rec))
    t0, t1 = rec.time_span_s()
    p = PdrPipeline(cfg)
    events = []
    for a, b in zip(np.linspace(t0, t1 + 1, 6)[:-1], np.linspace(t0, t1 + 1, 6)[1:], strict=True):
        events += p.update(rec.slice_time(a, b))
        p = PdrPipeline.from_state(p.state())
    events += p.finish()
    assert track_rows(events) == one


def test_the_phone_source_without_orientation_is_refused_and_the_option_notes_it(hand_walk):
    with pytest.raises(InputError, match="orientation"):
        PdrPipeline(PipelineConfig(attitude_source="phone")).run(hand_walk)
    events = PdrPipeline(PipelineConfig(use_phone_orientation=True)).run(hand_walk)
    assert any(e["type"] == "notice" and "orientation" in e["message"] for e in events)
    assert track_rows(events) == track_rows(PdrPipeline(PipelineConfig()).run(hand_walk))
    with pytest.raises(InputError):
        PipelineConfig(attitude_source="rotation_vector")


def test_real_texting_walk_reference_follows_the_rotation_vector():
    """Tyrex benchmark (Nexus 5, texting): the reference's step heading is the rotation vector's device +y."""
    rec = read_recording(data_path("attitude_smartphones", "android", "Jakob_Nexus5_NoDist_Texting"))
    cfg = PipelineConfig(placement="hand", drift_elimination=False)
    ref = track_rows(PdrPipeline(replace(cfg, attitude_source="phone")).run(rec))
    ours = track_rows(PdrPipeline(cfg).run(rec))
    assert len(ref) == len(ours) > 20
    o = rec.stream("orientation")
    t = o.t_ns / 1e9
    q = sign_continuous(o.values)
    yaw_y = yaw_of_axis(q, np.array([0.0, 1.0, 0.0]))
    errs = []
    for r in ref:
        m = (t >= r["t_start_s"]) & (t < r["t_s"])
        rv = math.atan2(np.sin(yaw_y[m]).mean(), np.cos(yaw_y[m]).mean())
        errs.append(math.degrees(abs(float(wrap_angle(heading_deg_to_yaw(r["heading_deg"]) - rv)))))
    assert np.median(errs) < 1.0
    with_phone = PdrPipeline(replace(cfg, use_phone_orientation=True))
    assert len(track_rows(with_phone.run(rec))) == len(ours)
    assert with_phone.phone_yaw_updates > 0


def test_real_ipin_log_reference_has_our_steps():
    rec = read_recording(data_path("ipin2023_t3", "logfiles", "IPIN2023_T3_TrainingTrial01_repetition01.txt"))
    t0, _ = rec.time_span_s()
    rec = rec.slice_time(t0, t0 + 90.0)
    cfg = PipelineConfig()
    ours = track_rows(PdrPipeline(cfg).run(rec))
    ref = track_rows(PdrPipeline(replace(cfg, attitude_source="phone")).run(rec))
    assert len(ours) > 20
    assert [r["t_s"] for r in ref] == [r["t_s"] for r in ours]
    assert [r["step_length_m"] for r in ref] != [] and any(
        a["heading_deg"] != b["heading_deg"] for a, b in zip(ref, ours, strict=True))
