"""The HTTP service: Flask application factory, API blueprints, storage, jobs, auth and web page."""

from server.app import create_app

__all__ = ["create_app"]
