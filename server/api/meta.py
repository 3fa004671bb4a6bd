"""Health and the OpenAPI document."""

from __future__ import annotations

from flask import Blueprint, Response, jsonify

import pdr
from server.openapi import openapi_document

bp = Blueprint("meta", __name__, url_prefix="/api/v1")


@bp.get("/health")
def health() -> Response:
    return jsonify({"status": "ok", "version": pdr.__version__})


@bp.get("/openapi.json")
def openapi() -> Response:
    return jsonify(openapi_document())
