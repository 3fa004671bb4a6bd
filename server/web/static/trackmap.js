/* The track map of a session in local metres: Leaflet (vendor/leaflet, from npm) with L.CRS.Simple, one map unit
 * one metre, latitude north and longitude east of the session's frame (east_m, north_m), so north is up and the
 * axes are equal. Leaflet pans (drag, keys), zooms (wheel, pinch, the page's buttons) and keeps markers their size
 * on screen; layers: a metre grid, the floor plan, the truth and its errors, the tracks, the markers. A session with
 * an origin also gets a real (Web Mercator) map in app.js; this one carries what has no longitude and latitude:
 * floor plans in the site's frame and the truth aligned as the scorers align it. */
"use strict";

const TrackMap = (() => {
  const { niceStep, fmt } = Plot;
  /** Leaflet's [lat, lng] of a point (east_m, north_m). */
  const at = (e, n) => [n, e];
  /** Zoom limits: 2^z pixels per metre, from a 40 km walk on a phone (2^-12) to 1 cm per pixel (2^7). */
  const MIN_ZOOM = -12, MAX_ZOOM = 7;
  /** Smallest extent (m) fitted: a track of one step still gets a few metres around it. */
  const MIN_EXTENT_M = 4;
  /** Every polyline drawn vertex for vertex: no simplification (smoothFactor) and no clipping to the view. */
  const EXACT = { smoothFactor: 0, noClip: true };

  /** ``data-*`` attributes on a drawn layer's SVG element (the browser tests and styles select by them). */
  function tag(layer, attrs, title) {
    const node = layer.getElement();
    if (!node) return;
    for (const [k, v] of Object.entries(attrs)) if (v !== undefined && v !== null) node.setAttribute(`data-${k}`, String(v));
    if (title) {
      const t = document.createElementNS("http://www.w3.org/2000/svg", "title");
      t.textContent = title;
      node.appendChild(t);
    }
  }

  class TrackMap {
    /** container: an empty block element with a size (CSS); scaleBar: the toolbar's scale bar, or null. */
    constructor(container, scaleBar) {
      this.el = container;
      this.scaleBar = scaleBar;
      this.map = L.map(container, { crs: L.CRS.Simple, zoomControl: false, attributionControl: false, zoomSnap: 0,
        zoomDelta: 0.5, wheelPxPerZoomLevel: 120, minZoom: MIN_ZOOM, maxZoom: MAX_ZOOM, boxZoom: false,
        renderer: L.svg({ padding: 0.5 }) }).setView([0, 0], 0);
      this.layers = L.layerGroup().addTo(this.map);
      this.bounds = null; // what Fit shows: the data's extent
      this.lines = []; // [{role, xy: [[e, n], ...]}] drawn, for the page's tests
      this.moved = false; // the user panned or zoomed: a redraw keeps their view, else it fits the data
      this.empty = null;
      this.map.on("dragstart", () => { this.moved = true; });
      container.addEventListener("wheel", () => { this.moved = true; }, { passive: true });
      container.addEventListener("touchstart", (ev) => { if (ev.touches.length > 1) this.moved = true; }, { passive: true });
      this.map.on("zoom zoomend resize viewreset", () => this._updateScale());
      // A new size (a phone turned, a window resized) fits the data again unless the user chose the view.
      this.map.on("resize", () => { if (!this.moved) this.fit(); });
      // Leaflet notices a window resize, not a box resized by the page's layout after it: told of both.
      this.resizeObserver = new ResizeObserver(() => this.map.invalidateSize({ pan: false }));
      this.resizeObserver.observe(container);
    }

    /** True when there is something to show. */
    get hasData() { return this.bounds !== null; }

    /** The view in metres: [west (min east), south (min north), east, north]. */
    view() {
      const b = this.map.getBounds();
      return [b.getWest(), b.getSouth(), b.getEast(), b.getNorth()];
    }

    /** Metres per screen pixel at the current zoom (CRS.Simple: 2^zoom pixels per unit). */
    metresPerPixel() { return 1 / this.map.options.crs.scale(this.map.getZoom()); }

    /** A point (east_m, north_m) in the coordinates of the SVG the paths are drawn in (Leaflet's layer points). */
    toLayerPoint(e, n) {
      const p = this.map.latLngToLayerPoint(at(e, n));
      return [p.x, p.y];
    }

    /** Zoom out by ``factor`` (> 1) or in (< 1) about the centre of the view. */
    zoom(factor) {
      if (!this.hasData) return;
      this.moved = true;
      this.map.setZoom(this.map.getZoom() - Math.log2(factor), { animate: false });
    }

    fit() {
      this.moved = false;
      if (this.bounds) this.map.fitBounds(this.bounds, { padding: [14, 14], animate: false });
    }

    _updateScale() {
      if (!this.scaleBar) return;
      const line = this.scaleBar.querySelector(".scale-line"), text = this.scaleBar.querySelector(".scale-text");
      if (!this.hasData) { line.style.width = "0"; text.textContent = ""; return; }
      const k = this.metresPerPixel();
      const metres = niceStep(k * 120, 1);
      line.style.width = `${(metres / k).toFixed(0)}px`;
      text.textContent = metres >= 1000 ? `${metres / 1000} km` : `${fmt(metres)} m`;
    }

    _showEmpty(text) {
      if (!this.empty) {
        this.empty = document.createElement("div");
        this.empty.className = "map-empty";
        this.el.appendChild(this.empty);
      }
      this.empty.textContent = text;
      this.empty.hidden = false;
    }

    /**
     * Draw layers. plan: {floor, polygons: GeoJSON MultiPolygon coordinates (m, site frame), name} or null;
     * tracks: [{device, foot, segments: [{colour, mode, xy: Float64Array [e0, n0, e1, n1, ...], count}]}];
     * truth: [{e, n}]; errors: [[e, n, e', n']]; markers: [{e, n, cls, px, title}]; empty: text without data.
     * keepView: keep the user's pan and zoom (else fit the data). Returns the number of track points drawn.
     */
    draw(layers, keepView) {
      this.layers.clearLayers();
      this.lines = [];
      const bounds = L.latLngBounds([]);
      for (const tr of layers.tracks) for (const s of tr.segments) for (let i = 0; i < s.xy.length; i += 2) bounds.extend(at(s.xy[i], s.xy[i + 1]));
      for (const p of layers.truth || []) bounds.extend(at(p.e, p.n));
      if (!bounds.isValid()) {
        this.bounds = null;
        this.el.dataset.points = "0";
        this._showEmpty(layers.empty || "no track points yet");
        this._updateScale();
        return 0;
      }
      if (this.empty) this.empty.hidden = true;
      const c = bounds.getCenter(), half = MIN_EXTENT_M / 2;
      bounds.extend([c.lat - half, c.lng - half]).extend([c.lat + half, c.lng + half]);
      this.bounds = bounds;
      // The view first, then the layers: each layer is projected once, at the view it is shown in (a fit after
      // adding them would project every point again). Keep the view only when the user chose it: rows arriving
      // later (the smoothed track, the truth, a live upload) may reach beyond the first fit.
      if (!(keepView && this.moved)) this.fit();
      this._grid(bounds);
      if (layers.plan) { // the floor's walkable area under everything else: outer rings and holes, even-odd
        const rings = layers.plan.polygons.map((poly) => poly.map((ring) => ring.map((p) => at(p[0], p[1]))));
        const plan = L.polygon(rings, { className: "floor-plan", interactive: false, fillRule: "evenodd", weight: 1,
          color: "#98a2b3", fillColor: "#eaf1fb", fillOpacity: 1 }).addTo(this.layers);
        tag(plan, { role: "floor-plan", floor: layers.plan.floor, rings: rings.reduce((n, poly) => n + poly.length, 0) },
          `${layers.plan.name ? `${layers.plan.name}: ` : ""}floor ${layers.plan.floor}, walkable area`);
      }
      if ((layers.truth || []).length) {
        const xy = layers.truth.map((p) => [p.e, p.n]);
        const line = L.polyline(xy.map(([e, n]) => at(e, n)), Object.assign({ className: "truth-line", interactive: false,
          color: "#111", weight: 1.2, dashArray: "2 3" }, EXACT)).addTo(this.layers);
        tag(line, { role: "truth" });
        this.lines.push({ role: "truth", xy });
      }
      if ((layers.errors || []).length) {
        const line = L.polyline(layers.errors.map(([e0, n0, e1, n1]) => [at(e0, n0), at(e1, n1)]), Object.assign({
          className: "error-line", interactive: false, color: "#d92d20", weight: 1, opacity: 0.7 }, EXACT)).addTo(this.layers);
        tag(line, { role: "errors", count: layers.errors.length });
      }
      let drawn = 0;
      for (const tr of layers.tracks) {
        for (const s of tr.segments) {
          const xy = [];
          for (let i = 0; i < s.xy.length; i += 2) xy.push([s.xy[i], s.xy[i + 1]]);
          const line = L.polyline(xy.map(([e, n]) => at(e, n)), Object.assign({ className: tr.foot ? "track foot" : "track",
            color: s.colour, weight: tr.foot ? 1.2 : 2.2, opacity: 1, dashArray: tr.foot ? "4 3" : null,
            lineJoin: "round", lineCap: "round" }, EXACT)).addTo(this.layers);
          tag(line, { role: "track", device: tr.device, mode: s.mode, points: s.count }, `${tr.device}: ${s.mode || "unknown mode"}`);
          this.lines.push({ role: "track", xy });
          drawn += s.count;
        }
      }
      for (const m of layers.markers || []) {
        const marker = L.circleMarker(at(m.e, m.n), { radius: m.px || 5, className: m.cls, weight: 1.5, fillOpacity: 1,
          color: "#fff" }).addTo(this.layers);
        tag(marker, { role: m.cls.split(" ")[0] }, m.title);
      }
      this.el.dataset.points = String(drawn);
      this._updateScale();
      return drawn;
    }

    /** Grid lines every "nice" number of metres over three times the data's extent (room to pan), as one path. */
    _grid(bounds) {
      const w = bounds.getWest(), e = bounds.getEast(), s = bounds.getSouth(), n = bounds.getNorth();
      const span = Math.max(e - w, n - s);
      const step = niceStep(span, 10);
      const x0 = Math.floor((w - span) / step) * step, x1 = e + span, y0 = Math.floor((s - span) / step) * step, y1 = n + span;
      const parts = [];
      for (let x = x0; x <= x1; x += step) parts.push([at(x, y0), at(x, y1)]);
      for (let y = y0; y <= y1; y += step) parts.push([at(x0, y), at(x1, y)]);
      L.polyline(parts, Object.assign({ className: "grid-line", interactive: false, color: "#e8ecf1", weight: 1 }, EXACT))
        .addTo(this.layers);
    }

    /** Take the map off its element (another session is opened, or none). */
    remove() {
      this.resizeObserver.disconnect();
      this.map.remove();
      while (this.el.firstChild) this.el.removeChild(this.el.firstChild);
      delete this.el.dataset.points;
    }
  }

  return TrackMap;
})();
