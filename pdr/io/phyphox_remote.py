"""phyphox live: the app's remote-access API (a web server on the phone) read batch by batch into recordings.

phyphox ("Allow remote access" in an experiment's menu) serves, below the phone's URL (phyphox.org wiki,
"Remote-interface communication"):

``/config``
    the experiment: ``buffers`` and ``inputs``, each input a sensor ``source`` (``accelerometer``,
    ``linear_acceleration``, ``gyroscope``, ``magnetic_field``, ``pressure``) whose ``outputs`` name the buffers of
    its axes and time (``[{"x": "accX"}, {"y": "accY"}, {"z": "accZ"}, {"t": "acc_time"}]``);
``/get?accX=T|acc_time&...&acc_time=T``
    ``{"buffer": {name: {"buffer": [...], "updateMode": ...}}, "status": {"session", "measuring", ...}}``: the
    values whose time buffer is later than ``T`` (``full`` for all of them);
``/time``
    the START and PAUSE events, ``experimentTime`` (s) with the phone's ``systemTime`` (s since 1970), which put the
    experiment time on the epoch clock as an export's ``meta/time.csv`` does (:func:`pdr.io.phyphox.epoch_ns`);
``/meta``
    the device (``deviceModel``, ...); ``/control?cmd=start|stop|clear`` starts or stops the measurement.

:class:`PhyphoxRemote` asks for what arrived since its last poll and returns it as a :class:`Recording` in the
units and frame of :mod:`pdr.frames` (phyphox reports Android-convention specific force on both platforms, with
gravity in the accelerometer: m/s^2, rad/s, uT, hPa). Fetching is a function of a path (``fetch("/get?...") ->
bytes``), so the HTTP transport (and a test's fake phone) is the caller's.
"""

from __future__ import annotations

import json
import math
import urllib.parse
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pdr.errors import InputError
from pdr.io.phyphox import epoch_ns
from pdr.io.time_order import keep_increasing
from pdr.recording import DeviceInfo, Recording, SensorStream

#: phyphox input source -> stream kind (SI units already: m/s^2 with g, m/s^2, rad/s, uT, hPa).
SOURCE_KINDS: Mapping[str, str] = {"accelerometer": "acc", "linear_acceleration": "lin_acc", "gyroscope": "gyro",
                                   "magnetic_field": "mag", "pressure": "baro"}
_AXES = ("x", "y", "z")

Fetch = Callable[[str], bytes]


@dataclass(frozen=True)
class RemoteStream:
    """One sensor of the experiment: its stream kind and the buffers of its time and value columns."""

    kind: str
    time: str
    values: tuple[str, ...]


def streams_of_config(config: Any, source: str = "/config") -> list[RemoteStream]:
    """The sensors of a ``/config`` answer that give streams; :class:`InputError` when there are none."""
    if not isinstance(config, dict) or not isinstance(config.get("inputs"), list):
        raise InputError("not a phyphox experiment configuration (no 'inputs' list)", source=source, field="inputs")
    out: list[RemoteStream] = []
    for i, entry in enumerate(config["inputs"]):
        kind = SOURCE_KINDS.get(str(entry.get("source", ""))) if isinstance(entry, dict) else None
        if kind is None:
            continue
        outputs: dict[str, str] = {}
        for o in entry.get("outputs") or []:
            if isinstance(o, dict):
                outputs.update({str(k): str(v) for k, v in o.items()})
        others = [v for k, v in outputs.items() if k != "t"]
        # pressure has one output, whatever phyphox calls it; the others one per axis
        names = [others[0] if len(others) == 1 else None] if kind == "baro" else [outputs.get(c) for c in _AXES]
        if "t" not in outputs or any(n is None for n in names):
            raise InputError(f"sensor '{entry.get('source')}' lacks a time or axis buffer (outputs {outputs})",
                             source=source, field=f"inputs[{i}].outputs")
        if kind not in {s.kind for s in out}:
            out.append(RemoteStream(kind, outputs["t"], tuple(str(n) for n in names)))
    if not out:
        raise InputError("the experiment records no accelerometer, gyroscope, magnetometer or pressure sensor "
                         "(use e.g. 'Acceleration (with g)' or a multi-sensor experiment)", source=source,
                         field="inputs")
    return out


def get_path(streams: list[RemoteStream], since: Mapping[str, float | None]) -> str:
    """The ``/get`` request for every stream's values later than ``since[kind]`` (all of them when None)."""
    query: list[tuple[str, str]] = []
    for s in streams:
        t = since.get(s.kind)
        bound = "full" if t is None else repr(float(t))
        query += [(v, bound if t is None else f"{bound}|{s.time}") for v in s.values] + [(s.time, bound)]
    return "/get?" + urllib.parse.urlencode(query, safe="|")


