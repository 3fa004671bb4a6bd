"""A trained context model: windows -> features -> window posteriors -> Markov smoothing -> reject option.

:class:`ContextModel` ties one fitted estimator (Gaussian Bayes, boosted trees or the landmark tree) to the
window settings and feature layout it was trained with, and turns a recording into one decision per window:

1. windows and features (:mod:`classifiers.windows`, :mod:`classifiers.features`);
2. window posteriors ``P(C | z)`` from the estimator; windows whose features are missing (a sensor gap, or
   NaN where the estimator cannot take it) are marked unusable;
3. Markov smoothing (:mod:`classifiers.sequence`): offline forward-backward, online forward filtering, with
   the estimator's posteriors divided by its effective training priors as emission likelihoods; unusable
   windows contribute no evidence;
4. reject option (seed 004 Sec. 4.3, partial classification): the label is ``unknown`` when the smoothed
   posterior of the best class is below ``reject_threshold`` or the window is unusable;
5. in a timeline (:meth:`ContextModel.classify`, the streaming classifier), transition classes hold only next to
   their anchor (:mod:`classifiers.transitions`: car step-in/out next to a vehicle segment).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from classifiers import stairs_direction
from classifiers.baro_stage import log_likelihood as baro_log_likelihood
from classifiers.baro_stage import vertical_speed
from classifiers.features import FEATURE_GROUPS, context_margin_s, extract_features, feature_names
from classifiers.posture import gate_posture, window_gravity
from classifiers.sequence import ForwardFilter, dwell_transitions, forward_backward, scaled_log_likelihood
from classifiers.transitions import gate_transitions
from classifiers.windows import WindowConfig, Windows, make_windows
from pdr.errors import InputError
from pdr.recording import Recording

FloatArray = NDArray[np.float64]

UNKNOWN = "unknown"

#: Estimators whose features must be complete (no NaN) in a window.
_NEEDS_COMPLETE_FEATURES = ("bayes",)


@dataclass(frozen=True)
class WindowResults:
    """Decisions for a sequence of windows.

    Attributes
    ----------
    t_start_s, t_end_s
        (W,) window bounds in seconds on the recording's axis (add ``t0_ns / 1e9`` for the log's clock).
    label
        (W,) class or ``unknown``.
    confidence
        (W,) posterior probability of the reported class (of the best class for ``unknown``).
    proba
        (W, r) smoothed posteriors over ``classes``.
    raw_proba
        (W, r) per-window posteriors before smoothing.
    classes
        Class names of the columns.
    """

    t_start_s: FloatArray
    t_end_s: FloatArray
    label: tuple[str, ...]
    confidence: FloatArray
    proba: FloatArray
    raw_proba: FloatArray
    classes: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.label)

    def rows(self, t0_s: float = 0.0) -> list[dict[str, Any]]:
        """One dict per window (``t_start_s, t_end_s, mode, confidence``), times shifted by ``t0_s``."""
        return [{"t_start_s": float(a + t0_s), "t_end_s": float(b + t0_s), "mode": lab, "confidence": float(c)}
                for a, b, lab, c in zip(self.t_start_s, self.t_end_s, self.label, self.confidence, strict=True)]


@dataclass
class ContextModel:
    """A fitted classifier with everything needed to apply it to a recording.

    Parameters
    ----------
    task
        Task name (:mod:`classifiers.tasks`).
    window
        Window settings used in training (inference must use the same).
    feature_groups
        Feature groups of the estimator's input columns, in order.
    estimator_kind
        ``bayes``, ``xgboost`` or ``landmark_tree``.
    estimator
        The fitted estimator (``predict_proba`` and ``classes_``).
    train_priors
        (r,) class priors the estimator's posteriors carry (training frequencies for Bayes, uniform for
        class-balanced training); divided out for the Markov smoothing.
    mean_dwell_s
        Mean time in one class for the smoothing (s); 0 disables smoothing.
    reject_threshold
        Smoothed posterior below which the label is ``unknown``.
    stairs_direction
        Parameters of the stairs direction stage (:mod:`classifiers.stairs_direction`), or ``None``.
    barometer
        Add the barometric second stage's evidence (:mod:`classifiers.baro_stage`) when a window has
        pressure data (a run-time switch, not stored with the model).
    info
        Training data, metrics and other card entries (JSON-serialisable).
    """

    task: str
    window: WindowConfig
    feature_groups: tuple[str, ...]
    estimator_kind: str
    estimator: Any
    train_priors: FloatArray
    mean_dwell_s: float = 20.0
    reject_threshold: float = 0.5
    info: dict[str, Any] = field(default_factory=dict)
    barometer: bool = True
    stairs_direction: dict[str, Any] | None = None

    @property
    def classes(self) -> tuple[str, ...]:
        return tuple(str(c) for c in self.estimator.classes_)

    @property
    def feature_names(self) -> list[str]:
        return feature_names(self.feature_groups)

    @property
    def required_streams(self) -> tuple[str, ...]:
        """Sensor streams every input recording must have."""
        return tuple(sorted({FEATURE_GROUPS[g][0] for g in self.feature_groups}))

    def transitions(self) -> FloatArray:
        r = len(self.classes)
        if self.mean_dwell_s <= 0:
            return np.full((r, r), 1.0 / r)
        return dwell_transitions(r, self.window.hop_s, self.mean_dwell_s)

    @property
    def margin_s(self) -> float:
        """Seconds of data the context features need beyond each window, on each side."""
        return context_margin_s(self.feature_groups, self.window.length_s)

    def check_recording(self, rec: Recording) -> None:
        """:class:`InputError` naming the missing stream when ``rec`` lacks one the model needs."""
        missing = [s for s in self.required_streams if not rec.has(s)]
        if missing:
            raise InputError(f"the '{self.info.get('name', self.task)}' model needs the {', '.join(missing)} "
                             f"stream(s); the recording has {sorted(rec.streams)}", source=rec.source or None)

    def window_proba(self, X: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        """Per-window posteriors (W, r) and the usable-window mask (W,) for feature rows ``X``."""
        X = np.asarray(X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != len(self.feature_names):
            raise InputError(f"features must have shape (W, {len(self.feature_names)}), got {X.shape}")
        if self.estimator_kind in _NEEDS_COMPLETE_FEATURES:
            usable: NDArray[np.bool_] = np.asarray(np.isfinite(X).all(axis=1), dtype=bool)
        else:
            usable = np.asarray(np.isfinite(X).any(axis=1), dtype=bool)
        r = len(self.classes)
        proba = np.full((X.shape[0], r), 1.0 / r)
        if usable.any():
            proba[usable] = self.estimator.predict_proba(X[usable])
        if self.stairs_direction is not None:
            proba = stairs_direction.apply(proba, X, self.feature_names, self.classes, self.stairs_direction)
        return proba, usable

    def emissions(self, proba: FloatArray, usable: NDArray[np.bool_],
                  speed: tuple[FloatArray, FloatArray] | None = None) -> FloatArray:
        """Emission log-likelihoods for the smoother; unusable windows carry no evidence (zeros).

        ``speed``: the windows' barometric vertical speed and standard error (m/s,
        :func:`classifiers.baro_stage.vertical_speed`); with :attr:`barometer` on, their evidence is added.
        """
        ll = scaled_log_likelihood(proba, self.train_priors)
        ll[~usable] = 0.0
        if speed is not None and self.barometer:
            ll[usable] += baro_log_likelihood(speed[0][usable], speed[1][usable], self.classes)
        return ll

    def window_evidence(self, win: Windows) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
        """Posteriors (W, r), usable mask (W,) and emission log-likelihoods (W, r) of windows, the
        barometric stage's evidence included where they have pressure data.
        """
        raw, usable = self.window_proba(extract_features(win, self.feature_groups))
        return raw, usable, self.emissions(raw, usable, vertical_speed(win))

    def decide(self, smoothed: FloatArray, raw: FloatArray, usable: NDArray[np.bool_],
               t_start_s: FloatArray, t_end_s: FloatArray) -> WindowResults:
        """Labels with the reject option applied."""
        classes = self.classes
        best = np.argmax(smoothed, axis=1) if smoothed.size else np.zeros(0, dtype=int)
        conf = smoothed[np.arange(best.size), best] if smoothed.size else np.zeros(0)
        labels = tuple(UNKNOWN if (not ok or c < self.reject_threshold) else classes[b]
                       for b, c, ok in zip(best, conf, usable, strict=True))
        return WindowResults(np.asarray(t_start_s, np.float64), np.asarray(t_end_s, np.float64), labels,
                             np.asarray(conf, np.float64), smoothed, raw, classes)

    def predict_windows(self, win: Windows) -> WindowResults:
        """Offline decisions for windows of one recording (forward-backward smoothing over the sequence)."""
        raw, usable, ll = self.window_evidence(win)
        if self.mean_dwell_s > 0:
            r = len(self.classes)
            smoothed = forward_backward(ll, self.transitions(), np.full(r, 1.0 / r))
        else:
            smoothed = raw
        return self.decide(smoothed, raw, usable, win.t_start_s, win.t_end_s)

    def classify(self, rec: Recording) -> WindowResults:
        """Offline timeline of a recording: a decision per window, transitions and posture gated (module
        docstring).
        """
        self.check_recording(rec)
        win = make_windows(rec, self.window, margin_s=self.margin_s)
        return self.gated(self.predict_windows(win), window_gravity(win))

    @staticmethod
    def gated(res: WindowResults, gravity: FloatArray | None = None) -> WindowResults:
        """``res`` with transition windows away from their anchor relabelled (:mod:`classifiers.transitions`) and,
        given each window's gravity direction (device frame, :func:`classifiers.posture.window_gravity`),
        ``sitting`` windows of an upright thigh relabelled (:mod:`classifiers.posture`).
        """
        labels, conf = gate_transitions(res.label, res.confidence, res.proba, res.classes, res.t_start_s,
                                        res.t_end_s)
        if gravity is not None:
            labels, conf = gate_posture(labels, conf, res.proba, res.classes, res.t_start_s, res.t_end_s, gravity)
        return replace(res, label=labels, confidence=conf)

    def forward_filter(self) -> ForwardFilter:
        """A fresh online smoother for this model."""
        r = len(self.classes)
        return ForwardFilter(self.transitions(), np.full(r, 1.0 / r))
