/* Small SVG drawing kit of the page: elements, nice ticks, time-series charts and log-log charts (the track map is
 * trackmap.js). No dependencies; every text goes through textContent. */
"use strict";

const SVG_NS = "http://www.w3.org/2000/svg";

const Plot = (() => {
  function svgEl(tag, attrs, parent) {
    const node = document.createElementNS(SVG_NS, tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v !== undefined && v !== null) node.setAttribute(k, String(v));
    }
    if (parent) parent.appendChild(node);
    return node;
  }

  function clear(node) {
    while (node.firstChild) node.removeChild(node.firstChild);
  }

  function svgText(parent, x, y, text, attrs) {
    const t = svgEl("text", Object.assign({ x, y }, attrs || {}), parent);
    t.textContent = text;
    return t;
  }

  /** A "nice" step (1, 2 or 5 times a power of ten) near span / count. */
  function niceStep(span, count) {
    if (!(span > 0)) return 1;
    const raw = span / Math.max(count, 1);
    const p = Math.pow(10, Math.floor(Math.log10(raw)));
    const m = raw / p;
    return (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * p;
  }

  /** Time ticks (seconds) at steps people read: 1, 2, 5, 10, 15, 30 s, 1, 2, 5, 10, 15, 30 min, 1, 2, 3, 6, 12 h. */
  const TIME_STEPS = [1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 10800, 21600, 43200, 86400];
  function timeTicks(lo, hi, count) {
    const raw = (hi - lo) / Math.max(count, 1);
    const step = raw < 1 ? niceStep(hi - lo, count) : TIME_STEPS.find((s) => s >= raw) || niceStep(hi - lo, count);
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(v);
    return out;
  }

  function ticks(lo, hi, count) {
    const step = niceStep(hi - lo, count);
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
    return out;
  }

  // Loops rather than Math.min(...a): spreading a long array can overflow the call stack.
  function minOf(a) { let m = Infinity; for (const v of a) if (v < m) m = v; return m; }
  function maxOf(a) { let m = -Infinity; for (const v of a) if (v > m) m = v; return m; }

  function fmt(v, digits) {
    if (v === null || v === undefined || !Number.isFinite(v)) return "–";
    const d = digits === undefined ? 2 : digits;
    return Math.abs(v) >= 1e5 || (Math.abs(v) < 1e-3 && v !== 0) ? v.toExponential(2) : String(Number(v.toFixed(d)));
  }

  function fmtDuration(s) {
    if (!Number.isFinite(s)) return "–";
    const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = Math.round(s % 60);
    if (h) return m ? `${h} h ${String(m).padStart(2, "0")} min` : `${h} h`;
    if (m) return sec ? `${m} min ${String(sec).padStart(2, "0")} s` : `${m} min`;
    return `${sec} s`;
  }

  /* Stable colours: the usual motion modes get fixed ones, anything else a hashed hue. */
  const MODE_COLOURS = {
    walking: "#1f6feb", walk: "#1f6feb", running: "#7a5af8", run: "#7a5af8", standing: "#98a2b3", still: "#98a2b3",
    stationary: "#98a2b3", sitting: "#667085", stairs_up: "#f79009", stairs_down: "#dc6803", upstairs: "#f79009",
    downstairs: "#dc6803", elevator: "#12b76a", elevator_up: "#12b76a", elevator_down: "#039855", lift: "#12b76a", escalator: "#0e9384",
    escalator_up: "#0e9384", escalator_down: "#107569", driving: "#e31b54",
    vehicle: "#e31b54", cycling: "#ee46bc", unknown: "#475467",
  };
  const DEVICE_COLOURS = { phone: "#1f6feb", left_foot: "#12b76a", right_foot: "#f79009", fused: "#6941c6" };
  const PALETTE = ["#1f6feb", "#f79009", "#12b76a", "#d92d20", "#7a5af8", "#0e9384", "#ee46bc", "#475467"];

  function hashColour(name) {
    let h = 0;
    for (const c of String(name)) h = (h * 31 + c.charCodeAt(0)) >>> 0;
    return PALETTE[h % PALETTE.length];
  }
  const modeColour = (m) => MODE_COLOURS[m || "unknown"] || hashColour(m);
  const deviceColour = (d) => DEVICE_COLOURS[d] || hashColour(d);

  /**
   * Time-series chart. series: [{name, colour, t: [], y: [], breakAbove?: number (jump that breaks the line),
 * gapS?: number (s; a longer interval between two samples breaks the line)}];
   * bands: [{t0, t1, colour, label}] drawn as a strip; opts: {title, yLabel, yMin, yMax, tMin, tMax, steps}.
   */
  function timeChart(svg, series, opts) {
    clear(svg);
    const W = svg.clientWidth || 900, H = svg.clientHeight || 150;
    svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
    const L = 54, R = 12, T = 18, B = 24; // B: room for the time labels below the lowest y label
    const bands = opts.bands || [];
    const bandH = bands.length ? 16 : 0;
    let tMin = opts.tMin, tMax = opts.tMax, yMin = opts.yMin, yMax = opts.yMax;
    const allT = [], allY = [];
    for (const s of series) {
      for (let i = 0; i < s.t.length; i++) {
        if (Number.isFinite(s.y[i])) { allT.push(s.t[i]); allY.push(s.y[i]); }
      }
    }
    if (tMin === undefined) tMin = bands.reduce((a, b) => Math.min(a, b.t0), minOf(allT));
    if (tMax === undefined) tMax = bands.reduce((a, b) => Math.max(a, b.t1), maxOf(allT));
    if (!Number.isFinite(tMin) || !Number.isFinite(tMax)) {
      svgText(svg, W / 2, H / 2, opts.empty || "no data", { "text-anchor": "middle" });
      return;
    }
    if (tMax <= tMin) tMax = tMin + 1;
    if (yMin === undefined) yMin = allY.length ? minOf(allY) : 0;
    if (yMax === undefined) yMax = allY.length ? maxOf(allY) : 1;
    if (yMax <= yMin) { yMax = yMin + 0.5; yMin -= 0.5; }
    const x = (t) => L + ((t - tMin) / (tMax - tMin)) * (W - L - R);
    const plotTop = T + bandH + (bandH ? 6 : 0);
    const y = (v) => H - B - ((v - yMin) / (yMax - yMin)) * (H - B - plotTop);
    if (opts.title) svgText(svg, L, 12, opts.title, { class: "title" });
    for (const v of ticks(yMin, yMax, 4)) {
      svgEl("line", { x1: L, x2: W - R, y1: y(v), y2: y(v), class: "gridline" }, svg);
      svgText(svg, L - 4, y(v) + 4, (opts.yFormat || fmt)(v), { "text-anchor": "end" });
    }
    const origin = opts.tOrigin ?? tMin;
    // About one label per 80 px: "1 h 20 min" is about 60 px wide, so narrow charts get fewer ticks.
    for (const t of timeTicks(0, tMax - origin, Math.max(2, Math.min(8, Math.floor((W - L - R) / 80))))) {
      if (origin + t < tMin) continue;
      svgEl("line", { x1: x(origin + t), x2: x(origin + t), y1: H - B, y2: H - B + 4, class: "axis" }, svg);
      svgText(svg, x(origin + t), H - 5, fmtDuration(t), { "text-anchor": "middle" });
    }
    svgEl("line", { x1: L, x2: W - R, y1: H - B, y2: H - B, class: "axis" }, svg);
    svgEl("line", { x1: L, x2: L, y1: plotTop, y2: H - B, class: "axis" }, svg);
    if (bands.length) {
      const g = svgEl("g", { class: "bands" }, svg);
      for (const b of bands) {
        const r = svgEl("rect", { x: x(b.t0), y: T, width: Math.max(x(b.t1) - x(b.t0), 0.5), height: bandH,
          fill: b.colour, "data-label": b.label }, g);
        svgEl("title", {}, r).textContent = `${b.label}: ${fmtDuration(b.t1 - b.t0)}`;
      }
    }
    for (const s of series) {
      const parts = [];
      let cur = [];
      for (let i = 0; i < s.t.length; i++) {
        const v = s.y[i];
        if (!Number.isFinite(v)) { if (cur.length) parts.push(cur); cur = []; continue; }
        if (cur.length && ((s.breakAbove !== undefined && Math.abs(v - s.y[i - 1]) > s.breakAbove)
          || (s.gapS !== undefined && s.t[i] - s.t[i - 1] > s.gapS))) {
          parts.push(cur); cur = [];
        }
        if (opts.steps && cur.length) cur.push(`${x(s.t[i]).toFixed(1)},${y(s.y[i - 1]).toFixed(1)}`);
        cur.push(`${x(s.t[i]).toFixed(1)},${y(v).toFixed(1)}`);
      }
      if (cur.length) parts.push(cur);
      for (const p of parts) {
        if (p.length === 1) { // a lone sample between two gaps: a dot, or it would not show at all
          const [cx, cy] = p[0].split(",");
          svgEl("circle", { cx, cy, r: 1.8, fill: s.colour, class: "lone", "data-series": s.name }, svg);
          continue;
        }
        svgEl("polyline", { points: p.join(" "), class: "series", stroke: s.colour, "data-series": s.name }, svg);
      }
    }
    if (series.length > 1 || opts.legend) {
      let lx = W - R - 8;
      for (const s of series.slice().reverse()) {
        const t = svgText(svg, lx, 12, s.name, { "text-anchor": "end" });
        t.style.fill = s.colour; // a style, not the attribute: the stylesheet's text colour would win
        lx -= (s.name.length * 6.5 + 14);
      }
    }
  }

  /** Log-log chart: series [{name, colour, x: [], y: [], lo?: [], hi?: []}], lines [{name, x: [], y: [], dash}]
   * (opts.lines, named together by opts.linesLabel in the legend). */
  function logLogChart(svg, series, opts) {
    clear(svg);
    const W = svg.clientWidth || 640, H = svg.clientHeight || 360;
    svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
    // B: room under the plot for the decade labels, low enough to clear the lowest y label at the corner, and
    // the axis title under them.
    const L = 64, R = 12, T = 22, B = 40;
    const xs = [], ys = [];
    for (const s of series.concat(opts.lines || [])) {
      s.x.forEach((v, i) => {
        const w = s.y[i];
        if (v > 0 && w > 0) { xs.push(v); ys.push(w); }
        if (s.lo && s.lo[i] > 0) ys.push(s.lo[i]);
        if (s.hi && s.hi[i] > 0) ys.push(s.hi[i]);
      });
    }
    if (!xs.length) { svgText(svg, W / 2, H / 2, "no data", { "text-anchor": "middle" }); return; }
    const lx0 = Math.floor(Math.log10(minOf(xs))), lx1 = Math.ceil(Math.log10(maxOf(xs)));
    const ly0 = Math.floor(Math.log10(minOf(ys))), ly1 = Math.ceil(Math.log10(maxOf(ys)));
    const X = (v) => L + ((Math.log10(v) - lx0) / Math.max(lx1 - lx0, 1)) * (W - L - R);
    const Y = (v) => H - B - ((Math.log10(v) - ly0) / Math.max(ly1 - ly0, 1)) * (H - B - T);
    if (opts.title) svgText(svg, L, 14, opts.title, { class: "title" });
    for (let e = lx0; e <= lx1; e++) {
      svgEl("line", { x1: X(10 ** e), x2: X(10 ** e), y1: T, y2: H - B, class: "gridline" }, svg);
      svgText(svg, X(10 ** e), H - B + 17, `1e${e}`, { "text-anchor": "middle" });
    }
    for (let e = ly0; e <= ly1; e++) {
      svgEl("line", { x1: L, x2: W - R, y1: Y(10 ** e), y2: Y(10 ** e), class: "gridline" }, svg);
      svgText(svg, L - 4, Y(10 ** e) + 4, `1e${e}`, { "text-anchor": "end" });
    }
    svgText(svg, (L + W - R) / 2, H - 6, opts.xLabel || "τ (s)", { "text-anchor": "middle" });
    svgText(svg, 12, (T + H - B) / 2, opts.yLabel || "", { transform: `rotate(-90 12 ${(T + H - B) / 2})`,
      "text-anchor": "middle" });
    svgEl("rect", { x: L, y: T, width: W - L - R, height: H - B - T, fill: "none", class: "axis" }, svg);
    for (const line of opts.lines || []) {
      const pts = line.x.map((v, i) => (v > 0 && line.y[i] > 0 ? `${X(v).toFixed(1)},${Y(line.y[i]).toFixed(1)}` : null))
        .filter(Boolean);
      if (pts.length) svgEl("polyline", { points: pts.join(" "), class: "series", stroke: line.colour || "#667085",
        "stroke-dasharray": line.dash || "5 4" }, svg);
    }
    let legendY = T + 14;
    for (const s of series) {
      const pts = [];
      s.x.forEach((v, i) => {
        if (!(v > 0 && s.y[i] > 0)) return;
        pts.push(`${X(v).toFixed(1)},${Y(s.y[i]).toFixed(1)}`);
        if (s.lo && s.hi && s.lo[i] > 0 && s.hi[i] > 0) {
          svgEl("line", { x1: X(v), x2: X(v), y1: Y(s.lo[i]), y2: Y(s.hi[i]), stroke: s.colour, "stroke-width": 1,
            opacity: 0.6 }, svg);
        }
      });
      svgEl("polyline", { points: pts.join(" "), class: "series", stroke: s.colour, "data-series": s.name }, svg);
      svgText(svg, W - R - 8, legendY, s.name, { "text-anchor": "end" }).style.fill = s.colour;
      legendY += 14;
    }
    // What the dashed lines are, under the series' names (the title alone would not fit a phone's width).
    if (opts.linesLabel && (opts.lines || []).length) svgText(svg, W - R - 8, legendY, opts.linesLabel, { "text-anchor": "end" });
  }

  return { svgEl, svgText, clear, niceStep, ticks, timeTicks, fmt, fmtDuration, modeColour, deviceColour, timeChart,
    logLogChart };
})();
