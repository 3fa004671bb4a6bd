"""Model listing and cards, window classification, Allan reports through the API."""

from __future__ import annotations

import io
import time

import numpy as np
import pytest

from pdr.io.native import batch_to_json
from pdr.recording import DeviceInfo, Recording, SensorStream
from tests.server.conftest import bearer
from tests.server.helpers import multipart


def test_models_list_and_card(client, tokens):
    h = bearer(tokens["alice"])
    models = client.get("/api/v1/models", headers=h).get_json()["models"]
    names = [m["name"] for m in models]
    assert "motion_mode" in names
    card = client.get("/api/v1/models/motion_mode", headers=h).get_json()
    assert "Model card" in card["card_markdown"]
    assert client.get("/api/v1/models/nope", headers=h).status_code == 404
    assert client.get("/api/v1/models").status_code == 401


def _walk_batch(seconds: float = 8.0) -> dict:
    rate = 100.0
    t = np.arange(int(seconds * rate)) / rate
    t_ns = (1_700_000_000_000_000_000 + np.round(t * 1e9)).astype(np.int64)
    step = 2 * np.pi * 1.9 * t
    acc = np.c_[0.8 * np.sin(step), 9.81 + 2.5 * np.sin(2 * step), 0.6 * np.cos(step)]
    gyro = np.c_[0.9 * np.cos(step), 0.2 * np.sin(step), 0.1 * np.sin(2 * step)]
    rec = Recording({"acc": SensorStream("acc", t_ns, acc), "gyro": SensorStream("gyro", t_ns, gyro)},
                    DeviceInfo(platform="android"), t0_ns=int(t_ns[0]))
    return batch_to_json(rec, batch_id="w")


def test_classify_window(client, tokens):
    h = bearer(tokens["alice"])
    resp = client.post("/api/v1/classify", json={"batch": _walk_batch()}, headers=h)
    assert resp.status_code == 200, resp.get_json()
    windows = resp.get_json()["windows"]
    assert len(windows) >= 3
    assert all({"t_start_s", "t_end_s", "mode", "confidence"} <= set(w) for w in windows)
    assert windows[0]["t_start_s"] >= 1_700_000_000.0  # on the log's clock
    short = client.post("/api/v1/classify", json={"batch": _walk_batch(1.0)}, headers=h)
    assert short.status_code == 422


@pytest.mark.parametrize("model", ["motion_mode", "placement"])
def test_classify_a_batch_with_a_gap_longer_than_a_window_labels_the_gap_unknown(client, tokens, model):
    """An app suspended for 6 s: the windows without one accelerometer sample were NaN, which the pitch and stride
    features' eigendecompositions refused (LinAlgError): a 500. Now they are labelled unknown, the others classified
    as without the gap."""
    h = bearer(tokens["alice"])
    walk = _walk_batch(20.0)
    gap = {kind: [i for i, t in enumerate(s["t_ns"]) if not 7e9 <= t - walk["t0_ns"] < 13e9]
           for kind, s in walk["streams"].items()}
    for kind, s in walk["streams"].items():
        s["t_ns"], s["values"] = [s["t_ns"][i] for i in gap[kind]], [s["values"][i] for i in gap[kind]]
    resp = client.post("/api/v1/classify", json={"batch": walk, "model": model}, headers=h)
    assert resp.status_code == 200, resp.get_json()
    windows = resp.get_json()["windows"]
    inside = [w for w in windows if w["t_start_s"] >= 1_700_000_007.0 and w["t_end_s"] <= 1_700_000_013.0]
    assert inside and {w["mode"] for w in inside} == {"unknown"}
    assert any(w["mode"] != "unknown" for w in windows)



