"""``pdr site from-ms FLOOR_DIR --out SITE.json`` and ``pdr site check SITE.json [--plot F.png]``: floor plans."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from pdr.cli.outputs import in_made_folder, plot_path
from pdr.errors import InputError
from pdr.phone.landmarks import Site
from pdr.site.ms import site_from_ms_floor
from pdr.site.plan import SitePlan


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("site", help="site descriptions with floor plans: build from a dataset, check, draw")
    sub = p.add_subparsers(dest="site_command", metavar="COMMAND")
    sub.required = True
    m = sub.add_parser("from-ms", help="a site from a Microsoft Indoor Location floor folder (its waypoints' frame)")
    m.add_argument("floor_dir", help="floor folder with geojson_map.json and floor_info.json (e.g. site2/F3)")
    m.add_argument("--out", required=True, help="site description JSON to write")
    m.set_defaults(func=run_from_ms)
    c = sub.add_parser("check", help="validate a site description; print its floors; optionally draw it")
    c.add_argument("site", help="site description JSON")
    c.add_argument("--plot", help="PNG of every floor's walkable area and walls")
    c.add_argument("--points", help="also check that these positions are walkable: a JSON list of "
                                    "[east_m, north_m, floor]")
    c.set_defaults(func=run_check)


def run_from_ms(args: argparse.Namespace) -> int:
    doc = site_from_ms_floor(args.floor_dir)
    in_made_folder(args.out).write_text(json.dumps(doc))
    plan = SitePlan.from_dict(doc, source=args.out)
    for f in plan.floors.values():
        print(f"floor {f.floor}: {len(f.polygons)} walkable polygon(s), {sum(len(p.holes) for p in f.polygons)} "
              f"holes, {len(f.walls())} wall segments -> {args.out}")
    return 0


def run_check(args: argparse.Namespace) -> int:
    import numpy as np
    args.plot = plot_path(args.plot)    # the file written: '.png' added to a name without an extension
    try:
        doc = json.loads(Path(args.site).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"cannot read site description ({exc})", source=args.site) from None
    if isinstance(doc, dict) and "landmarks" in doc:
        Site.from_dict(doc, source=args.site)          # the landmark section, when there is one
    plan = SitePlan.from_dict(doc, source=args.site)
    for f in plan.floors.values():
        x0, y0, x1, y1 = f.bounds()
        print(f"floor {f.floor}: altitude {plan.altitude_m(f.floor):.2f} m, {len(f.polygons)} walkable polygon(s), "
              f"{sum(len(p.holes) for p in f.polygons)} holes, {len(f.walls())} walls, "
              f"extent {x1 - x0:.1f} x {y1 - y0:.1f} m")
    if args.points:
        try:
            pts = np.asarray(json.loads(Path(args.points).read_text()), dtype=np.float64).reshape(-1, 3)
        except (OSError, ValueError, json.JSONDecodeError) as exc:
            raise InputError(f"expected a JSON list of [east_m, north_m, floor] ({exc})", source=args.points) \
                from None
        outside = 0
        for i, (e, n, fl) in enumerate(pts):
            if not plan.floor(int(fl), args.site).contains(np.array([[e, n]]))[0]:
                outside += 1
                print(f"point {i} ({e:.2f}, {n:.2f}) on floor {int(fl)} is outside the walkable area")
        print(f"{len(pts) - outside} of {len(pts)} points walkable")
        if outside:
            return 1
    if args.plot:
        _plot(plan, in_made_folder(args.plot))
    print(f"{args.site}: valid ({len(plan.floors)} floor(s))")
    return 0


def _plot(plan: SitePlan, path: str | Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon
    floors = sorted(plan.floors)
    fig, axes = plt.subplots(1, len(floors), figsize=(6 * len(floors), 6), squeeze=False)
    for ax, fl in zip(axes[0], floors, strict=True):
        f = plan.floors[fl]
        for poly in f.polygons:       # walkable: the outer ring filled, its holes drawn over it in white
            ax.add_patch(Polygon(poly.outer, closed=True, facecolor="#dde8f0", edgecolor="k", lw=0.5))
            for h in poly.holes:
                ax.add_patch(Polygon(h, closed=True, facecolor="white", edgecolor="k", lw=0.4))
        ax.autoscale_view()
        ax.set_aspect("equal")
        ax.set_title(f"floor {fl}")
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
    fig.savefig(path, dpi=100)
    plt.close(fig)
