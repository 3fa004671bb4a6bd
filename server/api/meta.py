"""Health and the OpenAPI document."""

from __future__ import annotations

from flask import Blueprint, Response, jsonify

import pdr
from server import warmup
from server.openapi import openapi_document

bp = Blueprint("meta", __name__, url_prefix="/api/v1")


@bp.get("/health")
def health() -> Response:
    kernels = warmup.status()  # "warming up" while `pdr serve` compiles the kernels in the background
    return jsonify({"status": "warming up" if kernels["state"] == "warming up" else "ok",
                    "version": pdr.__version__, "kernels": kernels})


@bp.get("/openapi.json")
def openapi() -> Response:
    return jsonify(openapi_document())