@pytest.mark.parametrize(("change", "field", "words"), [
    # one sample two days on: the windows of the whole span were built (6.8 GB, 35 s), one at t_ns -1 asked 633 GiB
    (lambda b: b["streams"]["acc"]["t_ns"].__setitem__(-1, b["streams"]["acc"]["t_ns"][-1] + 2 * 86_400 * 10**9),
     "batch.streams.*.t_ns", "span"),
    (lambda b: b["streams"]["acc"]["t_ns"].__setitem__(0, -1), "batch.streams.*.t_ns", "span"),
    # beyond any gyro (1e300 rad/s): the stride features' eigendecomposition failed (LinAlgError)
    (lambda b: b["streams"]["gyro"]["values"][0].__setitem__(0, 1e300), "batch.streams.gyro.values[0]", "beyond any"),
])
def test_classify_refuses_a_batch_an_ingest_route_refuses_naming_the_field(client, tokens, change, field, words):
    """A read token's POST /api/v1/classify took a batch spanning days, and made windows over the whole span: a
    500 after minutes, or the machine's memory. It checks the batch as the ingest routes do now (its span, at most
    MAX_CLASSIFY_SPAN_S, and its values' ranges): a 422 naming the field."""
    batch = _walk_batch()
    change(batch)
    resp = client.post("/api/v1/classify", json={"batch": batch}, headers=bearer(tokens["alice"]))
    assert resp.status_code == 422, resp.get_data()[:300]
    error = resp.get_json()["error"]
    assert error["details"]["field"] == field and words in error["message"], error
    from server.api.models import MAX_CLASSIFY_SPAN_S

    late = _walk_batch()
    late["streams"]["acc"]["t_ns"][-1] += int(MAX_CLASSIFY_SPAN_S * 1e9) + 10**9
    assert client.post("/api/v1/classify", json={"batch": late}, headers=bearer(tokens["alice"])).status_code == 422

def _static_npz(seconds: float = 200.0, rate: float = 100.0) -> bytes:
    rng = np.random.default_rng(3)
    n = int(seconds * rate)
    gyro = np.radians(0.02) * rng.standard_normal((n, 3)) + 1e-3
    acc = np.array([0.0, 0.0, 9.81]) + 0.003 * rng.standard_normal((n, 3))
    buf = io.BytesIO()
    np.savez(buf, data=np.c_[gyro, acc], columns=np.array(["Gyro X", "Gyro Y", "Gyro Z", "Accel X", "Accel Y",
                                                           "Accel Z"]), fs=rate)
    return buf.getvalue()


@pytest.mark.timeout(120)
def test_allan_report_round_trip(client, tokens):
    h = bearer(tokens["alice"])
    body, content_type = multipart({"file": (_static_npz(), "static.npz")})
    resp = client.post("/api/v1/reports/allan", data=body, headers=h, content_type=content_type)
    assert resp.status_code == 202, resp.get_json()
    rid = resp.get_json()["id"]
    deadline = time.monotonic() + 90
    while True:
        rep = client.get(f"/api/v1/reports/{rid}", headers=h).get_json()
        if rep["status"] != "pending":
            break
        assert time.monotonic() < deadline
        time.sleep(0.2)
    assert rep["status"] == "done", rep["error"]
    assert {"report.json", "report.html", "gyro.png", "acc.png", "imu.yaml"} <= set(rep["files"])
    assert rep["report"]["gyro"] and rep["report"]["acc"]
    png = client.get(f"/api/v1/reports/{rid}/files/gyro.png", headers=h)
    assert png.status_code == 200 and png.data[:8] == b"\x89PNG\r\n\x1a\n"
    html = client.get(f"/api/v1/reports/{rid}/report.html", headers=h)
    assert html.status_code == 200 and b"<html" in html.data.lower()
    # the report names the uploaded file, never the server's temporary copy of it
    assert b"static.npz" in html.data and b"pdr-upload-" not in html.data and "pdr-upload-" not in str(rep)
    assert client.get(f"/api/v1/reports/{rid}", headers=bearer(tokens["bob"])).status_code == 404


def test_model_cards_carry_no_fitted_internals_and_the_artifact_downloads(client, tokens):
    h = bearer(tokens["alice"])
    models = client.get("/api/v1/models", headers=h)
    assert len(models.data) < 60_000  # the three cards; the motion-mode artifact alone is 700 KB
    card = next(m for m in models.get_json()["models"] if m["name"] == "motion_mode")
    assert card["task"] == "motion_mode" and card["estimator"] == "bayes" and "walking" in card["classes"]
    assert card["evaluations"][0]["protocol"].startswith("leave-one-group-out")
    # The protocol as the evaluation states it (held-out groups, windows never shuffled), not only its title.
    assert any("never shuffled" in ev["protocol"] for ev in card["evaluations"])
    assert all(ev["title"] for ev in card["evaluations"])
    assert 0 < card["evaluations"][0]["metrics"]["macro_f1"] <= 1
    assert card["features"]["count"] == len(card["features"]["names"]) > 0
    assert card["training"]["recordings"] > 0 and "numpy" in card["versions"] and card["date"]
    raw = client.get("/api/v1/models/motion_mode/model.json", headers=h)
    assert raw.status_code == 200 and "attachment" in raw.headers["Content-Disposition"]
    assert "estimator" in raw.get_json()
    assert client.get("/api/v1/models/nope/model.json", headers=h).status_code == 404
    assert client.get("/api/v1/models/motion_mode/model.json").status_code == 401
