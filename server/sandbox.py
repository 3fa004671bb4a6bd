"""Reading uploaded log files in a separate, resource-limited process.

An uploaded file is untrusted input to parsers that are not all memory-safe or bounded: a corrupt
MATLAB file made ``scipy.io.loadmat`` (native code) crash the whole interpreter with a segmentation
fault (scipy 1.17, a PyShoe ``.mat`` whose bytes 176-208 are zeroed; :func:`pdr.io.matfile.check_elements`
now refuses the damage scipy trusts, and this process stays for what such checks miss), and a
gzip bomb within the upload limit decompresses to tens of GB. Read in the web process, either takes
the service down. Here the reader runs in a child Python process with an address-space and CPU-time
limit; a crash, a limit or a timeout becomes an :class:`~pdr.errors.InputError` (422 for an upload, a
``failed`` batch in processing) and the service keeps running.

The child is started per file: uploads of whole files are rare and large, batches (the frequent path) are
parsed in-process from JSON. The child loads only the readers (``server/__init__`` imports the application
lazily): reading a 0.9 MB PyShoe ``.mat`` takes 1.1 s end to end, 2.5-3.2 s when the child loaded the whole
service.
"""

from __future__ import annotations

import io
import os
import pickle
import re
import resource
import subprocess
import sys
import tempfile
import threading
import zipfile
from pathlib import Path
from typing import Any

from pdr import recording_codec
from pdr.errors import InputError
from pdr.io import format_names
from pdr.io.gz import GZIP_MAGIC, inflated_size
from pdr.io.registry import relocated
from pdr.recording import Recording

#: Address space a reader may use, MB (``PDR_READER_MEMORY_MB``; a 64 MB upload of any format needs far less).
MEMORY_LIMIT_MB = 2048
#: Prefix of the temporary folder an upload is read from (never shown to a user: :func:`without_temp_names`).
TEMP_PREFIX = "pdr-upload-"
#: Readers running at once in this process (``PDR_READERS``); further uploads wait for a free one.
READERS = 2
#: Largest uncompressed size an archive or gzip file may declare, bytes, and its largest compression ratio:
#: sensor logs (text, floats) compress 3-15x; a ratio far beyond is a compression bomb, refused before inflating.
MAX_INFLATED_BYTES = 1024**3
MAX_COMPRESSION_RATIO = 100.0

_readers = threading.BoundedSemaphore(int(os.environ.get("PDR_READERS", READERS)))
#: CPU time a reader may use, s, and wall-clock time the parent waits.
CPU_LIMIT_S = 300
WALL_LIMIT_S = 600


#: Longest file name kept from an upload, characters (file systems allow 255 bytes).
MAX_FILENAME_CHARS = 120


def safe_filename(name: str | None) -> str:
    """A harmless local file name for an uploaded file's name: its last path component, characters outside
    ``[A-Za-z0-9._-]`` replaced, at most :data:`MAX_FILENAME_CHARS` (the suffixes such as ``.csv.gz``, which
    format detection reads, are kept); ``upload`` when nothing usable is left (``..``, empty).
    """
    base = re.sub(r"[^A-Za-z0-9._-]", "_", (name or "").replace("\\", "/").rsplit("/", 1)[-1]).lstrip(".")
    if not base.strip("._"):
        return "upload"
    if len(base) > MAX_FILENAME_CHARS:
        stem, dot, suffixes = base.partition(".")
        suffixes = suffixes[-40:] if dot else ""
        base = stem[:MAX_FILENAME_CHARS - len(suffixes) - 1] + ("." + suffixes if suffixes else "")
    return base


def read_isolated(payload: bytes, filename: str, fmt: str | None = None) -> tuple[str, Recording]:
    """(format, recording) of an uploaded file, detected (unless ``fmt`` is given) and read in one child process.

    Raises
    ------
    InputError
        The reader's own error, or the file crashed the reader or exceeded the limits.
    """
    safe_name = safe_filename(filename)
    if fmt and fmt not in format_names():
        raise InputError(f"unknown format {fmt!r} (supported: {', '.join(format_names())})", source=safe_name,
                         field="format")
    check_compressed(payload, safe_name)
    with _readers, tempfile.TemporaryDirectory(prefix=TEMP_PREFIX) as tmp:
        path = Path(tmp) / safe_name
        path.write_bytes(payload)
        out = Path(tmp) / "result.pickle"
        cmd = [sys.executable, "-m", "server.sandbox", str(path), fmt or "", str(out)]
        try:
            proc = subprocess.run(cmd, capture_output=True, timeout=WALL_LIMIT_S, check=False)
        except subprocess.TimeoutExpired:
            raise InputError(f"reading the file took longer than {WALL_LIMIT_S} s", source=safe_name) from None
        if not out.exists():
            why = (f"killed by signal {-proc.returncode}" if proc.returncode < 0
                   else f"exit status {proc.returncode}")
            raise InputError(f"the file could not be read within the service's limits (the reader crashed: {why}); "
                             "it is corrupt or not a supported log", source=safe_name)
        result: tuple[Any, ...] = pickle.loads(out.read_bytes())  # written by our own child process
    if result[0] == "ok":
        return result[1], without_temp_names(recording_codec.loads(result[2]), Path(tmp), safe_name)
    if result[0] == "input_error":
        _, message, source, line, field, code = result
        err = InputError(message, source=source, line=line, field=field)
        err.code = code
        raise err
    raise RuntimeError(f"{result[1]}: {result[2]}")


