"""Online classification as sensor batches arrive (the mode provider of the PDR pipeline and the server).

:class:`StreamingClassifier` keeps the raw samples of the not yet complete window, the index of the next
window and the forward-filter distribution; :meth:`StreamingClassifier.update` takes the next batch (a
:class:`pdr.recording.Recording` on the same log clock), emits one :class:`StreamResult` per window that
the batch completed, and costs time proportional to the batch. The window grid is anchored at the first
accelerometer sample of the session, so the per-window posteriors equal those of an offline pass over the
whole log (``ContextModel.classify``); the offline pass smooths forward-backward, the online one filters
forward (it cannot see the future). Transition classes are gated as offline
(:class:`classifiers.transitions.TransitionGate`): a ``car_step_in`` window waits for its vehicle window.
A model with context features (``ctx_*`` groups) looks
``ContextModel.margin_s`` seconds past each window, so its decisions come that much later.

The state is a JSON-serialisable dict (:meth:`state`, :meth:`from_state`): a session can be resumed in
another process, and pdr/ receives this object by dependency injection without importing classifiers/.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from classifiers.artifacts import load_model
from classifiers.installed import DEFAULT_MODEL, resolve_model_dir
from classifiers.model import ContextModel
from classifiers.posture import PostureGate, window_gravity
from classifiers.transitions import TransitionGate
from classifiers.windows import WINDOW_STREAMS, WindowConfig, make_windows
from pdr.errors import InputError
from pdr.recording import Recording, SensorStream

STATE_VERSION = 1


def shared_model(name_or_path: str) -> ContextModel:
    """The saved model, loaded once per process and file version (resuming a classifier per batch is cheap).

    Models are only read by the classifier, so one instance serves every session.
    """
    path = resolve_model_dir(name_or_path) / "model.json"
    return _load_version(str(path.parent.resolve()), path.stat().st_mtime_ns)


@lru_cache(maxsize=8)
def _load_version(folder: str, _mtime_ns: int) -> ContextModel:
    return load_model(folder)
#: Raw history kept before the next window's start (s): covers the resampler's support and gaps.
_HISTORY_S = 1.0

#: How long (s of accelerometer data) the classifier waits for the first sample of another stream the model needs
#: (a phone that starts its gyroscope a batch late) before it says that the session lacks it.
WAIT_FOR_STREAM_S = 10.0


@dataclass(frozen=True)
class StreamResult:
    """One window's decision.

    Attributes
    ----------
    t_start_s, t_end_s
        Window bounds in seconds on the log's own clock (``t_ns / 1e9``).
    mode
        Filtered class, or ``unknown`` (reject option, missing data).
    confidence
        Filtered posterior of ``mode`` (of the best class for ``unknown``).
    window_mode
        Best class of this window alone (before smoothing).
    proba
        Class -> filtered posterior.
    """

    t_start_s: float
    t_end_s: float
    mode: str
    confidence: float
    window_mode: str
    proba: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        return {"t_start_s": self.t_start_s, "t_end_s": self.t_end_s, "mode": self.mode,
                "confidence": self.confidence, "window_mode": self.window_mode, "proba": self.proba}


class StreamingClassifier:
    """Streaming motion-mode (or any context-task) classifier.

    Parameters
    ----------
    model
        A :class:`~classifiers.model.ContextModel` or the name/path of a saved model (default: the shipped
        motion-mode model).

    Use ``results = clf.update(batch)`` for every batch in time order; ``clf.state()`` gives a JSON-able
    dict from which ``StreamingClassifier.from_state(state)`` continues exactly where it stopped.
    """

    def __init__(self, model: ContextModel | str = DEFAULT_MODEL) -> None:
        self.model = shared_model(model) if isinstance(model, str) else model
        self.model_name = str(self.model.info.get("name", model if isinstance(model, str) else ""))
        self.t0_ns: int | None = None
        self.next_window = 0
        self.buffers: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self.filter = self.model.forward_filter()
        self.gate = TransitionGate()
        self.posture = PostureGate()

    @property
    def window(self) -> WindowConfig:
        return self.model.window

    def _append(self, batch: Recording) -> None:
        for kind in WINDOW_STREAMS:
            if not batch.has(kind):
                continue
            s = batch.stream(kind)
            t, v = s.t_ns, s.values
            if kind in self.buffers:
                bt, bv = self.buffers[kind]
                if bt.size:
                    newer = t > bt[-1]  # drop re-sent or out-of-order samples
                    t, v = t[newer], v[newer]
                t = np.concatenate([bt, t])
                v = np.concatenate([bv, v])
            self.buffers[kind] = (t, v)

    @property
    def waiting(self) -> list[str]:
        """The streams the model needs of which no sample has come yet."""
        return [k for k in self.model.required_streams if k not in self.buffers]

    def update(self, batch: Recording) -> list[StreamResult]:
        """Add a batch; returns the decisions of the windows it completed (possibly none).

        A batch may lack a stream the model needs (a phone that starts a sensor late, a stream sent in a later
        batch): the windows wait for it, and those before its first sample are not classified. :class:`InputError`
        once the session has gone :data:`WAIT_FOR_STREAM_S` seconds without any sample of it, or once it is that far
        behind the accelerometer (it stopped).
        """
        started = self.t0_ns is not None and bool(self.waiting)
        self._append(batch)
        if self.t0_ns is None and "acc" in self.buffers:
            self.t0_ns = int(self.buffers["acc"][0][0])
        if self.t0_ns is None:
            return []
        if self.waiting:
            if float(self.buffers["acc"][0][-1] - self.t0_ns) / 1e9 >= WAIT_FOR_STREAM_S:
                raise self._lacks(self.waiting, f"; the recording has {sorted(self.buffers)}", batch.source)
            return []
        lead = max(int(self.buffers[k][0][-1]) for k in self.model.required_streams)
        behind = [k for k in self.model.required_streams
                  if float(lead - self.buffers[k][0][-1]) / 1e9 > WAIT_FOR_STREAM_S]
        if behind:      # a stream that stopped: the windows would wait (and the others' buffers grow) to the end
            raise self._lacks(behind, f", which stopped more than {WAIT_FOR_STREAM_S:g} s before the others",
                              batch.source)
        if started:     # the last stream came: the first window starts at or after every one's first sample
            first = max(int(self.buffers[k][0][0]) for k in self.model.required_streams)
            self.next_window = max(self.next_window, math.ceil((first - self.t0_ns) / 1e9 / self.window.hop_s))
        return self._emit(final=False, source=batch.source)

    def _lacks(self, streams: list[str], why: str, source: str) -> InputError:
        """The error for streams the model needs that the session lacks (``why`` ends the message)."""
        return InputError(f"the '{self.model.info.get('name', self.model.task)}' model needs the "
                          f"{', '.join(streams)} stream(s){why}", source=source or None)

    def finish(self) -> list[StreamResult]:
        """End of the session: decisions of the windows still waiting for context that will not come.

        Their context spans end at the last sample, as in an offline pass over the whole log. :class:`InputError`
        when a stream the model needs never came.
        """
        if self.t0_ns is None:
            return []
        if self.waiting:
            raise self._lacks(self.waiting, f"; the recording has {sorted(self.buffers)}", "")
        tail = self.posture.push(self.gate.flush()) + self.posture.flush()
        return self._emit(final=True, source="") + [StreamResult(**d) for d in tail]

    def _emit(self, final: bool, source: str) -> list[StreamResult]:
        t0 = self.t0_ns
        if t0 is None:
            return []
        streams = {k: SensorStream(k, t, v) for k, (t, v) in self.buffers.items() if t.size}
        if "acc" not in streams or len(streams["acc"]) < 2:
            return []
        rec = Recording(streams, t0_ns=t0, source=source)
        margin = self.model.margin_s
        win = make_windows(rec, self.window, t_origin_s=0.0, first_window=self.next_window, margin_s=margin)
        # Only windows that every required stream has fully covered (later batches cannot change them).
        limit = min((float(self.buffers[k][0][-1] - t0) / 1e9 for k in self.model.required_streams),
                    default=float("inf"))
        done = win.t_end_s + (0.0 if final else margin) <= limit - 1.0 / self.window.rate_hz
        if not done.any():
            return []
        win = win.select(done)
        gravity = window_gravity(win)
        raw, usable, ll = self.model.window_evidence(win)
        filtered = self.filter.update(ll)
        res = self.model.decide(filtered, raw, usable, win.t_start_s, win.t_end_s)
        self.next_window = int(round(win.t_start_s[-1] / self.window.hop_s)) + 1
        keep_from = int(t0 + (self.next_window * self.window.hop_s - _HISTORY_S - margin) * 1e9)
        for k, (t, v) in list(self.buffers.items()):
            m = t >= keep_from
            self.buffers[k] = (t[m], v[m])
        classes = res.classes
        off = t0 / 1e9
        results = [StreamResult(float(a + off), float(b + off), lab, float(c), classes[int(np.argmax(r))],
                                {cl: float(p) for cl, p in zip(classes, pr, strict=True)})
                   for a, b, lab, c, r, pr in zip(res.t_start_s, res.t_end_s, res.label, res.confidence,
                                                   res.raw_proba, res.proba, strict=True)]
        items = [{**r.to_dict(), "gravity": g.tolist()} for r, g in zip(results, gravity, strict=True)]
        return [StreamResult(**d) for d in self.posture.push(self.gate.push(items))]

    def state(self) -> dict[str, Any]:
        """State for :func:`pdr.state_codec.dumps`: model name, clock origin, next window, filter, sample buffers."""
        return {
            "version": STATE_VERSION, "model": self.model_name, "window": self.window.to_dict(),
            "t0_ns": self.t0_ns, "next_window": self.next_window, "filter": self.filter.state(),
            "gate": self.gate.state(), "posture": self.posture.state(),
            "buffers": {k: {"t_ns": t.copy(), "values": v.copy()} for k, (t, v) in self.buffers.items()},
        }

    @classmethod
    def from_state(cls, state: dict[str, Any], model: ContextModel | None = None) -> StreamingClassifier:
        """Resume from :meth:`state`; ``model`` defaults to loading the model named in the state."""
        try:
            if state["version"] != STATE_VERSION:
                raise InputError(f"state version {state['version']} is not {STATE_VERSION}", field="version")
            clf = cls(model if model is not None else str(state["model"]))
            if WindowConfig.from_dict(state["window"]) != clf.window:
                raise InputError("the state's window settings differ from the model's", field="window")
            clf.t0_ns = None if state["t0_ns"] is None else int(state["t0_ns"])
            clf.next_window = int(state["next_window"])
            clf.filter.set_state(state["filter"])
            if "gate" in state:  # states stored before the gate existed resume with an empty one
                clf.gate = TransitionGate.from_state(state["gate"])
            if "posture" in state:  # states stored before the posture rule resume with an empty one
                clf.posture = PostureGate.from_state(state["posture"])
            for k, b in state["buffers"].items():
                t = np.asarray(b["t_ns"], dtype=np.int64)
                v = np.asarray(b["values"], dtype=np.float64).reshape(t.size, -1)
                clf.buffers[str(k)] = (t, v)
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"not a streaming-classifier state ({exc})", field="state") from None
        return clf
