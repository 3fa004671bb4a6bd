"""Two-fold cross-validation of the learnable parts of the filter bank (seed 002) and belief condensation (seed 000).

Issue #5 asks whether the filter bank and belief condensation beat the plain ZUPT-EKF on the PyShoe VICON trials.
Their learnable parts are fitted as the seeds do, on trials disjoint from the evaluated ones (seed 000 Sec. VI
uses the same 2-fold scheme): the trials (sorted by name, crawling excluded) are split into odd and even ones;
each half is learned on and the other half evaluated, and both halves are reported.

Learned on the training half:

* filter bank: the leaves' accelerometer process noise and the unconstrained mode's ``sigma_nc`` from ZUPT-INS
  runs (:func:`pdr.foot.filterbank.learn_swing_noise`), then the mode transition matrix by maximum likelihood
  (eq. 11a, :func:`pdr.foot.filterbank.learn_transition`: a bounded derivative-free search from the default
  matrix, ``--evaluations`` likelihood evaluations over the first ``--train-seconds`` of each training trial);
* belief condensation: the m-component context mixture by EM from the states of a ZUPT-EKF run
  (Sec. V.C, :func:`pdr.foot.bc.learn_context`).

Run ``python -m pdr.evaluation.foot_crossval /work/shared/data/pyshoe_vicon``.

Measured (issue #5, defaults: 40 evaluations over 15 s of each training trial, ~110-260 s per search on the
shared machine), held-out median ARMSE (m), learn odd/test even | learn even/test odd: ZUPT 0.056 | 0.060;
``speed`` default 0.077 | 0.056, learned noise with default ``Pi`` 0.108 | 0.106, learned noise and ``Pi`` 0.112 |
0.108; ``height`` default 0.132 | 0.044, learned noise 0.125 | 0.055, learned noise and ``Pi`` 0.125 | 0.050. The
learned ``Pi`` moves the held-out figures by -5 to +4 mm; the learned swing noise makes ``speed`` worse on both halves.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.evaluation.foot_metrics import PYSHOE_EXCLUDED, pyshoe_armse
from pdr.foot.bc import BCConfig, context_samples, learn_context, run_bc
from pdr.foot.detectors import detect
from pdr.foot.filterbank import FilterBankConfig, learn_swing_noise, learn_transition, run_filterbank
from pdr.foot.navigate import FootImu, foot_imu
from pdr.foot.zupt import ZuptTrack, run_zupt

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Trial:
    """One PyShoe trial: checked IMU input, detector flags, ZUPT-INS run, VICON truth (m, ENU-like)."""

    name: str
    imu: FootImu
    zero_velocity: NDArray[np.bool_]
    zupt: ZuptTrack
    truth_t_s: Array
    truth_en: Array
    label: NDArray[np.bool_]


def load_trials(root: Path, excluded: frozenset[str] = frozenset(), limit: int = 0) -> list[Trial]:
    """Read the PyShoe trials of ``root`` (sorted by name, ``excluded`` stems left out) and run the ZUPT INS."""
    from pdr.io import read_recording

    out: list[Trial] = []
    for f in sorted(root.glob("*.mat")):
        if f.stem in excluded:
            continue
        rec = read_recording(f)
        truth = rec.truth.positions
        if truth is None:
            continue
        imu = foot_imu(rec)
        zv = detect(imu.acc_b, imu.gyro_b, imu.rate_hz)
        zt = run_zupt(imu.t_s, imu.acc_b, imu.gyro_b, zv, rate_hz=imu.rate_hz)
        label = np.asarray(rec.truth.extra.get("zero_velocity", np.zeros(0, dtype=bool)), dtype=bool)
        out.append(Trial(f.stem, imu, zv, zt, truth.t_s, truth.pos_m[:, :2], label))
        if limit and len(out) >= limit:
            break
    return out


def armse(trial: Trial, t_s: Array, pos_n: Array) -> float:
    """PyShoe ARMSE (m) of a track against the trial's VICON truth."""
    est = np.stack([np.interp(trial.truth_t_s, t_s, pos_n[:, i]) for i in range(2)], axis=1)
    return pyshoe_armse(est, trial.truth_en)