def without_temp_names(recording: Recording, folder: Path, name: str) -> Recording:
    """The recording of the upload ``name`` read from the temporary ``folder``, with nothing that names the folder:
    the source is the uploaded file's name, paths inside the folder lose the folder, and a name a reader took from
    the folder itself (e.g. a device model from a parent folder's name) is left empty (:func:`pdr.io.registry.
    relocated`).
    """
    return relocated(relocated(recording, folder / name, name), folder, name, forget=folder.name)


def check_compressed(payload: bytes, source: str) -> None:
    """Refuse a zip or gzip file whose declared uncompressed size or compression ratio is excessive, from its
    headers (zip central directory, gzip trailer), before anything is inflated. :class:`InputError` if so.
    """
    declared: list[tuple[str, int, int]] = []  # (member, uncompressed, compressed) bytes
    if payload[:4] == b"PK\x03\x04":
        try:
            with zipfile.ZipFile(io.BytesIO(payload)) as zf:
                declared = [(i.filename, i.file_size, i.compress_size) for i in zf.infolist()]
        except (zipfile.BadZipFile, ValueError, OSError) as exc:
            raise InputError(f"not a readable zip archive ({exc})", source=source) from None
    elif payload[:2] == GZIP_MAGIC and len(payload) >= 18:
        # ISIZE, the last 4 bytes: the uncompressed size modulo 2**32 (a larger file is refused by its ratio). In a
        # file cut short (or of several members) they are something else: before refusing, count what it inflates
        # to, up to the limits (the refusal then names the real size, and a cut file goes on to be read).
        size = int.from_bytes(payload[-4:], "little")
        if size > MAX_INFLATED_BYTES or _excessive(size, len(payload)):
            bound = min(MAX_INFLATED_BYTES, int(MAX_COMPRESSION_RATIO * len(payload)))
            size = inflated_size(payload, bound)
            if size > bound:
                raise InputError(f"the file inflates to more than {bound} bytes (the service's limits: "
                                 f"{MAX_INFLATED_BYTES} bytes, a compression ratio of {MAX_COMPRESSION_RATIO:g}:1): "
                                 "refused as a compression bomb", source=source)
        declared = [(source, size, len(payload))]
    total = sum(size for _, size, _ in declared)
    if total > MAX_INFLATED_BYTES:
        raise InputError(f"the file declares {total} bytes uncompressed, more than the service's limits allow "
                         f"({MAX_INFLATED_BYTES} bytes): refused before inflating", source=source)
    for member, size, packed in declared:
        if _excessive(size, packed):
            raise InputError(f"member '{member}' declares a compression ratio of {size / max(packed, 1):.0f}:1 "
                             f"(more than {MAX_COMPRESSION_RATIO:g}:1): refused as a compression bomb",
                             source=source)


def _excessive(size: int, packed: int) -> bool:
    """Whether ``size`` bytes inflated from ``packed`` is a compression ratio beyond :data:`MAX_COMPRESSION_RATIO`
    (1 MiB and less always passes).
    """
    return size > 1024**2 and size > MAX_COMPRESSION_RATIO * max(packed, 1)


def _child(path: str, fmt: str, out: str) -> None:
    memory = int(os.environ.get("PDR_READER_MEMORY_MB", MEMORY_LIMIT_MB)) * 1024**2
    resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
    resource.setrlimit(resource.RLIMIT_CPU, (CPU_LIMIT_S, CPU_LIMIT_S))
    from pdr.io import detect_format, read_recording

    try:
        name = fmt or detect_format(path)
        # The recording as recording_codec bytes, which the parent decodes (no pickle of reader objects) and the
        # service stores with the upload, so that nothing reads the file again.
        result: tuple[Any, ...] = ("ok", name, recording_codec.dumps(read_recording(path, format=name)))
    except InputError as exc:
        source = None if exc.source is None else str(exc.source).replace(str(Path(path).parent) + "/", "")
        result = ("input_error", exc.message, source, exc.line, exc.field, exc.code)
    except MemoryError:
        result = ("input_error", "the file needs more memory than the service allows (a compression bomb?)",
                  None, None, None, "invalid_input")
    except Exception as exc:  # a reader bug: reported as such by the parent
        result = ("error", type(exc).__name__, str(exc)[:2000])
    Path(out).write_bytes(pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL))


if __name__ == "__main__":
    _child(sys.argv[1], sys.argv[2], sys.argv[3])
