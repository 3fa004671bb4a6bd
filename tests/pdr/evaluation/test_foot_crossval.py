"""Two-fold cross-validation summary of the foot filters (pdr.evaluation.foot_crossval)."""

from __future__ import annotations

from pdr.evaluation.foot_crossval import summary


def test_summary_counts_wins_over_zupt_and_runaways() -> None:
    rows: list[dict[str, float | str]] = [
        {"file": "a", "zupt": 0.05, "fb": 0.04, "bc": 2.0},
        {"file": "b", "zupt": 0.06, "fb": 0.07, "bc": 0.05},
        {"file": "c", "zupt": 0.04, "fb": 0.03, "bc": 0.09},
    ]
    s = summary(rows)
    assert s["zupt"]["median_m"] == 0.05 and s["zupt"]["better_than_zupt"] == 0
    assert s["fb"]["median_m"] == 0.04 and s["fb"]["better_than_zupt"] == 2 and s["fb"]["over_1m"] == 0
    assert s["bc"]["median_m"] == 0.09 and s["bc"]["better_than_zupt"] == 1 and s["bc"]["over_1m"] == 1
    assert s["bc"]["trials"] == 3


def test_learn_searches_pi_on_the_first_seconds_of_each_training_trial() -> None:
    import numpy as np

    from pdr.evaluation.foot_crossval import Trial, learn
    from pdr.foot.detectors import detect
    from pdr.foot.navigate import FootImu
    from pdr.foot.zupt import run_zupt
    from tests.pdr.foot.gait import simulate_gait

    trials = []
    for seed in (1, 2):
        g = simulate_gait(n_strides=5, sigma_acc=0.02, sigma_gyro=0.002, seed=seed)
        zv = detect(g.acc_b, g.gyro_b, 200.0)
        imu = FootImu(g.t_s, g.acc_b, g.gyro_b, 200.0, 0.0)
        trials.append(Trial(f"sim{seed}", imu, zv, run_zupt(g.t_s, g.acc_b, g.gyro_b, zv), g.t_s, g.pos_n[:, :2],
                            g.stance))
    learned = learn(trials, ("speed",), evaluations=3, train_seconds=3.0, m=2)
    assert abs(learned.notes["train_seconds"] - 2 * 3.0) < 0.02
    assert learned.notes["loglik_speed"]["evaluations"] == 3
    assert learned.notes["loglik_speed"]["best"] >= learned.notes["loglik_speed"]["initial"]
    # The noise-only configuration keeps the default Pi; the learned one keeps Fig. 1a's zeros.
    assert learned.filterbank_noise["speed"].transition is None
    pi = np.array(learned.filterbank["speed"].transition)
    assert pi[2, 0] == 0.0 and pi[0, 2] == 0.0 and learned.filterbank["speed"].transition_rate_hz == 200.0
