"""The project's own formats: a JSON batch (uploads, simulator output) and a folder/zip of CSVs (whole recordings).

Both are documented in ``pdr/io/schemas/README.md``; the batch has a JSON Schema
(``pdr/io/schemas/batch.schema.json``). Units and frames are the project's (:mod:`pdr.frames`), so no
conversion happens here: what is written is exactly what is read back, ``read(write(x)) == x`` including
the ground truth, warnings and metadata (floats are written with Python's shortest round-trip ``repr``).

Folder layout (the zip holds the same members, at its root or under one top folder)::

    meta.json                 format tag "pdr-native/1", device, t0_ns, warnings, meta, file list
    <kind>.csv                one per stream: t_ns,<columns of STREAM_KINDS[kind]>
    truth/positions.csv       t_s,east_m,north_m,up_m,floor   (floor empty where unknown)
    truth/steps.csv           t_s[,length_m]
    truth/modes.csv           t_start_s,t_end_s,label
    truth/landmarks.csv       t_start_s,t_end_s,label
    truth/extra/<name>.npy    any extra truth array (numpy .npy, exact dtype and shape)

Every member may also be gzip-compressed (``acc.csv.gz``). :func:`write` ends every line with a line break, so a
stream CSV whose last line has none (a copy cut off, perhaps mid-number) has that line dropped with a warning.
"""

from __future__ import annotations

import csv
import gzip
import io
import json
import math
import zipfile
from collections.abc import Callable, Mapping
from functools import cache
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pdr.errors import InputError
from pdr.io.bundle import Bundle, is_zip
from pdr.io.csvtable import parse_table
from pdr.io.text import decode_text, head, parse_json, read_bytes
from pdr.io.time_order import keep_increasing
from pdr.recording import STREAM_KINDS, DeviceInfo, GroundTruth, Labels, PositionTruth, Recording, SensorStream

if TYPE_CHECKING:   # jsonschema costs about 0.5 s to import: only when a document is validated
    import jsonschema

FORMAT = "native"
DESCRIPTION = "pdr native: JSON batch (pdr-batch/1) or folder/zip of CSVs with meta.json (pdr-native/1)"

#: Format tag of a JSON batch.
BATCH_FORMAT = "pdr-batch/1"
#: Format tag in ``meta.json`` of a recording folder.
FOLDER_FORMAT = "pdr-native/1"

_EXTRA_DIR = "truth/extra/"
_POSITION_COLUMNS = ("t_s", "east_m", "north_m", "up_m", "floor")
_LABEL_COLUMNS = ("t_start_s", "t_end_s", "label")


# --------------------------------------------------------------------------------------------- JSON batch

@cache
def _schema(name: str) -> dict[str, Any]:
    text = resources.files("pdr.io.schemas").joinpath(name).read_text(encoding="utf-8")
    schema: dict[str, Any] = json.loads(text)
    return schema


def batch_schema() -> dict[str, Any]:
    """The JSON Schema of a ``pdr-batch/1`` document."""
    return _schema("batch.schema.json")


@cache
def _validator(name: str) -> jsonschema.protocols.Validator:
    """Validator for one schema file; ``$ref`` to the other schema file of this package resolves locally."""
    import jsonschema
    from referencing import Registry, Resource
    registry: Registry = Registry().with_resources(
        (_schema(n)["$id"], Resource.from_contents(_schema(n))) for n in ("batch.schema.json", "folder.schema.json"))
    cls = jsonschema.validators.validator_for(_schema(name))
    return cls(_schema(name), registry=registry)


def json_path(parts: Any) -> str:
    """``streams.acc.values[3][1]`` from a sequence of keys and indices (``$`` for the document itself)."""
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "$"


def _short(x: Any, n: int = 80) -> str:
    s = json.dumps(x, default=str) if not isinstance(x, str) else repr(x)
    return s if len(s) <= n else s[: n - 3] + "..."