@dataclass(frozen=True)
class Learned:
    """What one training half gave: per variant the learned noise with the default ``Pi`` and with the learned one."""

    filterbank_noise: dict[str, FilterBankConfig]
    filterbank: dict[str, FilterBankConfig]
    bc: BCConfig
    notes: dict[str, Any]


def learn(train: Sequence[Trial], variants: Sequence[str] = ("speed", "height"), evaluations: int = 40,
          train_seconds: float = 15.0, m: int = 4) -> Learned:
    """Fit the filter bank's noise and transition matrix and the BC context on ``train`` (see module doc).

    ``Pi`` is searched with ``evaluations`` likelihood evaluations over the first ``train_seconds`` (s) of each
    training trial (all of it if <= 0), starting from the variant's default matrix at the training rate.
    """
    runs = [(t.imu.t_s, t.zupt.vel_n, t.zupt.q_nb, t.imu.acc_b, t.imu.gyro_b, t.zero_velocity) for t in train]
    swing = learn_swing_noise(runs)
    notes: dict[str, Any] = {"acc_psd": swing.acc_psd, "sigma_nc": swing.sigma_nc, "swings": swing.swings}
    rate = float(np.median([t.imu.rate_hz for t in train]))
    seqs = []
    for t in train:
        n = t.imu.t_s.size if train_seconds <= 0 else int(np.searchsorted(t.imu.t_s, t.imu.t_s[0] + train_seconds))
        seqs.append((t.imu.t_s[:n], t.imu.acc_b[:n], t.imu.gyro_b[:n], t.zero_velocity[:n]))
    notes["train_seconds"] = float(sum(s[0][-1] - s[0][0] for s in seqs))
    fb: dict[str, FilterBankConfig] = {}
    fb_noise: dict[str, FilterBankConfig] = {}
    for variant in variants:
        base = FilterBankConfig(variant=variant, acc_psd=swing.acc_psd, sigma_nc=swing.sigma_nc)
        res = learn_transition(seqs, base, rate_hz=rate, max_evaluations=evaluations,
                               initial=FilterBankConfig(variant=variant).transition_matrix(rate))
        fb_noise[variant] = base
        fb[variant] = replace(base, transition=tuple(map(tuple, res.transition.tolist())),
                              transition_rate_hz=rate)
        notes[f"transition_{variant}"] = np.round(res.transition, 4).tolist()
        notes[f"loglik_{variant}"] = {"initial": round(float(res.log_likelihood[0]), 1),
                                      "best": round(float(res.best_so_far[-1]), 1),
                                      "evaluations": int(res.log_likelihood.size),
                                      "seconds": round(res.seconds, 1)}
    samples = np.concatenate([context_samples(t.zupt.vel_n[t.zupt.start_index:], t.zupt.q_nb[t.zupt.start_index:],
                                              t.imu.acc_b[t.zupt.start_index:], t.imu.gyro_b[t.zupt.start_index:])
                              for t in train])
    ctx = learn_context(samples, m=m)
    notes["context_weights"] = np.round(ctx.weights, 3).tolist()
    notes["context_sds"] = np.round(ctx.sds[:, [0, 2, 3, 5, 6]], 3).tolist()
    return Learned(fb_noise, fb, BCConfig(context=ctx), notes)


