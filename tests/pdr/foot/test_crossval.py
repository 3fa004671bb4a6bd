"""Two-fold cross-validation summary of the foot filters (pdr.foot.crossval)."""

from __future__ import annotations

from pdr.foot.crossval import summary


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
