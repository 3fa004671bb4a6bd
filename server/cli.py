"""``pdr serve`` and ``pdr users``: run the service with a production WSGI server, manage accounts.

Both read the same configuration (:mod:`server.config`: ``PDR_DATA_DIR``, ``DATABASE_URL``, ...), so
``pdr users add`` creates accounts in the database that ``pdr serve`` uses.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys

from server.config import load_settings


def _serve(args: argparse.Namespace) -> int:
    from server import warmup

    warmup.use_cache_dir(load_settings().data_dir / "numba-cache")   # before numba is imported (server.warmup doc)
    from waitress import create_server
    from waitress.server import BaseWSGIServer

    from server.app import body_limit_of, create_app
    from server.config import limit_native_threads, safe_url
    from server.limits import limited_channel

    logging.getLogger().setLevel(logging.INFO)  # the access log (pdr.access) and the service's notes
    limit_native_threads()
    app = create_app()
    settings = app.extensions["pdr"].settings
    warmup.start()
    # waitress reads a whole body before the application runs: its own cap is the largest route limit, and its
    # request parser applies each route's limit from the headers (server.limits).
    server = create_server(app, host=args.host, port=args.port, threads=args.threads, ident="pdr",
                           max_request_body_size=max(settings.max_upload_bytes, settings.max_batch_bytes) + 1,
                           # behind trusted proxies werkzeug's ProxyFix (server.app) reads X-Forwarded-*
                           clear_untrusted_proxy_headers=not settings.trusted_proxies)
    channel = limited_channel(body_limit_of(settings))
    dispatchers = getattr(server, "map", None) or server._map  # several sockets, or one server
    for dispatcher in list(dispatchers.values()):
        if isinstance(dispatcher, BaseWSGIServer):
            dispatcher.channel_class = channel
    print(f"pdr service on http://{args.host}:{args.port}/api/v1/health (data: {safe_url(settings.database_url)})",
          flush=True)
    server.run()
    return 0


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
                print(auth.issue_token(conn, auth.user_id(conn, args.name), args.scope, args.expires))
                print(f"new '{args.scope}' token of '{args.name}'"
                      + (f", valid {args.expires:g} days" if args.expires else "") + "; shown only once",
                      file=sys.stderr)
            elif args.action == "tokens":
                print("prefix\tscope\tcreated\texpires\tlast_used\trevoked")
                for t in auth.list_tokens(conn, args.name):
                    print("\t".join([t.prefix, t.scope, *(_when(v) for v in (t.created_at, t.expires_at,
                                                                             t.last_used_at, t.revoked_at))]))
            elif args.action == "revoke":
                n = auth.revoke_user_tokens(conn, args.name, args.token)
                print(f"revoked {n} token(s) of '{args.name}'")
            elif args.action == "delete":
                if not args.yes:
                    raise ValueError(f"deleting '{args.name}' removes every session, report and token of the "
                                     "user for good: repeat with --yes")
                auth.delete_user(conn, args.name)
                print(f"deleted user '{args.name}' and all their data")
            else:
                for row in conn.execute(select(db.users.c.name, db.users.c.created_at).order_by(db.users.c.name)):
                    print(f"{row.name}\t{row.created_at.isoformat()}")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    finally:
        engine.dispose()
    return 0


def _when(t: object) -> str:
    return "-" if t is None else str(getattr(t, "isoformat", lambda: t)())[:19]


def register_users(subparsers: argparse._SubParsersAction) -> None:
    from server.auth import SCOPES

    p = subparsers.add_parser("users", help="manage user accounts and API tokens")
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    actions.required = True
    a = actions.add_parser("add", help="create a user and print its first API token (scope full)")
    a.add_argument("name")
    a = actions.add_parser("token", help="print a new additional API token for a user")
    a.add_argument("name")
    a.add_argument("--scope", choices=SCOPES, default="full",
                   help="ingest: push data only (give this one to phones); read: read only; full: everything")
    a.add_argument("--expires", type=float, metavar="DAYS", help="the token stops working after DAYS days")
    a = actions.add_parser("tokens", help="list a user's tokens: prefix, scope, expiry, last use")
    a.add_argument("name")
    a = actions.add_parser("revoke", help="revoke one token of a user (--token PREFIX) or all of them")
    a.add_argument("name")
    a.add_argument("--token", metavar="PREFIX", help="the token's prefix as 'pdr users tokens' lists it")
    a = actions.add_parser("delete", help="delete a user and all their sessions, reports and tokens")
    a.add_argument("name")
    a.add_argument("--yes", action="store_true", help="confirm: the data cannot be recovered")
    actions.add_parser("list", help="list users")
    p.set_defaults(func=_users)