def validate_batch(obj: Any, *, source: str = "batch") -> None:
    """Check a decoded JSON batch against the schema; :class:`InputError` naming the JSON path of the first error.

    The (pure-Python) schema validation runs on a skeleton in which each stream keeps one sample: its first
    one, or the first malformed one (found by a quick scan) whose index is then put back into the error path.
    So a 100 000-sample batch validates in milliseconds with the schema as the only authority on what is valid.
    """
    if not isinstance(obj, dict):
        raise InputError(f"a batch must be a JSON object, got {type(obj).__name__}", source=source, field="$")
    skeleton = obj
    where: dict[tuple[str, str], int] = {}
    streams = obj.get("streams")
    if isinstance(streams, dict):
        small = {}
        for kind, s in streams.items():
            small[kind] = _stream_skeleton(kind, s, where)
        skeleton = {**obj, "streams": small}
    from jsonschema.exceptions import best_match
    error = best_match(_validator("batch.schema.json").iter_errors(skeleton))
    if error is not None:
        path = list(error.absolute_path)
        if len(path) >= 4 and path[0] == "streams" and (path[1], path[2]) in where and path[3] == 0:
            path[3] = where[(path[1], path[2])]
        raise _schema_error(error, path, source)


def validate_folder_meta(obj: Any, *, source: str = "meta.json") -> None:
    """Check a decoded folder ``meta.json`` against its schema; :class:`InputError` naming the JSON path."""
    if not isinstance(obj, dict):
        raise InputError(f"meta.json must be a JSON object, got {type(obj).__name__}", source=source, field="$")
    from jsonschema.exceptions import best_match
    error = best_match(_validator("folder.schema.json").iter_errors(obj))
    if error is not None:
        raise _schema_error(error, list(error.absolute_path), source)


def _schema_error(error: jsonschema.ValidationError, path: list[Any], source: str) -> InputError:
    msg = error.message
    if "propertyNames" in error.absolute_schema_path:  # a bad key: name it in the path
        path = [*path, error.instance]
    if error.validator in ("type", "enum", "const", "minItems", "maxItems", "required", "additionalProperties",
                           "minProperties", "minimum", "maxLength", "minLength"):
        msg = f"{_short(error.instance)} is invalid: expected {_expectation(error)}"
    return InputError(msg, source=source, field=json_path(path))


def _expectation(error: jsonschema.ValidationError) -> str:
    v, schema = error.validator, error.schema
    value: Any = error.validator_value
    instance: Any = error.instance
    if v == "type":
        return f"type {value}"
    if v in ("enum", "const"):
        return f"one of {value}" if v == "enum" else f"{value!r}"
    if v == "required":
        return f"properties {value} (missing: {[k for k in value if k not in instance]})"
    if v == "additionalProperties":
        allowed = sorted(schema.get("properties", {}) if isinstance(schema, dict) else [])
        extra = sorted(set(instance) - set(allowed)) if isinstance(instance, dict) else []
        return f"only the properties {allowed} (unexpected: {extra})"
    if v in ("minItems", "maxItems"):
        return f"{'at least' if v == 'minItems' else 'at most'} {value} items"
    return f"{v} {value}"


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _stream_skeleton(kind: str, s: Any, where: dict[tuple[str, str], int]) -> Any:
    """The stream reduced to one sample per array: the first malformed one if any (index noted in ``where``)."""
    spec = STREAM_KINDS.get(kind)
    if spec is None or not isinstance(s, dict):
        return s
    out = dict(s)
    t, v = s.get("t_ns"), s.get("values")
    if isinstance(t, list) and t:
        bad_t = next((i for i, x in enumerate(t) if not isinstance(x, int) or isinstance(x, bool)), None)
        if bad_t is None:
            out["t_ns"] = t[:1]
        else:
            out["t_ns"] = [t[bad_t]]
            where[(kind, "t_ns")] = bad_t
    if isinstance(v, list) and v:
        ncol = len(spec.columns)
        bad_v = next((i for i, row in enumerate(v) if not isinstance(row, list) or len(row) != ncol
                      or not all(_is_number(x) for x in row)), None)
        if bad_v is None:
            out["values"] = v[:1]
        else:
            out["values"] = [v[bad_v]]
            where[(kind, "values")] = bad_v
    return out


