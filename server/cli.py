"""``pdr serve`` and ``pdr users``: run the service with a production WSGI server, manage accounts.

Both read the same configuration (:mod:`server.config`: ``PDR_DATA_DIR``, ``DATABASE_URL``, ...), so
``pdr users add`` creates accounts in the database that ``pdr serve`` uses.
"""

from __future__ import annotations

import argparse
import os
import sys

from server.config import load_settings


def _serve(args: argparse.Namespace) -> int:
    from server import warmup

    warmup.use_cache_dir(load_settings().data_dir / "numba-cache")   # before numba is imported (server.warmup doc)
    from waitress import serve

    from server.app import create_app
    from server.config import limit_native_threads

    limit_native_threads()
    app = create_app()
    settings = app.extensions["pdr"].settings
    warmup.start(extra=(_warm_classifier,))
    print(f"pdr service on http://{args.host}:{args.port}/api/v1/health (data: {settings.database_url})",
          flush=True)
    serve(app, host=args.host, port=args.port, threads=args.threads, ident="pdr")
    return 0


def _warm_classifier(recording: object) -> None:
    """The motion-mode classifier's compiled features, on the warm-up walk (server.warmup)."""
    from classifiers.streaming import StreamingClassifier
    StreamingClassifier().update(recording)  # type: ignore[arg-type]


def register_serve(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("serve", help="run the HTTP service (embedded default: SQLite + in-process worker)")
    p.add_argument("--host", default=os.environ.get("PDR_HOST", "127.0.0.1"), help="bind address (127.0.0.1)")
    p.add_argument("--port", type=int, default=int(os.environ.get("PDR_PORT", "8000")), help="port (8000)")
    p.add_argument("--threads", type=int, default=int(os.environ.get("PDR_THREADS", "8")),
                   help="request threads (8)")
    p.set_defaults(func=_serve)


def _engine():  # noqa: ANN202
    from server import migrations
    from server.db import make_engine

    settings = load_settings()
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    migrations.upgrade(settings.database_url)
    return make_engine(settings.database_url)


def _users(args: argparse.Namespace) -> int:
    from sqlalchemy import select

    from server import auth, db

    engine = _engine()
    try:
        with engine.begin() as conn:
            if args.action == "add":
                token = auth.add_user(conn, args.name)
                print(token)
                print(f"created user '{args.name}'; the token above is shown only once", file=sys.stderr)
            elif args.action == "token":
                row = conn.execute(select(db.users.c.id).where(db.users.c.name == args.name)).first()
                if row is None:
                    raise ValueError(f"no user '{args.name}'")
                print(auth.issue_token(conn, int(row.id)))
            elif args.action == "revoke":
                n = auth.revoke_user_tokens(conn, args.name)
                print(f"revoked {n} token(s) of '{args.name}'")
            else:
                for row in conn.execute(select(db.users.c.name, db.users.c.created_at).order_by(db.users.c.name)):
                    print(f"{row.name}\t{row.created_at.isoformat()}")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    finally:
        engine.dispose()
    return 0


def register_users(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("users", help="manage user accounts and API tokens")
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    actions.required = True
    for name, help_ in (("add", "create a user and print its first API token"),
                        ("token", "print a new additional API token for a user"),
                        ("revoke", "revoke every token of a user")):
        a = actions.add_parser(name, help=help_)
        a.add_argument("name")
    actions.add_parser("list", help="list users")
    p.set_defaults(func=_users)