def _json(raw: bytes, source: str) -> Any:
    try:
        return json.loads(raw)
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"not a JSON answer ({exc})", source=source) from None


@dataclass
class PhyphoxRemote:
    """A phone running a phyphox experiment with remote access, read poll by poll.

    Parameters
    ----------
    fetch
        ``fetch(path) -> bytes``: the body of a GET of ``path`` (``/config``, ``/get?...``) below the phone's URL.
    """

    fetch: Fetch
    streams: list[RemoteStream] = field(default_factory=list)
    title: str = ""
    device: DeviceInfo = field(default_factory=DeviceInfo)
    since: dict[str, float | None] = field(default_factory=dict)
    measuring: bool = False
    session: str = ""
    clock: list[tuple[float, int]] | None = None

    def connect(self) -> PhyphoxRemote:
        """Read the experiment (``/config``) and the device (``/meta``, when the app serves it)."""
        config = _json(self.fetch("/config"), "/config")
        self.streams = streams_of_config(config)
        self.title = str(config.get("localTitle") or config.get("title") or "")
        self.since = {s.kind: None for s in self.streams}
        try:
            meta = _json(self.fetch("/meta"), "/meta")
        except (InputError, OSError):  # phyphox before 1.1.8 has no /meta
            meta = {}
        model = str(meta.get("deviceModel", "")) if isinstance(meta, dict) else ""
        self.device = DeviceInfo(platform="unknown", model=model[:200], role="phone")
        return self

    def control(self, cmd: str) -> None:
        """``/control?cmd=start|stop|clear``; :class:`InputError` when the app refuses."""
        answer = _json(self.fetch(f"/control?cmd={urllib.parse.quote(cmd)}"), "/control")
        if not (isinstance(answer, dict) and answer.get("result")):
            raise InputError(f"phyphox refused '{cmd}' ({answer})", source="/control")

    def _update_clock(self) -> None:
        try:
            events = _json(self.fetch("/time"), "/time")
        except (InputError, OSError):  # no /time (phyphox before 1.1.8): experiment time stays relative
            return
        if isinstance(events, list):
            clock = [(float(e["experimentTime"]), int(round(float(e["systemTime"]) * 1e9)))
                     for e in events if isinstance(e, dict) and {"experimentTime", "systemTime"} <= set(e)]
            if clock:
                self.clock = clock

    def poll(self) -> Recording | None:
        """The samples that arrived since the last poll as a :class:`Recording` (None when there are none)."""
        self._update_clock()
        path = get_path(self.streams, self.since)
        answer = _json(self.fetch(path), "/get")
        if not isinstance(answer, dict) or not isinstance(answer.get("buffer"), dict):
            raise InputError("not a phyphox /get answer (no 'buffer' object)", source="/get")
        raw_status = answer.get("status")
        status: dict[str, Any] = raw_status if isinstance(raw_status, dict) else {}
        self.measuring = bool(status.get("measuring", False))
        session = str(status.get("session", ""))
        if self.session and session and session != self.session:  # the experiment was cleared: start over
            self.since = {s.kind: None for s in self.streams}
        self.session = session or self.session
        streams: dict[str, SensorStream] = {}
        warnings: list[str] = []
        for s in self.streams:
            columns = [self._buffer(answer["buffer"], name) for name in (s.time, *s.values)]
            n = min(len(c) for c in columns)
            arr = np.column_stack([c[:n] for c in columns]) if n else np.empty((0, len(columns)))
            arr = arr[np.all(np.isfinite(arr), axis=1)]   # phyphox pads unfilled buffer slots with NaN
            last = self.since.get(s.kind)
            if last is not None:
                arr = arr[arr[:, 0] > last]
            if not len(arr):
                continue
            arr = arr[keep_increasing(arr[:, 0], "/get", s.time, warnings, what=s.kind)]
            self.since[s.kind] = float(arr[-1, 0])
            t_ns = epoch_ns(arr[:, 0], self.clock, s.time)
            streams[s.kind] = SensorStream(s.kind, t_ns, arr[:, 1:])
        if not streams:
            return None
        meta = {"phyphox_session": self.session, "experiment": self.title,
                "clock": "epoch (phyphox /time)" if self.clock else "experiment time (no /time: s from the start)"}
        return Recording(streams, device=self.device, source=f"phyphox {self.title}".strip(), format="phyphox",
                         warnings=tuple(warnings), meta=meta)

    @staticmethod
    def _buffer(buffers: Mapping[str, Any], name: str) -> np.ndarray:
        entry = buffers.get(name)
        values = entry.get("buffer") if isinstance(entry, dict) else None
        if not isinstance(values, list):
            raise InputError(f"buffer '{name}' missing from the answer", source="/get", field=name)
        try:
            return np.array([math.nan if v is None else float(v) for v in values], dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"buffer '{name}' holds non-numeric values", source="/get", field=name) from None