def batch_to_json(recording: Recording, *, session_id: str | None = None, batch_id: str | None = None) -> dict:
    """A ``pdr-batch/1`` JSON object (plain dicts, lists, ints and floats) holding ``recording``.

    ``session_id`` and ``batch_id`` default to ``recording.meta['session_id']`` / ``['batch_id']``.
    :func:`batch_from_json` gives back an equal recording.
    """
    meta = dict(recording.meta)
    session_id = session_id if session_id is not None else meta.get("session_id")
    batch_id = batch_id if batch_id is not None else meta.get("batch_id")
    meta.pop("session_id", None)
    meta.pop("batch_id", None)
    out: dict[str, Any] = {"format": BATCH_FORMAT}
    if session_id is not None:
        out["session_id"] = str(session_id)
    if batch_id is not None:
        out["batch_id"] = str(batch_id)
    out["device"] = _device_to_json(recording.device)
    out["t0_ns"] = recording.origin_ns
    out["streams"] = {k: {"t_ns": s.t_ns.tolist(), "values": s.values.tolist()} for k, s in recording.streams.items()}
    if not recording.truth.is_empty():
        out["truth"] = _truth_to_json(recording.truth)
    if meta:
        out["meta"] = _jsonable(meta)
    return out


def batch_from_json(obj: dict, *, source: str = "batch") -> Recording:
    """The :class:`Recording` of a decoded ``pdr-batch/1`` JSON object.

    Raises
    ------
    InputError
        Schema violations, mismatched lengths, non-finite values or a broken clock (samples whose time repeats or
        goes back are dropped with a warning, :mod:`pdr.io.time_order`), with
        ``field`` the JSON path of the offending element (e.g. ``streams.acc.values[3][1]``).
    """
    validate_batch(obj, source=source)
    streams = {}
    warnings: list[str] = []
    for kind, s in obj["streams"].items():
        try:
            t = np.array(s["t_ns"], dtype=np.int64) if s["t_ns"] else np.empty(0, dtype=np.int64)
        except OverflowError:
            raise InputError("a timestamp is outside the int64 nanosecond range", source=source,
                             field=f"streams.{kind}.t_ns") from None
        ncol = len(STREAM_KINDS[kind].columns)
        v = np.array(s["values"], dtype=np.float64).reshape(-1, ncol)
        if v.shape[0] != t.size:
            raise InputError(f"{t.size} timestamps but {v.shape[0]} rows of values", source=source,
                             field=f"streams.{kind}.values")
        bad = ~np.isfinite(v)
        if bad.any():
            r, c = np.argwhere(bad)[0]
            raise InputError(f"value {v[r, c]} is not finite", source=source, field=f"streams.{kind}.values[{r}][{c}]")
        keep = keep_increasing(t, source, f"streams.{kind}.t_ns", warnings)
        streams[kind] = SensorStream(kind, t[keep], v[keep])
    if all(len(s) == 0 for s in streams.values()) and obj.get("t0_ns") is None:
        raise InputError("every stream is empty and no t0_ns is given", source=source, field="streams")
    meta = dict(obj.get("meta") or {})
    for key in ("session_id", "batch_id"):
        if obj.get(key) is not None:
            meta[key] = obj[key]
    truth = _truth_from_json(obj["truth"], source) if "truth" in obj else GroundTruth()
    return _recording(streams, _device_from_json(obj.get("device", {}), source), obj.get("t0_ns"), truth, source,
                      tuple(warnings), meta)


def _recording(streams: dict[str, SensorStream], device: DeviceInfo, t0_ns: int | None, truth: GroundTruth,
               source: str, warnings: tuple[str, ...], meta: dict[str, Any]) -> Recording:
    try:
        return Recording(streams, device=device, t0_ns=t0_ns, truth=truth, source=source, format=FORMAT,
                         warnings=warnings, meta=meta)
    except InputError as exc:
        raise InputError(exc.message, source=source, field=exc.field or exc.source) from None


def _device_to_json(d: DeviceInfo) -> dict[str, Any]:
    return {"platform": d.platform, "model": d.model, "role": d.role, "placement": d.placement,
            "device_id": d.device_id}


def _device_from_json(d: Mapping[str, Any], source: str) -> DeviceInfo:
    try:
        return DeviceInfo(**{k: d[k] for k in ("platform", "model", "role", "placement", "device_id") if k in d})
    except InputError as exc:
        raise InputError(exc.message, source=source, field=f"device.{exc.field}") from None


def _nan_to_none(values: np.ndarray) -> list[Any]:
    return [None if (isinstance(x, float) and math.isnan(x)) else x for x in values.tolist()]


def _labels_to_json(lab: Labels) -> dict[str, Any]:
    return {"t_start_s": lab.t_start_s.tolist(), "t_end_s": lab.t_end_s.tolist(), "label": list(lab.label)}


