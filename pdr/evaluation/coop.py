"""Figures of ``pdr eval coop``: the simulations of seed 001 Sec. 5.1, the influence function (Fig. 8), cost.

* :func:`march_experiment`: straight-line march of N agents (Sec. 5.1.1): absolute and relative position RMSE
  against distance (Fig. 10), final RMSE against N with the fitted exponent of ``N^-p`` (Fig. 11; the seed
  reports ``p = 1/2``), and the correlation coefficients of two agents' position errors (Fig. 12).
* :func:`static_experiment`: three static agents and a fourth on a circle (Sec. 5.1.2, Figs. 13-14): the mobile
  agent's RMSE stays bounded, while its dead reckoning alone drifts.
* :func:`influence_function`: the change of the estimated range after a range update as a function of the
  residual, for the robust update (eq. 20) and the Kalman update (Fig. 8).
* :func:`cost_experiment`: communication per agent and the fusion centre's time per update (Sec. 3.4).
"""

from __future__ import annotations

import math
import multiprocessing
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.fusion.centre import AgentCorrection, FusionConfig
from pdr.fusion.ranging import RangeModel, kalman_range_update, range_update, square_lattice
from pdr.fusion.simulation import (
    FEET,
    SimulationConfig,
    StepEvent,
    march_scenario,
    run_scenario,
    start_centre,
    static_circle_scenario,
)
from pdr.fusion.state import FOOT_DIM, FootKey, GlobalState

Array = NDArray[np.float64]


def fit_power_law(n: Array, rmse: Array) -> tuple[float, float]:
    """Least-squares fit of ``rmse = c * n^-p`` in log-log; returns ``(p, c)``."""
    n = np.asarray(n, dtype=np.float64)
    rmse = np.asarray(rmse, dtype=np.float64)
    if n.size < 2 or np.any(n <= 0) or np.any(rmse <= 0):
        raise InputError("a power-law fit needs two or more positive points", field="n")
    slope, intercept = np.polyfit(np.log(n), np.log(rmse), 1)
    return float(-slope), float(math.exp(intercept))


@dataclass(frozen=True)
class MarchResult:
    """Straight-line march figures.

    Attributes
    ----------
    agent_counts
        (K,) numbers of agents N.
    distance_m
        (L+1,) distance walked at each reset of the left feet, m.
    abs_rmse_m
        (K, L+1) absolute position RMSE over runs, agents and feet, m (Fig. 10, blue).
    rel_rmse_m
        (K, L+1) RMSE of the position errors relative to the group's mean error, m (Fig. 10, red).
    exponent
        ``p`` of the fit ``final abs RMSE = c N^-p`` (Fig. 11).
    coefficient_m
        ``c`` of that fit, m.
    correlation_mc
        (L+1, 3) correlation coefficients (x, y, z) of the errors of two agents over the runs (Fig. 12).
    correlation_filter
        (L+1, 3) the same correlation as estimated by the fusion centre's covariance (run average).
    runs
        Monte Carlo runs per N.
    """

    agent_counts: NDArray[np.int64]
    distance_m: Array
    abs_rmse_m: Array
    rel_rmse_m: Array
    exponent: float
    coefficient_m: float
    correlation_mc: Array
    correlation_filter: Array
    runs: int


def _group_errors(result_error: dict[FootKey, Array], agents: tuple[str, ...], n_rows: int) -> Array:
    """(agents, feet, n_rows, 3) errors (the right feet have the same number of resets as the left)."""
    return np.stack([np.stack([result_error[FootKey(a, f)][:n_rows] for f in FEET]) for a in agents])


def _map_runs(fn: Callable[..., Any], args: list[tuple[Any, ...]], workers: int) -> list[Any]:
    """``[fn(*a) for a in args]``, in order, over ``workers`` forked processes (1: in this process).

    Every Monte Carlo run draws from its own seeded generator, so the results do not depend on ``workers``.
    """
    if workers < 1:
        raise InputError(f"workers must be >= 1, got {workers}", field="workers")
    if workers == 1 or len(args) < 2:
        return [fn(*a) for a in args]
    with ProcessPoolExecutor(min(workers, len(args)), mp_context=multiprocessing.get_context("fork")) as pool:
        return list(pool.map(fn, *zip(*args, strict=True)))


