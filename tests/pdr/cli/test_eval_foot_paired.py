"""``pdr eval foot``: each navigator against the ZUPT-aided INS, trial by trial (issue #5)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import wilcoxon

from pdr.cli.foot import paired_against_zupt


def _result(errors: list[float]) -> dict[str, object]:
    return {"per_trial": [{"file": f"t{i}.mat", "armse_m": e} for i, e in enumerate(errors)]}


def test_paired_comparison_counts_trials_and_tests_the_differences() -> None:
    zupt = [0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.09, 0.10]
    bank = [e - 0.005 for e in zupt[:6]] + [0.12, 0.13]
    out = paired_against_zupt({"zupt": _result(zupt), "filterbank": _result(bank),
                               "zupt/no-hde": _result(zupt), "filterbank/no-hde": _result(zupt)})
    c = out["filterbank vs zupt"]
    d = np.array(bank) - np.array(zupt)
    assert c["trials"] == 8 and c["better"] == 6
    assert c["median_difference_m"] == pytest.approx(float(np.median(d)))
    assert c["wilcoxon_p"] == pytest.approx(float(wilcoxon(d).pvalue))
    # Rows pair only within the same drift-elimination setting; identical errors give no test.
    assert set(out) == {"filterbank vs zupt", "filterbank/no-hde vs zupt/no-hde"}
    same = out["filterbank/no-hde vs zupt/no-hde"]
    assert same["better"] == 0 and same["median_difference_m"] == 0.0 and math.isnan(same["wilcoxon_p"])


def test_paired_comparison_uses_only_the_trials_both_runs_have() -> None:
    out = paired_against_zupt({"zupt": _result([0.05] * 7), "bc": _result([0.04] * 3)})
    c = out["bc vs zupt"]
    assert c["trials"] == 3 and c["better"] == 3 and math.isnan(c["wilcoxon_p"])   # too few for the test