def _extra_dtype(name: str, a: np.ndarray) -> str:
    kinds = {"b": "bool", "i": "int", "u": "int", "f": "float", "U": "str"}
    if a.dtype.kind not in kinds:
        raise InputError(f"truth extra array has unsupported dtype {a.dtype} (bool, int, float or str)",
                         field=f"truth.extra.{name}")
    return kinds[a.dtype.kind]


def _truth_to_json(truth: GroundTruth) -> dict[str, Any]:
    out: dict[str, Any] = {}
    p = truth.positions
    if p is not None:
        assert p.floor is not None  # filled with NaN at construction
        out["positions"] = {"t_s": p.t_s.tolist(), "pos_m": p.pos_m.tolist(), "floor": _nan_to_none(p.floor),
                            "kind": p.kind, "frame": p.frame,
                            "origin_lat_lon_deg": None if p.origin_lat_lon_deg is None
                            else [float(x) for x in p.origin_lat_lon_deg]}
    if truth.step_times_s is not None:
        out["step_times_s"] = truth.step_times_s.tolist()
    if truth.step_count is not None:
        out["step_count"] = int(truth.step_count)
    if truth.step_lengths_m is not None:
        out["step_lengths_m"] = truth.step_lengths_m.tolist()
    if truth.modes is not None:
        out["modes"] = _labels_to_json(truth.modes)
    if truth.landmarks is not None:
        out["landmarks"] = _labels_to_json(truth.landmarks)
    if truth.extra:
        out["extra"] = {}
        for name, a in truth.extra.items():
            dtype = _extra_dtype(name, a)
            flat = a.ravel()
            data = _nan_to_none(flat) if dtype == "float" else flat.tolist()
            out["extra"][name] = {"dtype": dtype, "shape": list(a.shape), "data": data}
    return out


def _truth_from_json(t: Mapping[str, Any], source: str) -> GroundTruth:
    def wrap(field: str, build: Callable[[], Any]) -> Any:
        try:
            return build()
        except InputError as exc:
            where = f"truth.{field}" if field else (exc.source or "truth").replace(" ", ".")
            raise InputError(exc.message, source=source, field=where) from None

    positions = None
    if "positions" in t:
        p = t["positions"]
        floor = None if p.get("floor") is None else np.array([np.nan if f is None else f for f in p["floor"]],
                                                               dtype=np.float64)
        origin = p.get("origin_lat_lon_deg")
        positions = wrap("positions", lambda: PositionTruth(
            np.array(p["t_s"], dtype=np.float64), np.array(p["pos_m"], dtype=np.float64).reshape(-1, 3), floor,
            kind=p.get("kind", "landmark"), frame=p.get("frame", "enu"),
            origin_lat_lon_deg=None if origin is None else (float(origin[0]), float(origin[1]))))
    modes = wrap("modes", lambda: _labels(t["modes"])) if "modes" in t else None
    landmarks = wrap("landmarks", lambda: _labels(t["landmarks"])) if "landmarks" in t else None
    extra = {}
    for name, e in t.get("extra", {}).items():
        extra[name] = _extra_from_json(name, e, source)
    st = t.get("step_times_s")
    sl = t.get("step_lengths_m")
    return wrap("", lambda: GroundTruth(
        positions=positions, step_times_s=None if st is None else np.array(st, dtype=np.float64),
        step_count=t.get("step_count"), step_lengths_m=None if sl is None else np.array(sl, dtype=np.float64),
        modes=modes, landmarks=landmarks, extra=extra))


def _labels(d: Mapping[str, Any]) -> Labels:
    return Labels(np.array(d["t_start_s"], dtype=np.float64), np.array(d["t_end_s"], dtype=np.float64),
                  tuple(d["label"]))