def _march_run(n: int, run: int, seed: int, duration_s: float, sim: SimulationConfig, fusion: FusionConfig | None,
               n_rows: int) -> tuple[Array, Array, Array | None, Array | None]:
    """One march run of ``n`` agents: the mean squared absolute and relative position errors over the agents'
    feet per row (L+1,), m^2; for ``n == 2`` also the left feet's position errors (2, L+1, 3), m, navigation frame,
    and the filter's correlation coefficients of their positions per axis (L+1, 3); else None for both.
    """
    rng = np.random.default_rng([seed, n, run])
    scenario = march_scenario(n, duration_s, sim, rng)
    snaps = (np.arange(n_rows, dtype=np.float64) + 0.25) / sim.step_rate_hz if n == 2 else None
    res = run_scenario(scenario, fusion, ranging=n > 1, snapshot_times=snaps)
    e = _group_errors(res.error, scenario.agents, n_rows)      # (N, 2, L+1, 3)
    sq_abs = np.mean(np.sum(e**2, axis=-1), axis=(0, 1))
    rel = e - np.mean(e, axis=(0, 1), keepdims=True)
    sq_rel = np.mean(np.sum(rel**2, axis=-1), axis=(0, 1))
    if n != 2:
        return sq_abs, sq_rel, None, None
    ia = res.centre.state.position_indices(FootKey("a0", "left"))
    ib = res.centre.state.position_indices(FootKey("a1", "left"))
    c = res.snapshots_cov
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = c[:, ia, ib] / np.sqrt(c[:, ia, ia] * c[:, ib, ib])
    return sq_abs, sq_rel, e[:, 0], corr


def march_experiment(agent_counts: tuple[int, ...] = (1, 2, 4, 8), duration_s: float = 200.0, runs: int = 20,
                     seed: int = 0, sim: SimulationConfig | None = None,
                     fusion: FusionConfig | None = None, workers: int = 1) -> MarchResult:
    """Monte Carlo runs of the straight-line march (Sec. 5.1.1) for each number of agents, over ``workers``
    processes.
    """
    sim = sim or SimulationConfig()
    if runs < 2 or not agent_counts:
        raise InputError("the march needs >= 2 runs and at least one group size", field="runs")
    n_rows = int(math.floor(duration_s * sim.step_rate_hz + 1e-9)) + 1
    abs_rmse, rel_rmse = [], []
    corr_mc = np.full((n_rows, 3), np.nan)
    corr_filter = np.full((n_rows, 3), np.nan)
    jobs = [(n, run, seed, duration_s, sim, fusion, n_rows) for n in agent_counts for run in range(runs)]
    results = iter(_map_runs(_march_run, jobs, workers))
    for n in agent_counts:
        sq_abs = np.zeros(n_rows)
        sq_rel = np.zeros(n_rows)
        pair_errors = []
        filter_corr = []
        for _ in range(runs):
            run_abs, run_rel, left_errors, corr = next(results)
            sq_abs += run_abs
            sq_rel += run_rel
            if n == 2:
                pair_errors.append(left_errors)
                filter_corr.append(corr)
        abs_rmse.append(np.sqrt(sq_abs / runs))
        rel_rmse.append(np.sqrt(sq_rel / runs))
        if n == 2:
            pe = np.stack(pair_errors)                                   # (runs, 2, L+1, 3)
            a = pe[:, 0] - pe[:, 0].mean(axis=0)
            b = pe[:, 1] - pe[:, 1].mean(axis=0)
            with np.errstate(invalid="ignore", divide="ignore"):
                corr_mc = np.sum(a * b, axis=0) / np.sqrt(np.sum(a**2, axis=0) * np.sum(b**2, axis=0))
            corr_filter = np.mean(np.stack(filter_corr), axis=0)
    counts = np.asarray(agent_counts, dtype=np.int64)
    abs_arr = np.stack(abs_rmse)
    p, coef = fit_power_law(counts.astype(np.float64), abs_arr[:, -1]) if counts.size >= 2 else (math.nan, math.nan)
    distance = np.arange(n_rows, dtype=np.float64) * sim.step_length_m
    return MarchResult(counts, distance, abs_arr, np.stack(rel_rmse), p, coef, corr_mc, corr_filter, runs)