def evaluate(test: Sequence[Trial], learned: Learned | None,
             variants: Sequence[str] = ("speed", "height")) -> list[dict[str, float | str]]:
    """ARMSE per test trial of ZUPT, the filter banks (default; learned noise with the default ``Pi``, ``_noise``;
    learned noise and ``Pi``, ``_learned``), expert and learned BC.
    """
    rows: list[dict[str, float | str]] = []
    for tr in test:
        t, f, w, zv = tr.imu.t_s, tr.imu.acc_b, tr.imu.gyro_b, tr.zero_velocity
        row: dict[str, float | str] = {"file": tr.name, "zupt": armse(tr, tr.zupt.t_s, tr.zupt.pos_n)}
        for variant in variants:
            fbt = run_filterbank(t, f, w, zv, FilterBankConfig(variant=variant))
            row[f"fb_{variant}"] = armse(tr, fbt.t_s, fbt.pos_n)
            if learned is not None:
                fbt = run_filterbank(t, f, w, zv, learned.filterbank_noise[variant])
                row[f"fb_{variant}_noise"] = armse(tr, fbt.t_s, fbt.pos_n)
                fbt = run_filterbank(t, f, w, zv, learned.filterbank[variant])
                row[f"fb_{variant}_learned"] = armse(tr, fbt.t_s, fbt.pos_n)
        bct = run_bc(t, f, w, zv, BCConfig())
        row["bc"] = armse(tr, bct.t_s, bct.pos_n)
        if learned is not None:
            bct = run_bc(t, f, w, zv, learned.bc)
            row["bc_learned"] = armse(tr, bct.t_s, bct.pos_n)
        rows.append(row)
    return rows


def summary(rows: Sequence[dict[str, float | str]]) -> dict[str, dict[str, float]]:
    """Per method: median ARMSE (m), trials better than ZUPT, trials over 1 m."""
    keys = [k for k in rows[0] if k != "file"]
    out: dict[str, dict[str, float]] = {}
    for k in keys:
        v = np.array([float(r[k]) for r in rows])
        z = np.array([float(r["zupt"]) for r in rows])
        out[k] = {"median_m": float(np.median(v)), "better_than_zupt": int(np.sum(v < z)),
                  "over_1m": int(np.sum(v > 1.0)), "trials": len(rows)}
    return out


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m pdr.evaluation.foot_crossval", description=__doc__.split("\n")[0])
    p.add_argument("dir", help="pyshoe_vicon folder")
    p.add_argument("--evaluations", type=int, default=40, help="likelihood evaluations of the eq. 11a search")
    p.add_argument("--train-seconds", type=float, default=15.0,
                   help="seconds of each training trial used to learn Pi (<= 0: all)")
    p.add_argument("--components", type=int, default=4, help="BC context components m")
    p.add_argument("--variants", default="speed,height")
    p.add_argument("--json", help="write all figures to this file")
    args = p.parse_args(argv)
    variants = tuple(args.variants.split(","))
    trials = load_trials(Path(args.dir), PYSHOE_EXCLUDED)
    halves = {"odd": trials[0::2], "even": trials[1::2]}        # 1st, 3rd, ... and 2nd, 4th, ... trial
    report: dict[str, Any] = {}
    for name, other in (("odd", "even"), ("even", "odd")):
        learned = learn(halves[name], variants, args.evaluations, args.train_seconds, args.components)
        rows = evaluate(halves[other], learned, variants)
        summ = summary(rows)
        report[f"learn_{name}_test_{other}"] = {"learned": learned.notes, "per_trial": rows, "summary": summ}
        print(f"== learned on {name} trials ({len(halves[name])}), tested on {other} ({len(rows)})")
        print(json.dumps(learned.notes))
        for r in rows:
            print(r["file"], " ".join(f"{k}={float(v):.3f}" for k, v in r.items() if k != "file"), flush=True)
        for k, s in summ.items():
            print(f"  {k:>20}: median {s['median_m']:.3f} m, better than ZUPT {s['better_than_zupt']}/"
                  f"{s['trials']}, over 1 m {s['over_1m']}")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1, default=lambda o: None if isinstance(o, float)
                                              and not math.isfinite(o) else o))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