def _extra_from_json(name: str, e: Mapping[str, Any], source: str) -> np.ndarray:
    field = f"truth.extra.{name}.data"
    dtype = {"bool": np.bool_, "int": np.int64, "float": np.float64, "str": np.str_}[e["dtype"]]
    shape = tuple(e["shape"])
    data = e["data"]
    if e["dtype"] == "float":
        data = [np.nan if x is None else x for x in data]
    expected = {"bool": (bool,), "int": (int,), "float": (int, float), "str": (str,)}[e["dtype"]]
    for i, x in enumerate(data):
        if not isinstance(x, expected) or (e["dtype"] in ("int", "float") and isinstance(x, bool)):
            raise InputError(f"{_short(x)} is not of dtype {e['dtype']}", source=source, field=f"{field}[{i}]")
    if math.prod(shape) != len(data):
        raise InputError(f"{len(data)} elements do not fill shape {list(shape)}", source=source, field=field)
    arr: np.ndarray = np.array(data, dtype=dtype) if data else np.empty(0, dtype=dtype)
    return arr.reshape(shape)


def _jsonable(x: Any) -> Any:
    """Metadata made JSON-serialisable (numpy scalars and arrays to Python), or :class:`InputError`."""
    try:
        return json.loads(json.dumps(x, default=_json_default, allow_nan=True))
    except (TypeError, ValueError) as exc:
        raise InputError(f"metadata is not JSON-serialisable ({exc})", field="meta") from None


def _json_default(x: Any) -> Any:
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, tuple | set | frozenset):
        return list(x)
    raise TypeError(f"{type(x).__name__} is not JSON-serialisable")


# --------------------------------------------------------------------------------------------- folder / zip

def _fmt(x: float) -> str:
    return repr(x)


def _csv_lines(header: list[str], columns: list[list[str]]) -> str:
    rows = [",".join(header)]
    rows.extend(",".join(r) for r in zip(*columns, strict=True))
    return "\n".join(rows) + "\n"


def _stream_csv(s: SensorStream) -> str:
    cols = [[str(t) for t in s.t_ns.tolist()]]
    cols += [list(map(_fmt, s.values[:, j].tolist())) for j in range(s.values.shape[1])]
    return _csv_lines(["t_ns", *s.spec.columns], cols)


def _labels_csv(lab: Labels) -> str:
    """Label intervals as CSV; labels always quoted (they may hold commas, quotes and line breaks)."""
    rows = [",".join(_LABEL_COLUMNS)]
    for a, b, name in zip(lab.t_start_s.tolist(), lab.t_end_s.tolist(), lab.label, strict=True):
        quoted = '"' + name.replace('"', '""') + '"'
        rows.append(f"{_fmt(a)},{_fmt(b)},{quoted}")
    return "\n".join(rows) + "\n"