@dataclass(frozen=True)
class StaticResult:
    """Three static agents and a walker (Sec. 5.1.2).

    Attributes
    ----------
    t_s
        (L+1,) reset times of the walker's left foot, s.
    rmse_m
        (L+1,) RMSE of the walker's feet with ranging, m (Fig. 14).
    rmse_dead_reckoning_m
        (L+1,) the same without ranging (dead reckoning and the separation constraint only), m.
    static_rmse_m
        RMSE of the static agents' feet over the whole run, m.
    runs
        Monte Carlo runs.
    """

    t_s: Array
    rmse_m: Array
    rmse_dead_reckoning_m: Array
    static_rmse_m: float
    runs: int


def _static_run(run: int, seed: int, duration_s: float, sim: SimulationConfig, fusion: FusionConfig | None,
                n_rows: int) -> tuple[Array, Array, Array, float]:
    """One run of the static scenario: the walker's left-foot reset times (L+1,), s; its feet's mean squared
    position errors per row (L+1,) with and without ranging, m^2; the static agents' mean squared position error
    with ranging, m^2.
    """
    scenario = static_circle_scenario(duration_s, sim, np.random.default_rng([seed, run]))
    out: dict[bool, Array] = {}
    sq_static = 0.0
    for ranging in (True, False):
        res = run_scenario(scenario, fusion, ranging=ranging)
        e = np.stack([res.error[FootKey("mobile", f)][:n_rows] for f in FEET])
        out[ranging] = np.mean(np.sum(e**2, axis=-1), axis=0)
        if ranging:
            es = np.concatenate([res.error[FootKey(a, f)] for a in scenario.agents if a != "mobile" for f in FEET])
            sq_static = float(np.mean(np.sum(es**2, axis=-1)))
    return scenario.truth[FootKey("mobile", "left")].t_s, out[True], out[False], sq_static


def static_experiment(duration_s: float = 300.0, runs: int = 20, seed: int = 0, sim: SimulationConfig | None = None,
                      fusion: FusionConfig | None = None, workers: int = 1) -> StaticResult:
    """Monte Carlo runs of the three-static-agents scenario, with and without ranging, over ``workers``
    processes.
    """
    sim = sim or SimulationConfig()
    if runs < 1:
        raise InputError("needs at least one run", field="runs")
    n_rows = int(math.floor(duration_s * sim.step_rate_hz + 1e-9)) + 1
    results = _map_runs(_static_run, [(run, seed, duration_s, sim, fusion, n_rows) for run in range(runs)], workers)
    t = results[0][0]                                            # the same reset times in every run
    sq = np.zeros(n_rows)
    sq_dr = np.zeros(n_rows)
    sq_static = 0.0
    for _, run_sq, run_sq_dr, run_static in results:
        sq += run_sq
        sq_dr += run_sq_dr
        sq_static += run_static
    return StaticResult(t, np.sqrt(sq / runs), np.sqrt(sq_dr / runs), math.sqrt(sq_static / runs), runs)


@dataclass(frozen=True)
class InfluenceResult:
    """Influence functions of Fig. 8: estimated-range change against the range residual.

    Attributes
    ----------
    residual_m
        (R,) ``r~ - ||z_1||``, m.
    prior_variance_m2
        (V,) isotropic prior variances of ``z_1``, m^2.
    robust_m
        (V, R) change of ``||z_1||`` by the sampled update (eq. 20), m.
    kalman_m
        (V, R) change by the Kalman update, m.
    """

    residual_m: Array
    prior_variance_m2: Array
    robust_m: Array
    kalman_m: Array


