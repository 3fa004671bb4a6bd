"""``pdr phyphox URL --server S --token T``: a phone's phyphox experiment streamed live into a service session.

phyphox's remote access (:mod:`pdr.io.phyphox_remote`) is polled every ``--interval`` seconds; each poll's new
samples go to the service as one native batch (``POST /api/v1/sessions/ID/batches``, ``pdr-batch/1``), so the
session's track grows while the user walks, as with the Sensor Logger push. The command ends when the experiment
stops (after at least one sample), after ``--duration`` seconds, or on Ctrl-C, and prints the session's steps.
Only the standard library talks HTTP: pdr/ never imports the service.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import urllib.error
import urllib.request
from typing import Any

from pdr.errors import InputError
from pdr.io.native import batch_to_json
from pdr.io.phyphox_remote import PhyphoxRemote
from pdr.recording import PLACEMENTS

#: Seconds an HTTP request may take.
TIMEOUT_S = 10.0


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("phyphox", help="stream a phone's phyphox experiment (remote access) into a session")
    p.add_argument("url", help="the phone's phyphox remote-access URL, e.g. http://192.168.0.42:8080")
    p.add_argument("--server", required=True, help="the service's base URL, e.g. http://localhost:8000")
    p.add_argument("--token", required=True, help="an API token with the ingest (or full) scope")
    p.add_argument("--session-id", help="your key for the session (default: phyphox-<the experiment's session>)")
    p.add_argument("--placement", choices=PLACEMENTS, help="how the phone is carried (default: detected)")
    p.add_argument("--interval", type=float, default=1.0, help="seconds between polls of the phone (default 1)")
    p.add_argument("--duration", type=float, help="stop after this many seconds (default: when the experiment stops)")
    p.add_argument("--start", action="store_true", help="start the experiment's measurement first")
    p.set_defaults(func=run)


def _phone(url: str) -> Any:
    base = url.rstrip("/")

    def fetch(path: str) -> bytes:
        try:
            with urllib.request.urlopen(base + path, timeout=TIMEOUT_S) as r:  # noqa: S310 - the user's URL
                return bytes(r.read())
        except urllib.error.HTTPError as exc:
            raise InputError(f"phyphox answered {exc.code} to {path.split('?')[0]}", source=base) from None
        except (urllib.error.URLError, TimeoutError, ConnectionError) as exc:
            raise InputError(f"cannot reach phyphox ({getattr(exc, 'reason', exc)}); is remote access on?",
                             source=base) from None

    return fetch


def _post(server: str, token: str, path: str, body: dict[str, Any]) -> dict[str, Any]:
    req = urllib.request.Request(server.rstrip("/") + path, data=json.dumps(body).encode(), method="POST",
                                 headers={"Content-Type": "application/json", "Authorization": f"Bearer {token}"})
    return _send(req, server)


def _get(server: str, token: str, path: str) -> dict[str, Any]:
    return _send(urllib.request.Request(server.rstrip("/") + path, headers={"Authorization": f"Bearer {token}"}),
                 server)


def _send(req: urllib.request.Request, server: str) -> dict[str, Any]:
    try:
        with urllib.request.urlopen(req, timeout=TIMEOUT_S) as r:  # noqa: S310 - the user's URL
            out: dict[str, Any] = json.loads(r.read() or b"{}")
            return out
    except urllib.error.HTTPError as exc:
        try:
            message = json.loads(exc.read())["error"]["message"]
        except (ValueError, KeyError, TypeError):
            message = exc.reason
        raise InputError(f"the service answered {exc.code}: {message}", source=server) from None
    except (urllib.error.URLError, TimeoutError, ConnectionError) as exc:
        raise InputError(f"cannot reach the service ({getattr(exc, 'reason', exc)})", source=server) from None


def run(args: argparse.Namespace) -> int:
    phone = PhyphoxRemote(_phone(args.url)).connect()
    if args.start:
        phone.control("start")
    first = phone.poll()
    client_id = args.session_id or f"phyphox-{phone.session or int(time.time())}"
    body: dict[str, Any] = {"session_id": client_id, "name": f"phyphox {phone.title}".strip(),
                            "device": {"role": "phone", "platform": phone.device.platform, "model": phone.device.model}}
    if args.placement:
        body["placement"] = args.placement
    sid = _post(args.server, args.token, "/api/v1/sessions", body)["id"]
    print(f"session {sid} ({client_id}): streaming '{phone.title}' from {args.url}", file=sys.stderr)
    sent = samples = 0
    started = time.monotonic()
    batch = first
    try:
        while True:
            if batch is not None:
                _post(args.server, args.token, f"/api/v1/sessions/{sid}/batches",
                      batch_to_json(batch, session_id=client_id, batch_id=f"{client_id}-{sent:06d}"))
                sent += 1
                samples += sum(len(s) for s in batch.streams.values())
            elif not phone.measuring and samples:
                break          # the experiment stopped and everything it measured is sent
            if args.duration is not None and time.monotonic() - started >= args.duration:
                break
            time.sleep(max(0.0, args.interval))
            batch = phone.poll()
    except KeyboardInterrupt:
        pass
    session = _get(args.server, args.token, f"/api/v1/sessions/{sid}")
    print(f"{sent} batches, {samples} samples -> session {sid}: {session.get('steps', 0)} steps, "
          f"{session.get('distance_m', 0.0):.1f} m so far")
    return 0