def _npy_bytes(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()


def _members(recording: Recording) -> dict[str, bytes]:
    """File name -> content of the native folder of ``recording``."""
    files: dict[str, bytes] = {}
    for kind, s in recording.streams.items():
        files[f"{kind}.csv"] = _stream_csv(s).encode()
    truth = recording.truth
    truth_meta: dict[str, Any] = {}
    p = truth.positions
    if p is not None:
        assert p.floor is not None
        floor = ["" if math.isnan(f) else _fmt(f) for f in p.floor.tolist()]
        cols = [list(map(_fmt, p.t_s.tolist()))] + [list(map(_fmt, p.pos_m[:, j].tolist())) for j in range(3)]
        files["truth/positions.csv"] = _csv_lines(list(_POSITION_COLUMNS), [*cols, floor]).encode()
        truth_meta["positions"] = {"file": "truth/positions.csv", "kind": p.kind, "frame": p.frame,
                                   "origin_lat_lon_deg": None if p.origin_lat_lon_deg is None
                                   else [float(x) for x in p.origin_lat_lon_deg]}
    if truth.step_times_s is not None:
        cols = [list(map(_fmt, truth.step_times_s.tolist()))]
        header = ["t_s"]
        if truth.step_lengths_m is not None:
            cols.append(list(map(_fmt, truth.step_lengths_m.tolist())))
            header.append("length_m")
        files["truth/steps.csv"] = _csv_lines(header, cols).encode()
        truth_meta["steps"] = {"file": "truth/steps.csv"}
    if truth.step_count is not None:
        truth_meta["step_count"] = int(truth.step_count)
    for name, lab in (("modes", truth.modes), ("landmarks", truth.landmarks)):
        if lab is not None:
            files[f"truth/{name}.csv"] = _labels_csv(lab).encode()
            truth_meta[name] = {"file": f"truth/{name}.csv"}
    if truth.extra:
        truth_meta["extra"] = {}
        for i, (name, a) in enumerate(truth.extra.items()):
            _extra_dtype(name, a)
            fname = f"{_EXTRA_DIR}{i:03d}.npy"  # names may hold any character: the file is numbered
            files[fname] = _npy_bytes(a)
            truth_meta["extra"][name] = {"file": fname}
    meta = {
        "format": FOLDER_FORMAT,
        "device": _device_to_json(recording.device),
        "t0_ns": recording.origin_ns,
        "streams": {k: f"{k}.csv" for k in recording.streams},
        "truth": truth_meta,
        "warnings": list(recording.warnings),
        "meta": _jsonable(dict(recording.meta)),
        "origin": {"format": recording.format, "source": recording.source},
    }
    files["meta.json"] = (json.dumps(meta, indent=1, ensure_ascii=False) + "\n").encode()
    return files


def write(recording: Recording, path: str | Path) -> Path:
    """Write ``recording`` as a native folder, or a zip of it when ``path`` ends in ``.zip``; returns the path.

    An existing folder is written into (its other files are left alone); an existing zip is replaced.
    """
    p = Path(path)
    files = _members(recording)
    if p.suffix.lower() == ".zip":
        p.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(p, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for name, data in files.items():
                zf.writestr(name, data)
        return p
    for name, data in files.items():
        target = p / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
    return p


def write_batch(recording: Recording, path: str | Path, *, session_id: str | None = None,
                batch_id: str | None = None) -> Path:
    """Write ``recording`` as a ``pdr-batch/1`` JSON file (gzip-compressed when ``path`` ends in ``.gz``)."""
    p = Path(path)
    data = json.dumps(batch_to_json(recording, session_id=session_id, batch_id=batch_id)).encode()
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_bytes(gzip.compress(data) if p.name.endswith(".gz") else data)
    return p


def _load_json(text: str, source: str) -> Any:
    return parse_json(text, source)


def sniff(path: str | Path) -> bool:
    """A folder or zip with a ``meta.json`` tagged ``pdr-native/1``, or a JSON file tagged ``pdr-batch/1``."""
    try:
        p = Path(path)
        if p.is_dir():
            meta = p / "meta.json"
            return meta.is_file() and FOLDER_FORMAT.encode() in head(meta)
        if not p.is_file():
            return False
        name = p.name.lower()
        if name.endswith(".zip") or is_zip(p):
            with zipfile.ZipFile(p) as zf:
                metas = sorted((n for n in zf.namelist() if n.rsplit("/", 1)[-1] == "meta.json"), key=len)
                return bool(metas) and FOLDER_FORMAT.encode() in zf.read(metas[0])[:4096]
        start = head(p).lstrip()
        return start[:1] == b"{" and BATCH_FORMAT.encode() in start
    except Exception:  # noqa: BLE001 - sniffing must never raise on foreign input
        return False


def near_miss(path: str | Path) -> str | None:
    """Why a folder or zip of native stream CSVs (``acc.csv`` ... whose header starts ``t_ns,``) is not read as a
    native recording, or None: its ``meta.json`` is missing or not tagged ``pdr-native/1``.
    """
    p = Path(path)
    try:
        if not (p.is_dir() or (p.is_file() and is_zip(p))):
            return None
        members = Bundle(p, anchor="meta.json")
        streams = [f"{kind}.csv" for kind in STREAM_KINDS if members.head(f"{kind}.csv", 5) == b"t_ns,"]
        if not streams:
            return None
        meta = members.head("meta.json")
    except (OSError, InputError):
        return None
    what = f"a pdr native recording ({', '.join(streams)}: t_ns columns)"
    container = "zip" if p.is_file() else "folder"
    if not meta:
        return (f"{what} whose {container} has no meta.json, which tags it {FOLDER_FORMAT} and holds its device "
                "and t0_ns")
    return f"{what} whose meta.json is not tagged \"format\": \"{FOLDER_FORMAT}\""


def read(path: str | Path) -> Recording:
    """Read a native folder, zip of it, or ``pdr-batch/1`` JSON file (plain or ``.gz``)."""
    p = Path(path)
    if p.is_file() and not (p.name.lower().endswith(".zip") or is_zip(p)):
        text = decode_text(read_bytes(p), str(p))
        return batch_from_json(_load_json(text, str(p)), source=str(p))
    members = Bundle(p, anchor="meta.json")
    meta_name = members.name("meta.json")
    meta = _load_json(members.text("meta.json"), meta_name)
    if not isinstance(meta, dict) or meta.get("format") != FOLDER_FORMAT:
        raise InputError(f"not a native recording: expected \"format\": \"{FOLDER_FORMAT}\"", source=meta_name,
                         field="format")
    validate_folder_meta(meta, source=meta_name)
    warnings = list(meta.get("warnings") or ())
    streams = {kind: _read_stream(members, kind, fname, warnings) for kind, fname in meta["streams"].items()}
    truth = _read_truth(members, meta.get("truth") or {}, meta_name)
    return _recording(streams, _device_from_json(meta.get("device") or {}, meta_name), meta.get("t0_ns"), truth,
                      str(p), tuple(warnings), dict(meta.get("meta") or {}))


def _read_stream(members: Bundle, kind: str, fname: str, warnings: list[str]) -> SensorStream:
    source = members.name(fname)
    cols = STREAM_KINDS[kind].columns
    table = parse_table(members.text(fname), source, int_columns=("t_ns",), notes=warnings, terminated=True)
    expected = ("t_ns", *cols)
    if table.header != expected:
        raise InputError(f"header must be {','.join(expected)}, found {','.join(table.header)}", source=source,
                         line=1)
    keep = table.keep_increasing("t_ns", warnings)
    return SensorStream(kind, table.column("t_ns")[keep], table.stack(cols)[keep])


def _read_truth(members: Bundle, tm: Mapping[str, Any], meta_name: str) -> GroundTruth:
    positions = None
    if "positions" in tm:
        pm = tm["positions"]
        source = members.name(pm["file"])
        table = parse_table(members.text(pm["file"]), source, nan_columns=("floor",))
        origin = pm.get("origin_lat_lon_deg")
        positions = PositionTruth(table.column("t_s"), table.stack(("east_m", "north_m", "up_m")),
                                  table.column("floor"), kind=pm.get("kind", "landmark"),
                                  frame=pm.get("frame", "enu"),
                                  origin_lat_lon_deg=None if origin is None else (float(origin[0]), float(origin[1])))
    step_times = step_lengths = None
    if "steps" in tm:
        fname = tm["steps"]["file"]
        table = parse_table(members.text(fname), members.name(fname))
        step_times = table.column("t_s")
        if "length_m" in table.header:
            step_lengths = table.column("length_m")
    labels = {}
    for name in ("modes", "landmarks"):
        if name in tm:
            labels[name] = _read_labels(members, tm[name]["file"])
    extra = {}
    for name, e in (tm.get("extra") or {}).items():
        raw = members.need(e["file"])
        try:
            extra[name] = np.load(io.BytesIO(raw), allow_pickle=False)
        except Exception as exc:  # noqa: BLE001 - a corrupt .npy header raises SyntaxError, TokenError, ...
            raise InputError(f"not a readable .npy array ({exc})", source=members.name(e["file"])) from None
    return GroundTruth(positions=positions, step_times_s=step_times, step_count=tm.get("step_count"),
                       step_lengths_m=step_lengths, modes=labels.get("modes"), landmarks=labels.get("landmarks"),
                       extra=extra)


def _read_labels(members: Bundle, fname: str) -> Labels:
    source = members.name(fname)
    try:
        rows = list(csv.reader(io.StringIO(members.text(fname), newline="")))
    except csv.Error as exc:
        raise InputError(f"not a readable CSV file ({exc})", source=source) from None
    if not rows or tuple(rows[0]) != _LABEL_COLUMNS:
        raise InputError(f"header must be {','.join(_LABEL_COLUMNS)}", source=source, line=1)
    starts: list[float] = []
    ends: list[float] = []
    names: list[str] = []
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != 3:
            raise InputError(f"expected 3 fields ({', '.join(_LABEL_COLUMNS)}), found {len(row)}", source=source,
                             line=i)
        for value, col, out in ((row[0], "t_start_s", starts), (row[1], "t_end_s", ends)):
            try:
                out.append(float(value))
            except ValueError:
                raise InputError(f"'{value[:40]}' is not a number", source=source, line=i, field=col) from None
        names.append(row[2])
    try:
        return Labels(np.array(starts, dtype=np.float64), np.array(ends, dtype=np.float64), tuple(names))
    except InputError as exc:
        raise InputError(exc.message, source=source) from None
