"""The HTTP service: Flask application factory, API blueprints, storage, jobs, auth and web page.

``create_app`` is imported on first use, so that a submodule run on its own (the reader sandbox's child
process, ``python -m server.sandbox``) does not load Flask, the database layer and the pipelines.
"""

from typing import Any

__all__ = ["create_app"]


def __getattr__(name: str) -> Any:
    if name == "create_app":
        from server.app import create_app

        return create_app
    raise AttributeError(f"module 'server' has no attribute {name!r}")
