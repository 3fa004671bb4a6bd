import numpy as np
import pytest

from pdr.allan import grade
from pdr.allan.filter_params import gm_peak_constants, kalibr_yaml
from pdr.allan.pdr_impact import Walker, bias_impact, human_duration, scale_factor_impact
from pdr.allan.synthetic import gauss_markov, gauss_markov_avar
from pdr.allan.units import to_datasheet
from pdr.errors import InputError

DEG_H = np.deg2rad(1.0) / 3600.0


def _reached(t_s: float | None) -> float:
    """A time the impact analysis must have reached (None means never reached within the horizon)."""
    assert t_s is not None
    return t_s


@pytest.mark.parametrize(
    ("bias_deg_h", "t2", "t3", "t3deg"),
    [(25.0, 5.5 * 60, 8.3 * 60, 7.2 * 60), (1.0, 2.3 * 3600, 3.4 * 3600, 3.0 * 3600)],
)
def test_bias_impact_reproduces_seed_table3(bias_deg_h, t2, t3, t3deg):
    r = bias_impact(bias_deg_h * DEG_H)
    assert r.time_to_rel_error_s[0.02] == pytest.approx(t2, rel=0.02)
    assert r.time_to_rel_error_s[0.03] == pytest.approx(t3, rel=0.02)
    assert r.time_to_heading_error_s == pytest.approx(t3deg, rel=0.01)


@pytest.mark.slow
def test_bias_impact_navigation_grade_days():
    r = bias_impact(0.0035 * DEG_H)
    days = {k: _reached(v) / 86400 for k, v in r.time_to_rel_error_s.items()}
    assert days[0.02] == pytest.approx(27, rel=0.03) and days[0.03] == pytest.approx(41, rel=0.03)
    assert _reached(r.time_to_heading_error_s) / 86400 == pytest.approx(35, rel=0.03)


def test_bias_impact_scales_inversely_and_respects_horizon():
    a = bias_impact(25 * DEG_H)
    b = bias_impact(50 * DEG_H)
    assert b.time_to_rel_error_s[0.02] == pytest.approx(_reached(a.time_to_rel_error_s[0.02]) / 2, rel=0.01)
    short = bias_impact(25 * DEG_H, horizon_s=60.0)
    assert short.time_to_rel_error_s[0.02] is None and short.time_to_heading_error_s is None
    assert human_duration(None) == "not reached" and human_duration(330.0) == "5.5 min"


@pytest.mark.parametrize(("sf_pct", "heading_deg", "rel_pct"),
                         [(1.0, 1.8, 3.14), (0.015, 0.027, 0.047), (0.001, 0.0018, 0.00314)])
def test_scale_factor_impact_reproduces_seed_table4(sf_pct, heading_deg, rel_pct):
    r = scale_factor_impact(sf_pct / 100)
    assert r.heading_error_deg == pytest.approx(heading_deg, rel=0.01)
    assert 100 * r.rel_position_error == pytest.approx(rel_pct, rel=0.01)


def test_walker_validation():
    with pytest.raises(InputError, match="step_length_m"):
        Walker(step_length_m=0.0)
    with pytest.raises(InputError, match="finite"):
        bias_impact(float("nan"))


def test_grade_from_table1():
    assert grade.grade_value("gyro", "bias_instability", 25.0).grade == "consumer"
    assert grade.grade_value("gyro", "bias_instability", 0.08).grade == "tactical"
    assert grade.grade_value("gyro", "bias_instability", 0.004).grade == "navigation"
    assert grade.grade_value("gyro", "bias_instability", 500.0).grade == grade.BELOW
    assert grade.grade_value("acc", "noise_density", 40.0).grade == "tactical"
    calls = [grade.grade_value("gyro", "angular_random_walk", 0.002), grade.grade_value("gyro", "bias_instability", 5)]
    assert grade.worst(calls) == "consumer" and grade.worst([]) is None


def test_datasheet_units():
    # 1 deg/sqrt(h) = pi/180/60 rad/sqrt(s); 1 deg/h = pi/180/3600 rad/s; 1 ug = 9.80665e-6 m/s^2
    assert to_datasheet("gyro", "N", np.deg2rad(1) / 60)["deg/sqrt(h)"] == pytest.approx(1.0)
    assert to_datasheet("gyro", "B", np.deg2rad(1) / 3600)["deg/h"] == pytest.approx(1.0)
    assert to_datasheet("acc", "B", 9.80665e-6)["ug"] == pytest.approx(1.0)
    assert to_datasheet("acc", "N", 1.0)["m/s/sqrt(h)"] == pytest.approx(60.0)
    assert to_datasheet("gyro", "K", None)["deg/h/sqrt(h)"] is None
    with pytest.raises(InputError, match="unknown sensor"):
        to_datasheet("mag", "N", 1.0)


def test_gauss_markov_peak_constants_match_simulation():
    ratio_tau, ratio_dev = gm_peak_constants()
    assert ratio_tau == pytest.approx(1.89, abs=0.01)
    assert ratio_dev == pytest.approx(0.437 * np.sqrt(2), rel=0.01)
    # eq. 3 simulated: stationary variance and analytic AVAR agree with the generator
    rng = np.random.default_rng(4)
    x = gauss_markov(400_000, 10.0, 0.3, 5.0, rng)
    assert x.std() == pytest.approx(0.3, rel=0.05)
    from pdr.allan.estimators import allan_curve

    c = allan_curve(x, 10.0, m=[20, 100, 400])
    np.testing.assert_allclose(c.avar[:, 0], gauss_markov_avar(c.tau_s, 0.3, 5.0), rtol=0.1)


def test_kalibr_yaml_fields():
    g = {"noise_density": 1e-4, "bias_random_walk_density": 2e-6, "bias_random_walk_source": "bound"}
    a = {"noise_density": 2e-3, "bias_random_walk_density": 3e-5, "bias_random_walk_source": "fit"}
    text = kalibr_yaml(g, a, 200.0, source="log.csv")
    fields = dict(line.split("#")[0].split(":", 1) for line in text.splitlines() if line and not line.startswith("#"))
    fields = {k.strip(): v.strip() for k, v in fields.items()}
    assert float(fields["gyroscope_noise_density"]) == pytest.approx(1e-4)
    assert float(fields["accelerometer_random_walk"]) == pytest.approx(3e-5)
    assert float(fields["update_rate"]) == 200.0 and fields["rostopic"] == "/imu0"
    assert "upper bound" in text.splitlines()[-1]