def influence_function(residual_m: Array | None = None, prior_variance_m2: tuple[float, ...] = (1.0, 0.3),
                       model: RangeModel | None = None, kalman_variance_m2: float = 1.0,
                       range_m: float = 10.0) -> InfluenceResult:
    """Fig. 8: ``||z_1|| = range_m``, ``gamma_r = 2 m``, Cauchy ``sigma_r = 0.5 m``, Kalman variance 1 m^2."""
    model = model or RangeModel(2.0, 0.5)
    res = np.linspace(-8.0, 8.0, 33) if residual_m is None else np.asarray(residual_m, dtype=np.float64)
    robust = np.zeros((len(prior_variance_m2), res.size))
    kalman = np.zeros_like(robust)
    lattice = square_lattice(3)
    a, b = FootKey("a", "ranging"), FootKey("b", "ranging")
    for i, var in enumerate(prior_variance_m2):
        for j, r in enumerate(res):
            for out, robust_update in ((robust, True), (kalman, False)):
                s = GlobalState()
                s.add_foot(a, [range_m, 0.0, 0.0], 0.0, np.diag([var, var, var, 0.0]), 0.0)
                s.add_foot(b, [0.0, 0.0, 0.0], 0.0, np.zeros((FOOT_DIM, FOOT_DIM)), 0.0)
                if robust_update:
                    range_update(s, a, b, range_m + float(r), model, lattice)
                else:
                    kalman_range_update(s, a, b, range_m + float(r), kalman_variance_m2)
                out[i, j] = float(np.linalg.norm(s.position(a) - s.position(b))) - range_m
    return InfluenceResult(res, np.asarray(prior_variance_m2, dtype=np.float64), robust, kalman)


@dataclass(frozen=True)
class CostResult:
    """Communication and computation per group size (Sec. 3.4).

    Attributes
    ----------
    group_sizes
        (G,) numbers of agents.
    uplink_values_per_s
        (G,) numbers sent by each agent per second: 14 per foot step (``dp``, ``dpsi``, 10 covariance
        entries) and its share of the range values.
    downlink_values_per_s
        (G,) correction values received by each agent per second (position and heading per foot step).
    step_update_ms
        (G,) mean fusion-centre time per step update including the separation constraint, ms.
    range_update_ms
        (G,) mean fusion-centre time per range update, ms.
    realtime_factor
        (G,) processing time over simulated time (< 1: keeps up in real time on one core).
    """

    group_sizes: NDArray[np.int64]
    uplink_values_per_s: Array
    downlink_values_per_s: Array
    step_update_ms: Array
    range_update_ms: Array
    realtime_factor: Array


def _wire_values_per_step() -> int:
    """Values a foot sends per step: dp (3), dpsi (1) and the upper triangle of the (4, 4) covariance (10)."""
    return 3 + 1 + FOOT_DIM * (FOOT_DIM + 1) // 2


def cost_experiment(group_sizes: tuple[int, ...] = (2, 8, 32), duration_s: float = 30.0, seed: int = 0,
                    sim: SimulationConfig | None = None, fusion: FusionConfig | None = None) -> CostResult:
    """Time a fusion centre on a march of each group size; count the values exchanged with each agent."""
    sim = sim or SimulationConfig()
    up, down, step_ms, range_ms, factor = [], [], [], [], []
    for n in group_sizes:
        scenario = march_scenario(n, duration_s, sim, np.random.default_rng([seed, n]))
        centre = start_centre(scenario, fusion)
        t_step = t_range = 0.0
        n_step = n_range = 0
        down_values = 0
        for ev in scenario.events(ranging=n > 1):
            t0 = time.perf_counter()
            if isinstance(ev, StepEvent):
                centre.apply_step(ev.agent, ev.foot, ev.increment)
                corr: AgentCorrection = centre.correction(ev.agent)
                t_step += time.perf_counter() - t0
                n_step += 1
                down_values += corr.values_per_foot()
            else:
                centre.apply_range(ev.agent_a, ev.agent_b, ev.measured_m)
                t_range += time.perf_counter() - t0
                n_range += 1
        up.append((n_step * _wire_values_per_step() + n_range * 1) / n / duration_s)
        down.append(down_values / n / duration_s)
        step_ms.append(1e3 * t_step / max(n_step, 1))
        range_ms.append(1e3 * t_range / max(n_range, 1) if n_range else float("nan"))
        factor.append((t_step + t_range) / duration_s)
    return CostResult(np.asarray(group_sizes, dtype=np.int64), np.asarray(up), np.asarray(down),
                      np.asarray(step_ms), np.asarray(range_ms), np.asarray(factor))


def kalman_config(config: FusionConfig | None = None) -> FusionConfig:
    """The same fusion with the Kalman range update instead of the robust one (reference)."""
    return replace(config or FusionConfig(), robust=False)
