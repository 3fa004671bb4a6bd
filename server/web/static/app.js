/* The service's page: sign-in with an API token, sessions list, session view, Allan reports, model cards.
 *
 * Everything comes from the JSON API with "Authorization: Bearer <token>"; the token lives in this tab's
 * sessionStorage and never in a URL. Views are chosen by the URL fragment (#/sessions, #/session/ID,
 * #/reports, #/report/ID, #/models). Text from the server is only ever set with textContent. */
"use strict";

(() => {
  const TOKEN_KEY = "pdr.token";
  const API = "/api/v1";
  const LIVE_STATUSES = new Set(["pending", "processing", "empty"]);
  const RECENT_MS = 10 * 60 * 1000;
  /** Longest interval between two steps (s) drawn as a line: a stride takes about 1 s even at a slow walk,
   * so a longer interval is a stop, and the charts leave it blank rather than draw a line across it. */
  const STEP_GAP_S = 3;
  const FOOT_ROLES = new Set(["left_foot", "right_foot"]);
  const $ = (id) => document.getElementById(id);
  const enc = encodeURIComponent;
  const { fmt, fmtDuration } = Plot;

  /** Exposed for the browser tests: render timings (ms) of the last session view (``mapDrawMs``: its map's last
   * draw), which track it shows (``track.heading``: "smoothed" or "causal"; ``track.last``: [east_m, north_m] of its
   * last row), the geo-referenced map's track (``geo.start``: [lat, lon] of its first position), and the metric map
   * (``trackMap``: the TrackMap drawn, or null). */
  const page = { timings: {}, track: null, geo: null, trackMap: null };
  window.pdrPage = page;

  let generation = 0; // bumped on every navigation: late answers of an old view are dropped
  let pollTimer = null;
  let map = null; // the metric map of the open session (TrackMap: Leaflet, CRS.Simple)
  let geoMap = null; // the Leaflet map of a geo-referenced session
  let pageConfig = null; // GET /web/config.json: the map tile URL template and attribution (or nulls)
  let current = null; // the open session's state
  /** /modes entries drawn over the step-mode band (they cover time without steps). */
  const BAND_ENTRY_MODES = new Set(["standing", "elevator_up", "elevator_down", "escalator_up", "escalator_down"]);

  // -- API --------------------------------------------------------------------------------------
  class ApiError extends Error {
    constructor(status, code, message) {
      super(message);
      this.status = status;
      this.code = code;
    }

    /** A sentence for people: the server's message and the HTTP status. */
    readable(what) {
      const status = this.status ? ` (HTTP ${this.status}${this.code ? ", " + this.code : ""})` : "";
      return `${what ? what + ": " : ""}${this.message}${status}`;
    }
  }

  const token = () => sessionStorage.getItem(TOKEN_KEY);

  async function apiFetch(path, accept, method) {
    const tok = token();
    if (!tok) throw new ApiError(401, "unauthorized", "please sign in with your API token");
    let resp;
    try {
      resp = await fetch(path, {
        method: method || "GET",
        headers: { Authorization: `Bearer ${tok}`, Accept: accept || "application/json" },
        cache: "no-store", credentials: "omit", referrerPolicy: "no-referrer",
      });
    } catch (err) {
      throw new ApiError(0, "network", `the service could not be reached (${err.message})`);
    }
    if (!resp.ok) {
      let message = `${resp.status} ${resp.statusText || "error"}`, code = "";
      try {
        const body = await resp.json();
        if (body && body.error && body.error.message) { message = body.error.message; code = body.error.code || ""; }
      } catch (_) { /* not a JSON error body: keep the status line */ }
      const err = new ApiError(resp.status, code, message);
      if (resp.status === 401) signOut(err.readable("Your token was not accepted"));
      throw err;
    }
    return resp;
  }

  const apiJson = async (path) => (await apiFetch(path)).json();

  /** Track rows (objects) of a ``/track/columns`` answer (one array per column: compact and fast to serve). */
  function rowsOfColumns(body) {
    const c = body.columns, n = body.count, rows = new Array(n);
    for (let i = 0; i < n; i++) {
      rows[i] = { t_s: c.t_s[i], east_m: c.east_m[i], north_m: c.north_m[i], up_m: c.up_m[i], floor: c.floor[i],
        heading_deg: c.heading_deg[i], step_length_m: c.step_length_m[i], mode: c.mode[i], device: c.device[i],
        provisional: c.provisional ? c.provisional[i] : false };
    }
    return rows;
  }

  /** Download an API resource as a file (the token goes in the header, so a plain link cannot do it). */
  async function download(path, filename, accept) {
    const resp = await apiFetch(path, accept);
    const blob = await resp.blob();
    const url = URL.createObjectURL(blob);
    const a = document.createElement("a");
    a.href = url;
    a.download = filename;
    document.body.appendChild(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(url), 60000);
  }

  // -- messages and view switching --------------------------------------------------------------
  function showMessage(text, kind) {
    const box = $("message");
    box.textContent = text;
    box.className = `message ${kind || "error"}`;
    box.hidden = false;
  }

  function clearMessage() {
    $("message").hidden = true;
    $("message").textContent = "";
  }

  /** A notice for the view navigated to next (route() clears the message box on every navigation). */
  let nextNotice = null;
  function navigateWithNotice(hash, text) {
    nextNotice = text;
    if (location.hash === hash) route(); else location.hash = hash;
  }

  function reportError(err, what) {
    if (err instanceof ApiError) {
      if (err.status !== 401) showMessage(err.readable(what));
    } else {
      showMessage(`${what}: ${err && err.message ? err.message : err}`);
      console.error(err);
    }
  }

  function show(view) {
    for (const sec of document.querySelectorAll("main > .view")) sec.hidden = sec.id !== `view-${view}`;
    for (const a of document.querySelectorAll("#nav a")) {
      a.classList.toggle("active", a.dataset.view === view || a.dataset.view === view + "s");
    }
    $("nav").hidden = view === "signin";
  }

  function el(tag, attrs, text) {
    const node = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (k === "class") node.className = v; else node.setAttribute(k, v);
    }
    if (text !== undefined && text !== null) node.textContent = String(text);
    return node;
  }

  function clearNode(node) {
    while (node.firstChild) node.removeChild(node.firstChild);
  }

  function notAvailable(container, text) {
    clearNode(container);
    container.appendChild(el("p", { class: "not-available", "data-role": "not-available" }, text));
  }

  /** Take the metric map off the page (a new session is opened, or the user signs out). */
  function dropMap() {
    if (map) map.remove();
    map = null;
    page.trackMap = null;
    clearNode($("map"));
    delete $("map").dataset.points;
  }

  function stopPolling() {
    if (pollTimer) clearTimeout(pollTimer);
    pollTimer = null;
  }

  /** Forget the token and every piece of the previous user's data shown on the page. */
  function signOut(reason) {
    sessionStorage.removeItem(TOKEN_KEY);
    stopPolling();
    generation++;
    current = null;
    for (const id of ["session-title", "session-summary", "session-warnings", "truth-panel", "reports-body",
      "report-body", "models-body", "legend"]) clearNode($(id));
    for (const id of ["sessions-table", "batches-table"]) clearNode($(id).querySelector("tbody"));
    dropMap();
    for (const id of ["timeline", "steps-plot", "heading-plot"]) clearNode($(id));
    show("signin");
    if (reason) showMessage(reason); else clearMessage();
  }

  // -- routing ----------------------------------------------------------------------------------
  function route() {
    stopPolling();
    generation++;
    clearMessage();
    if (nextNotice) { showMessage(nextNotice, "info"); nextNotice = null; }
    if (!token()) { show("signin"); $("token").focus(); return; }
    const [view, ...rest] = (location.hash || "#/sessions").replace(/^#\/?/, "").split("/");
    const arg = rest.length ? decodeURIComponent(rest.join("/")) : "";
    switch (view) {
      // Both the singular and the plural form name one item (#/session/ID, #/sessions/ID).
      case "session": return arg ? openSession(arg) : showSessions();
      case "sessions": return arg ? openSession(arg) : showSessions();
      case "reports": return arg ? showReport(arg) : showReports();
      case "report": return arg ? showReport(arg) : showReports();
      case "models": return showModels();
      default: return showSessions();
    }
  }

  async function signIn(ev) {
    ev.preventDefault();
    const input = $("token");
    const candidate = input.value.trim();
    if (!candidate) return;
    sessionStorage.setItem(TOKEN_KEY, candidate);
    input.value = "";
    try {
      await apiFetch(`${API}/sessions`); // proves the token before showing anything
      route();
    } catch (err) {
      if (!(err instanceof ApiError && err.status === 401)) {
        sessionStorage.removeItem(TOKEN_KEY);
        reportError(err, "Could not sign in");
      }
    }
  }

  // -- sessions list ----------------------------------------------------------------------------
  function deviceText(devices) {
    if (!devices || !devices.length) return "–";
    return devices.map((d) => [d.model || d.platform || "device", d.role !== "phone" ? `(${d.role})` : ""]
      .filter(Boolean).join(" ")).join(", ");
  }

  function statusBadge(status, batches) {
    const span = el("span", { class: `status ${status}`, "data-role": "status" }, status);
    if (batches && Object.keys(batches).length) {
      span.title = Object.entries(batches).map(([k, v]) => `${v} ${k}`).join(", ") + " batches";
    }
    return span;
  }

  function warningsCell(warnings) {
    const td = el("td", { class: "warnings" });
    if (!warnings || !warnings.length) { td.textContent = "–"; return td; }
    const details = el("details");
    details.appendChild(el("summary", {}, `${warnings.length} warning${warnings.length > 1 ? "s" : ""}`));
    const ul = el("ul");
    for (const w of warnings) ul.appendChild(el("li", {}, w));
    details.appendChild(ul);
    details.addEventListener("click", (ev) => ev.stopPropagation());
    td.appendChild(details);
    return td;
  }

  async function showSessions() {
    show("sessions");
    const gen = generation;
    const refresh = async () => {
      let body;
      try {
        body = await apiJson(`${API}/sessions`);
      } catch (err) {
        if (gen === generation) reportError(err, "Could not load the sessions");
        return;
      }
      if (gen !== generation) return;
      renderSessions(body.sessions || []);
      // Live while something is uploading or processing; slower otherwise (new uploads still show up).
      const live = (body.sessions || []).some((s) => LIVE_STATUSES.has(s.status));
      pollTimer = setTimeout(refresh, live ? 1500 : 5000);
    };
    await refresh();
  }

  function renderSessions(sessions) {
    const tbody = $("sessions-table").querySelector("tbody");
    clearNode(tbody);
    $("sessions-empty").hidden = sessions.length > 0;
    const sorted = sessions.slice().sort((a, b) => String(b.created_at).localeCompare(String(a.created_at)));
    for (const s of sorted) {
      const tr = el("tr", { class: "clickable", "data-session": s.id });
      const name = el("td");
      const a = el("a", { href: `#/session/${enc(s.id)}` }, s.name || s.session_id || s.id);
      name.appendChild(a);
      tr.appendChild(name);
      tr.appendChild(el("td", {}, deviceText(s.devices)));
      tr.appendChild(el("td", {}, s.placement || "–"));
      tr.appendChild(el("td", {}, s.created_at ? new Date(s.created_at).toLocaleString() : "–"));
      tr.appendChild(el("td", {}, s.steps > 1 ? fmtDuration(s.duration_s) : "–"));
      tr.appendChild(el("td", { class: "num", "data-role": "distance" }, `${fmt(s.distance_m, 1)} m`));
      tr.appendChild(el("td", { class: "num", "data-role": "steps" }, s.steps));
      const st = el("td");
      st.appendChild(statusBadge(s.status, s.batches));
      tr.appendChild(st);
      tr.appendChild(warningsCell(s.warnings));
      tr.addEventListener("click", () => { location.hash = `#/session/${enc(s.id)}`; });
      tbody.appendChild(tr);
    }
    $("sessions-updated").textContent = `updated ${new Date().toLocaleTimeString()}`;
  }

  // -- session view -----------------------------------------------------------------------------
  /** The device whose track is "the" track: the fused/phone one, else the first. */
  function primaryDevice(devices) {
    return devices.find((d) => !FOOT_ROLES.has(d)) || devices[0];
  }

  function groupByDevice(rows) {
    const by = new Map();
    for (const r of rows) {
      const d = r.device || "phone";
      if (!by.has(d)) by.set(d, []);
      by.get(d).push(r);
    }
    for (const list of by.values()) list.sort((a, b) => a.t_s - b.t_s);
    return by;
  }

  /** Linear interpolation of a device's track (rows sorted by t_s) at time t; null outside its span. */
  function positionAt(rows, t) {
    if (!rows.length || t < rows[0].t_s || t > rows[rows.length - 1].t_s) return null;
    return positionNear(rows, t);
  }

  /** The track's position at time ``t`` as the scorers interpolate it (numpy's interp): linear between rows, the
   * first row's position before the track starts and the last row's after it ends; null without rows. */
  function positionNear(rows, t) {
    if (!rows.length) return null;
    if (t <= rows[0].t_s) return [rows[0].east_m, rows[0].north_m];
    if (t >= rows[rows.length - 1].t_s) return [rows[rows.length - 1].east_m, rows[rows.length - 1].north_m];
    let lo = 0, hi = rows.length - 1;
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (rows[mid].t_s <= t) lo = mid; else hi = mid;
    }
    const a = rows[lo], b = rows[hi];
    const w = b.t_s > a.t_s ? (t - a.t_s) / (b.t_s - a.t_s) : 0;
    return [a.east_m + w * (b.east_m - a.east_m), a.north_m + w * (b.north_m - a.north_m)];
  }

  async function openSession(id) {
    const gen = generation;
    const t0 = performance.now();
    page.timings = { start: t0 };
    show("session");
    $("session-title").textContent = "Loading…";
    $("session-body").hidden = false;
    dropMap();
    for (const svgId of ["timeline", "steps-plot", "heading-plot", "legend"]) clearNode($(svgId));
    $("dl-geojson").hidden = true; // until the session's detail says it has an origin
    clearNode($("session-summary"));
    clearNode($("session-warnings"));
    clearNode($("truth-panel"));
    $("geo-wrap").hidden = true;
    if (geoMap) { geoMap.pdrResize.disconnect(); geoMap.remove(); geoMap = null; }
    // The track first, alone: it is what the view is for, and the server answers it fastest without
    // the detail request competing for it; the header, landmarks and truth follow.
    let track;
    try {
      track = await apiJson(`${API}/sessions/${enc(id)}/track/columns`);
    } catch (err) {
      if (gen !== generation) return;
      $("session-title").textContent = "Session not available";
      $("session-body").hidden = true;
      dropMap();
      for (const svgId of ["timeline", "steps-plot", "heading-plot", "legend"]) clearNode($(svgId));
      clearNode($("batches-table").querySelector("tbody"));
      reportError(err, "Could not open the session");
      return;
    }
    if (gen !== generation) return;
    page.timings.fetched = performance.now() - t0;
    current = { id, detail: null, causal: rowsOfColumns(track), smoothed: null, smoothedNote: "", unsmoothed: "",
      version: 0, landmarks: [], truth: null };
    showRows();
    $("colour-by").value = current.byDevice.size > 1 ? "device" : "mode";
    setupFloorFilter();
    renderSessionData(false);
    page.timings.firstRender = performance.now() - t0;
    // Paint-inclusive time: the next animation frame comes after layout and paint of the new SVG.
    requestAnimationFrame(() => { page.timings.firstPaint = performance.now() - t0; });
    try {
      current.detail = await apiJson(`${API}/sessions/${enc(id)}`);
    } catch (err) {
      if (gen === generation) reportError(err, "Could not load the session's details");
      return;
    }
    if (gen !== generation) return;
    renderSessionHeader();
    loadExtras(gen);
    schedulePoll(gen, current.detail);
  }

  /** Poll while the session is processing or was updated in the last minutes (a phone streaming batches:
   * its status turns "done" between batches). */
  function schedulePoll(gen, detail) {
    if (LIVE_STATUSES.has(detail.status)) pollTimer = setTimeout(() => pollSession(gen), 1500);
    else if (Date.now() - Date.parse(detail.updated_at) < RECENT_MS) pollTimer = setTimeout(() => pollSession(gen), 2000);
  }

  async function loadExtras(gen) {
    const id = current.id;
    const [landmarks, truth, smoothed, modes, site] = await Promise.allSettled([apiJson(`${API}/sessions/${enc(id)}/landmarks`),
      apiJson(`${API}/sessions/${enc(id)}/truth`), loadSmoothed(), apiJson(`${API}/sessions/${enc(id)}/modes`), loadSite()]);
    if (gen !== generation) return;
    if (site.status === "fulfilled") current.site = site.value;
    else reportError(site.reason, "Could not load the session's floor plan");
    if (landmarks.status === "fulfilled") current.landmarks = landmarks.value.landmarks || [];
    // Stops, elevator and escalator rides have no steps: the band shows them from /modes (entries with an end).
    if (modes.status === "fulfilled") {
      current.stopEntries = (modes.value.modes || []).filter((m) => BAND_ENTRY_MODES.has(m.label) && m.t_end_s !== null);
    }
    if (truth.status === "fulfilled") current.truth = truth.value;
    else current.truthError = truth.reason;
    if (smoothed.status === "rejected") reportError(smoothed.reason, "Could not load the smoothed track");
    showRows();
    setupFloorFilter();
    renderSessionHeader();
    renderSessionData(true);
    page.timings.complete = performance.now() - page.timings.start;
    renderGeoMap(gen).catch((err) => { if (gen === generation) reportError(err, "Could not draw the session on the map"); });
  }

  async function loadConfig() {
    if (!pageConfig) {
      const resp = await fetch("/web/config.json", { cache: "no-cache" });
      pageConfig = resp.ok ? await resp.json() : { map: {} };
    }
    return pageConfig;
  }

  /** A geo-referenced session (its detail has an origin) on a real map: Leaflet (vendor/leaflet, from npm) on Web
   * Mercator with the server's GeoJSON of the track in longitude/latitude (the server converts from local metres, so
   * the page has no Earth model of its own), over the operator's tiles (PDR_MAP_TILE_URL) when configured. A session
   * in local metres has no such map: the metric map above (trackmap.js: Leaflet, CRS.Simple) is its map. */
  /** Leaflet notices a window resize, but not a box that changes size with the page's layout after it (a chart
   * redrawn, a scroll bar gone): the map is told of every change of its box's size (it then fires "resize"). */
  function watchBoxSize(leafletMap) {
    const observer = new ResizeObserver(() => leafletMap.invalidateSize({ pan: false }));
    observer.observe(leafletMap.getContainer());
    return observer;
  }

  async function renderGeoMap(gen) {
    const wrap = $("geo-wrap");
    const origin = current && current.detail && current.detail.origin;
    if (geoMap) { geoMap.pdrResize.disconnect(); geoMap.remove(); geoMap = null; }
    delete $("geomap").dataset.features;
    if (!origin || typeof L === "undefined") { wrap.hidden = true; return; }
    const [config, geo] = await Promise.all([loadConfig(),
      apiJson(`${API}/sessions/${enc(current.id)}/track?format=geojson&heading=${current.heading}`)]);
    if (gen !== generation) return;
    wrap.hidden = false;
    const tiles = config.map && config.map.tile_url;
    // A view before any layer: Leaflet's vector renderer needs the map's pixel bounds when a path is added.
    geoMap = L.map($("geomap"), { crs: L.CRS.EPSG3857, zoomSnap: 0.25 }).setView([origin.lat_deg, origin.lon_deg], 18);
    geoMap.pdrResize = watchBoxSize(geoMap);
    if (tiles) {
      L.tileLayer(tiles, { maxZoom: 22, maxNativeZoom: 19, attribution: config.map.attribution || "" }).addTo(geoMap);
    }
    const byDevice = geo.features.length > 1;
    const layer = L.geoJSON(geo, { style: (f) => ({ color: byDevice ? Plot.deviceColour(f.properties.device) : "#1f6feb",
      weight: 3, opacity: 0.9 }) }).addTo(geoMap);
    const lines = geo.features.filter((f) => f.geometry.coordinates.length);
    for (const f of lines) {
      const c = f.geometry.coordinates;
      L.circleMarker([c[0][1], c[0][0]], { radius: 6, color: "#067647", fillOpacity: 1, className: "geo-start" })
        .bindTooltip(`start (${f.properties.device})`).addTo(geoMap);
      L.circleMarker([c[c.length - 1][1], c[c.length - 1][0]], { radius: 6, color: "#b42318", fillOpacity: 1,
        className: "geo-end" }).bindTooltip(`end (${f.properties.device})`).addTo(geoMap);
    }
    if (lines.length) {
      // Fitted now, and again when the map's box changes size (a phone turned, a window resized) until the user
      // moves the map themselves. Not animated: Leaflet drops a new view asked for while a zoom animation runs.
      const fit = () => geoMap.fitBounds(layer.getBounds(), { padding: [24, 24], maxZoom: 21, animate: false });
      let moved = false;
      geoMap.on("dragstart", () => { moved = true; });
      geoMap.on("resize", () => { if (!moved) fit(); });
      fit();
    }
    const first = lines.length ? lines[0].geometry.coordinates[0] : null;
    page.geo = { start: first ? [first[1], first[0]] : null, features: geo.features.length };
    const el = $("geomap");
    el.dataset.features = String(geo.features.length);
    el.dataset.points = String(geo.features.reduce((n, f) => n + f.geometry.coordinates.length, 0));
    el.dataset.tiles = tiles ? "yes" : "no";
    $("geo-note").textContent = `Geo-referenced: the start is at ${origin.lat_deg.toFixed(6)}°, ${origin.lon_deg.toFixed(6)}°.`
      + (tiles ? "" : " No map tiles are configured on this server (PDR_MAP_TILE_URL), so the map has no background.");
  }

  /** The floor plans of the uploaded site the session names, when its track is in the site's frame (the session
   * has a start: map-matched online); null otherwise. */
  async function loadSite() {
    const p = current.detail && current.detail.processing;
    if (!p || !p.site_id || !p.start) return null;
    return apiJson(`${API}/sessions/${enc(current.id)}/site`);
  }

  /** The floor plan to draw under the track: the floor chosen in the floor filter, else the current floor (the
   * last step's; before any step, the start's), else the site's only floor. */
  function planLayer() {
    const site = current.site;
    if (!site || !site.floors || !site.floors.length) return null;
    const sel = $("floor-filter").value;
    let floor = sel === "" ? null : Number(sel);
    if (floor === null) {
      const rows = current.byDevice.get(primaryDevice([...current.byDevice.keys()])) || [];
      const last = rows.length ? rows[rows.length - 1] : null;
      if (last && last.floor !== null && last.floor !== undefined) floor = Math.round(last.floor);
      else if (site.start && site.start.floor !== null) floor = site.start.floor;
    }
    const plan = site.floors.find((f) => f.floor === floor) || (site.floors.length === 1 ? site.floors[0] : null);
    if (!plan) return null;
    return { floor: plan.floor, polygons: plan.walkable.coordinates, name: site.name || "" };
  }

  const wantSmoothed = () => $("heading-mode").value === "smoothed";
  const isLive = () => !current.detail || LIVE_STATUSES.has(current.detail.status);

  const hasPhone = () => current.causal.some((r) => r.device === "phone");

  /** Fetch the track with its headings smoothed over the whole session (``?heading=smoothed``) into
   * ``current.smoothed``, when it is wanted, the session has phone steps (the smoother's subject) and is not
   * processing (smoothing revises every row, so a live session shows its rows as streamed). When the server
   * smoothed no device (``smoothed_devices`` empty; its notes say why), ``current.unsmoothed`` keeps the reason. An answer older than
   * the rows it would replace is dropped. */
  async function loadSmoothed() {
    if (!current || !wantSmoothed() || current.smoothed || current.unsmoothed || !hasPhone() || isLive()) return;
    const { id, version } = current;
    const body = await apiJson(`${API}/sessions/${enc(id)}/track/columns?heading=smoothed`);
    if (!current || current.id !== id || current.version !== version) return;
    const notes = body.heading_notes || [];
    const smoothedNotes = (body.smoothed_devices || []).map((d) => notes.find((n) => n.startsWith(`${d}: `)) || d);
    if (smoothedNotes.length) {
      current.smoothed = rowsOfColumns(body);
      current.smoothedNote = smoothedNotes.join("; ");
    } else {
      current.unsmoothed = notes.join("; ") || "the server did not smooth it";
    }
  }

  /** The rows to draw: the smoothed track when it is wanted and loaded, else the rows as streamed. */
  function showRows() {
    const smoothed = wantSmoothed() && current.smoothed !== null;
    current.rows = smoothed ? current.smoothed : current.causal;
    current.heading = smoothed ? "smoothed" : "causal";
    current.byDevice = groupByDevice(current.rows);
    $("heading-mode").disabled = !hasPhone();
    const last = current.rows[current.rows.length - 1];
    page.track = { heading: current.heading, last: last ? [last.east_m, last.north_m] : null };
  }

  /** What the Heading part of the summary says about the track drawn. */
  function headingText() {
    if (current.heading === "smoothed") return current.smoothedNote;
    if (!hasPhone()) return "from the shoe IMUs (smoothing applies to phone tracks)";
    if (wantSmoothed() && isLive()) return "as streamed (smoothed once processing ends)";
    if (wantSmoothed() && current.unsmoothed) return `as streamed (${current.unsmoothed})`;
    return "as streamed";
  }

  async function changeHeading() {
    if (!current) return;
    const gen = generation;
    try {
      await loadSmoothed();
    } catch (err) {
      if (gen === generation) reportError(err, "Could not load the smoothed track");
    }
    if (gen !== generation || !current) return;
    showRows();
    setupFloorFilter();
    if (current.detail) renderSessionHeader();
    renderSessionData(true);
    renderGeoMap(gen).catch((err) => { if (gen === generation) reportError(err, "Could not draw the session on the map"); });
  }

  /** Poll while uploading: each device's new rows with ?device=&since= (its last time), and the status. */
  async function pollSession(gen) {
    if (gen !== generation || !current) return;
    const id = current.id;
    try {
      const detail = await apiJson(`${API}/sessions/${enc(id)}`);
      const roles = new Set([...(detail.devices || []).map((d) => d.role), ...current.byDevice.keys()]);
      // Provisional rows (the processor's tail) are replaced by the next batch: ask from each device's last
      // final row and swap the tail; redraw only when something differs.
      const finals = current.causal.filter((r) => !r.provisional);
      const finalsBy = groupByDevice(finals);
      const fresh = [];
      for (const role of roles) {
        const mine = finalsBy.get(role) || [];
        const since = mine.length ? `&since=${mine[mine.length - 1].t_s}` : "";
        const body = await apiJson(`${API}/sessions/${enc(id)}/track/columns?device=${enc(role)}${since}`);
        if (gen !== generation) return;
        for (const r of rowsOfColumns(body)) fresh.push(r);
      }
      const key = (rows) => JSON.stringify(rows.map((r) => [r.device, r.t_s, r.east_m, r.north_m, r.provisional]));
      const changed = key(fresh) !== key(current.causal.filter((r) => r.provisional));
      if (changed) {
        // New rows change the whole smoothed track: it is fetched again once processing ends (loadExtras).
        current.causal = finals.concat(fresh);
        current.smoothed = null;
        current.unsmoothed = "";
        current.version += 1;
      }
      const added = changed ? 1 : 0;
      if (gen !== generation) return;
      current.detail = detail;
      renderSessionHeader();
      if (added !== 0) {
        showRows();
        setupFloorFilter();
        renderSessionData(true);
      }
      if (added !== 0 && !LIVE_STATUSES.has(detail.status)) loadExtras(gen);
      schedulePoll(gen, detail);
    } catch (err) {
      if (gen === generation) reportError(err, "Live update stopped");
    }
  }

  /** The session's processing options in a few words ("" when there are none). */
  function processingText(p) {
    if (!p) return "";
    const out = [];
    if (p.site) out.push(`site ${p.site.name ? `"${p.site.name}" ` : ""}(${p.site.landmarks.length} landmarks)`);
    if (p.site_id) {
      out.push(p.start ? `uploaded site, map-matched from (${p.start.slice(0, 2).map((v) => fmt(v, 1)).join(", ")}) m`
        + (p.start.length > 2 ? ` on floor ${p.start[2]}` : "") : "uploaded site (floor altitudes)");
    }
    if (p.calibration) out.push("step-length calibration");
    if (p.foot && p.foot.zaru) out.push("gyro bias by zero angular-rate updates");
    return out.join(", ");
  }

  function renderSessionHeader() {
    const d = current.detail;
    $("session-title").textContent = d.name || d.session_id || d.id;
    // GeoJSON (RFC 7946) is longitude/latitude: only a session with an origin has one (the API answers 409).
    $("dl-geojson").hidden = !d.origin;
    const summary = $("session-summary");
    clearNode(summary);
    const part = (label, value, role) => {
      const span = el("span", role ? { "data-role": role } : {});
      span.appendChild(el("strong", {}, `${label}: `));
      span.appendChild(document.createTextNode(value));
      summary.appendChild(span);
    };
    const st = el("span");
    st.appendChild(el("strong", {}, "Status: "));
    st.appendChild(statusBadge(d.status, d.batches));
    summary.appendChild(st);
    part("Device", deviceText(d.devices));
    part("Placement", d.placement || "–");
    const processing = processingText(d.processing);
    if (processing) part("Processing", processing, "processing");
    part("Start", d.created_at ? new Date(d.created_at).toLocaleString() : "–");
    part("Duration", fmtDuration(d.duration_s));
    part("Distance", `${fmt(d.distance_m, 1)} m`);
    part("Steps", String(d.steps), "steps");
    part("Heading", headingText(), "heading");
    const warn = $("session-warnings");
    clearNode(warn);
    if (d.warnings && d.warnings.length) {
      const box = el("div", { class: "warn-box" });
      box.appendChild(el("strong", {}, `Warnings (${d.warnings.length})`));
      const ul = el("ul");
      for (const w of d.warnings) ul.appendChild(el("li", {}, w));
      box.appendChild(ul);
      warn.appendChild(box);
    }
    const tbody = $("batches-table").querySelector("tbody");
    clearNode(tbody);
    for (const b of d.batch_list || []) {
      const tr = el("tr");
      tr.appendChild(el("td", {}, b.batch_id));
      tr.appendChild(el("td", {}, b.device_role));
      tr.appendChild(el("td", {}, b.format));
      tr.appendChild(el("td", { class: "num" }, b.size_bytes < 1024 ? `${b.size_bytes} B` : `${fmt(b.size_bytes / 1024, 1)} KiB`));
      tr.appendChild(el("td", {}, b.received_at ? new Date(b.received_at).toLocaleString() : "–"));
      const st = el("td");
      st.appendChild(statusBadge(b.status));
      tr.appendChild(st);
      tr.appendChild(el("td", {}, b.error || ""));
      tbody.appendChild(tr);
    }
  }

  function setupFloorFilter() {
    const select = $("floor-filter");
    const floors = new Set();
    for (const r of current.rows) if (r.floor !== null && r.floor !== undefined) floors.add(Math.round(r.floor));
    const key = [...floors].sort((a, b) => a - b).join(",");
    if (select.dataset.floors === key) return;
    const keep = select.value;
    select.dataset.floors = key;
    clearNode(select);
    select.appendChild(el("option", { value: "" }, "all"));
    for (const f of [...floors].sort((a, b) => a - b)) select.appendChild(el("option", { value: String(f) }, String(f)));
    select.value = floors.has(Number(keep)) && keep !== "" ? keep : "";
    select.disabled = floors.size < 2;
  }

  /** Track layers for the map: per device, polylines split where the colour changes or the floor is hidden. */
  function trackLayers(byDeviceRows) {
    const floorSel = $("floor-filter").value;
    const floor = floorSel === "" ? null : Number(floorSel);
    const byDevice = $("colour-by").value === "device";
    const tracks = [];
    for (const [device, rows] of byDeviceRows) {
      const segments = [];
      let seg = null, prev = null;
      for (const r of rows) {
        const visible = floor === null || (r.floor !== null && r.floor !== undefined && Math.round(r.floor) === floor);
        if (!visible) { seg = null; prev = null; continue; }
        const mode = r.mode || "unknown";
        const colour = byDevice ? Plot.deviceColour(device) : Plot.modeColour(mode);
        if (!seg || seg.colour !== colour) {
          seg = { colour, mode: byDevice ? device : mode, coords: [], count: 0 };
          if (prev) seg.coords.push(prev.east_m, prev.north_m); // joins the previous segment
          segments.push(seg);
        }
        seg.coords.push(r.east_m, r.north_m);
        seg.count++;
        prev = r;
      }
      tracks.push({ device, foot: FOOT_ROLES.has(device) && byDeviceRows.size > 1,
        segments: segments.map((s) => ({ colour: s.colour, mode: s.mode, count: s.count, xy: Float64Array.from(s.coords) })) });
    }
    return tracks;
  }

  function truthPoints() {
    const t = current.truth;
    if (!t || !t.truth) return [];
    const pts = [];
    for (const set of t.truth) {
      for (const p of set.points || []) pts.push(Object.assign({ kind: set.kind, frame: set.frame || "enu" }, p));
    }
    pts.sort((a, b) => a.t_s - b.t_s);
    return pts;
  }

  /**
   * The tracks as the scorers of ``pdr eval`` compare them with the truth (pdr.evaluation.scoring): rows
   * before the first truth point dropped, the rest translated so that the primary track's position at that
   * time is the first truth point; in a ``map`` frame (a floor plan, not north-aligned) also rotated about
   * it by the least-squares angle over all truth points (``waypoint_errors``). Positions at truth times outside
   * the track's span are its first or last position, as numpy's interp gives the scorers. Null without a track.
   */
  function alignToTruth(primary, truth) {
    const rows = current.byDevice.get(primary) || [];
    const first = truth[0];
    const est0 = first ? positionNear(rows, first.t_s) : null;
    if (!est0) return null;
    let angle = 0;
    if (first.frame === "map") {
      let cross = 0, dot = 0;
      for (const p of truth) {
        const est = positionNear(rows, p.t_s);
        if (!est) continue;
        const rx = est[0] - est0[0], ry = est[1] - est0[1], gx = p.east_m - first.east_m, gy = p.north_m - first.north_m;
        cross += rx * gy - ry * gx;
        dot += rx * gx + ry * gy;
      }
      angle = Math.atan2(cross, dot);
    }
    const c = Math.cos(angle), s = Math.sin(angle);
    const move = (r) => {
      const dx = r.east_m - est0[0], dy = r.north_m - est0[1];
      return Object.assign({}, r, { east_m: first.east_m + c * dx - s * dy, north_m: first.north_m + s * dx + c * dy });
    };
    const out = new Map();
    for (const [device, list] of current.byDevice) {
      const kept = [];
      const at = positionNear(list, first.t_s);
      if (at) kept.push(move(Object.assign({}, list[0], { t_s: first.t_s, east_m: at[0], north_m: at[1] })));
      for (const r of list) if (r.t_s > first.t_s) kept.push(move(r));
      if (kept.length) out.set(device, kept);
    }
    return { byDevice: out, t0: first.t_s, angleDeg: (angle * 180) / Math.PI, frame: first.frame };
  }

  function renderSessionData(keepView) {
    const devices = [...current.byDevice.keys()];
    const primary = primaryDevice(devices);
    const truth = truthPoints();
    const aligned = truth.length ? alignToTruth(primary, truth) : null;
    const drawn = aligned ? aligned.byDevice : current.byDevice;
    const primaryRows = drawn.get(primary) || [];
    const markers = [];
    if (primaryRows.length) {
      const a = primaryRows[0], b = primaryRows[primaryRows.length - 1];
      markers.push({ e: a.east_m, n: a.north_m, cls: "marker start", px: 6, title: `start (${primary})` });
      markers.push({ e: b.east_m, n: b.north_m, cls: "marker end", px: 6, title: `end (${primary})` });
    }
    for (const lm of current.landmarks) {
      const rows = drawn.get(lm.device) || primaryRows;
      const pos = Number.isFinite(lm.east_m) && Number.isFinite(lm.north_m) ? [lm.east_m, lm.north_m] : positionAt(rows, lm.t_s);
      if (pos) markers.push({ e: pos[0], n: pos[1], cls: "landmark", px: 5, title: `${lm.label || "landmark"} at ${fmt(lm.t_s, 1)} s` });
    }
    const errors = [];
    const errorT = [], errorM = [];
    // As the scorers: the first truth point is where the track starts, so the errors are those of points 2..K.
    for (const p of aligned ? truth.slice(1) : []) {
      const est = positionNear(primaryRows, p.t_s);
      if (!est) continue;
      errorT.push(p.t_s);
      errorM.push(Math.hypot(est[0] - p.east_m, est[1] - p.north_m));
      errors.push([p.east_m, p.north_m, est[0], est[1]]);
    }
    if (truth.length <= 500) { // under the start and end markers: the track starts at the first truth point
      const points = truth.map((p) => ({ e: p.east_m, n: p.north_m, cls: "truth-point", px: 4, title: `truth ${p.kind} at ${fmt(p.t_s, 1)} s` }));
      markers.unshift(...points);
    }
    if (!map) page.trackMap = map = new TrackMap($("map"), $("scale-bar"));
    const step = Math.max(1, Math.ceil(errors.length / 500));
    current.plan = planLayer();
    const drawStart = performance.now();
    map.draw({ plan: current.plan, tracks: trackLayers(drawn), truth: truth.map((p) => ({ e: p.east_m, n: p.north_m })),
      errors: errors.filter((_, i) => i % step === 0), markers,
      empty: current.detail && LIVE_STATUSES.has(current.detail.status) ? "waiting for the first track points…" : "this session has no track" },
    keepView);
    page.timings.mapDrawMs = performance.now() - drawStart; // the last draw of the map (ms)
    renderLegend(truth.length > 0);
    const span = renderCharts(primary);
    renderTruthPanel(truth, errorT, errorM, primary, aligned, span);
  }

  function renderLegend(hasTruth) {
    const legend = $("legend");
    clearNode(legend);
    const item = (colour, label, round) => {
      const div = el("div", { class: "item" });
      const sw = el("span", { class: round ? "swatch round" : "swatch" });
      sw.style.background = colour;
      div.appendChild(sw);
      div.appendChild(el("span", {}, label));
      legend.appendChild(div);
    };
    if ($("colour-by").value === "device") {
      for (const d of current.byDevice.keys()) item(Plot.deviceColour(d), d);
    } else {
      const modes = new Set(current.rows.map((r) => r.mode || "unknown"));
      for (const m of current.stopEntries || []) modes.add(m.label);
      for (const m of modes) item(Plot.modeColour(m), m);
      if (current.byDevice.size > 1) legend.appendChild(el("div", { class: "muted" }, "dashed: single foot"));
    }
    if (current.plan) {
      const div = el("div", { class: "item", "data-role": "plan-legend" });
      div.appendChild(el("span", { class: "swatch plan" }));
      div.appendChild(el("span", {}, `walkable area, floor ${current.plan.floor}`));
      legend.appendChild(div);
    }
    item("#12b76a", "start", true);
    item("#d92d20", "end", true);
    if (current.landmarks.length) item("#f79009", "landmark", true);
    if (hasTruth) item("#111", "ground truth (– – –), error in red");
  }

  /** Mode, step-length and heading charts on the session's time axis; returns that axis {tMin, tMax}. */
  function renderCharts(primary) {
    const rows = current.byDevice.get(primary) || [];
    const tMin = current.rows.length ? Math.min(...[...current.byDevice.values()].map((r) => r[0].t_s)) : undefined;
    const tMax = current.rows.length ? Math.max(...[...current.byDevice.values()].map((r) => r[r.length - 1].t_s)) : undefined;
    // Motion mode as a band of runs; floor as a step line.
    const bands = [];
    for (let i = 0; i < rows.length; i++) {
      const mode = rows[i].mode || "unknown";
      const t1 = i + 1 < rows.length ? rows[i + 1].t_s : rows[i].t_s;
      const last = bands[bands.length - 1];
      if (last && last.label === mode) last.t1 = t1;
      else bands.push({ t0: rows[i].t_s, t1, label: mode, colour: Plot.modeColour(mode) });
    }
    for (const m of current.stopEntries || []) {
      if (m.device && m.device !== primary) continue;
      const label = m.floors ? `${m.label} (${m.floors} floor${m.floors === 1 ? "" : "s"})` : m.label;
      bands.push({ t0: m.t_s, t1: m.t_end_s, label, colour: Plot.modeColour(m.label) });
    }
    const floorsKnown = rows.some((r) => r.floor !== null && r.floor !== undefined);
    Plot.timeChart($("timeline"), floorsKnown ? [{ name: "floor", colour: "#344054", t: rows.map((r) => r.t_s),
      y: rows.map((r) => (r.floor === null ? NaN : r.floor)) }] : [],
    { title: `motion mode (band) and floor${floorsKnown ? "" : " (no floor estimate)"}`, bands, steps: true, tMin, tMax,
      yMin: floorsKnown ? undefined : 0, yMax: floorsKnown ? undefined : 1, empty: "no track yet",
      yFormat: (v) => (Number.isInteger(v) ? String(v) : "") });
    const series = (key) => [...current.byDevice].map(([device, r]) => ({
      name: device, colour: current.byDevice.size > 1 ? Plot.deviceColour(device) : "#1f6feb",
      t: r.map((x) => x.t_s), y: r.map((x) => (x[key] === null || x[key] === undefined ? NaN : x[key])),
      breakAbove: key === "heading_deg" ? 180 : undefined, gapS: STEP_GAP_S,
    }));
    Plot.timeChart($("steps-plot"), series("step_length_m"), { title: "step length (m)", tMin, tMax, empty: "no steps yet" });
    Plot.timeChart($("heading-plot"), series("heading_deg"), { title: "heading (° clockwise from north)", tMin, tMax,
      yMin: 0, yMax: 360, empty: "no steps yet" });
    return { tMin, tMax };
  }

  function renderTruthPanel(truth, errorT, errorM, primary, aligned, span) {
    const panel = $("truth-panel");
    clearNode(panel);
    if (current.truthError) {
      const e = current.truthError;
      notAvailable(panel, e instanceof ApiError ? e.readable("Ground truth is not available") : String(e));
      return;
    }
    if (!current.truth) { panel.appendChild(el("p", { class: "muted" }, "Loading ground truth…")); return; }
    const problems = (current.truth.truth || []).filter((s) => s.error).map((s) => s.error);
    for (const p of problems) panel.appendChild(el("p", { class: "warn-box" }, `Truth could not be read: ${p}`));
    if (!truth.length) {
      panel.appendChild(el("p", { class: "muted", "data-role": "no-truth" },
        "No ground truth in this session (uploaded logs with surveyed landmarks or waypoints carry it)."));
      return;
    }
    const stats = el("p", { class: "stats", "data-role": "truth-stats" });
    const kinds = [...new Set(truth.map((p) => p.kind))].join(", ");
    const add = (label, value) => {
      const s = el("span");
      s.appendChild(el("strong", {}, `${label}: `));
      s.appendChild(document.createTextNode(value));
      stats.appendChild(s);
    };
    add("Truth points", `${truth.length} (${kinds})`);
    if (aligned) {
      const how = aligned.frame === "map" ? `, rotated by ${fmt(aligned.angleDeg, 1)}° (map frame)` : "";
      add("Track", `starts at the first truth point (${fmt(aligned.t0, 1)} s)${how}, as pdr eval scores it`);
    }
    if (errorM.length) {
      const mean = errorM.reduce((a, b) => a + b, 0) / errorM.length;
      const rms = Math.sqrt(errorM.reduce((a, b) => a + b * b, 0) / errorM.length);
      add(`Horizontal error of ${primary} (${errorM.length} later points)`, "");
      add("mean", `${fmt(mean, 2)} m`);
      add("RMS", `${fmt(rms, 2)} m`);
      add("max", `${fmt(errorM.reduce((a, b) => Math.max(a, b), 0), 2)} m`);
      add("last", `${fmt(errorM[errorM.length - 1], 2)} m`);
    } else {
      add("Error", "no truth point falls within the track's time span");
    }
    panel.appendChild(stats);
    if (errorM.length) {
      const svg = Plot.svgEl("svg", { class: "chart", id: "error-plot" }, panel);
      Plot.timeChart(svg, [{ name: "error", colour: "#d92d20", t: errorT, y: errorM }],
        { title: "horizontal error (m) against time", yMin: 0, tMin: span.tMin, tMax: span.tMax });
    }
  }

  // -- reports and models -----------------------------------------------------------------------
  const MISSING = new Set([404, 405, 501]);

  async function showReports() {
    show("reports");
    const gen = generation;
    const body = $("reports-body");
    notAvailable(body, "Loading…");
    let data;
    try {
      data = await apiJson(`${API}/reports`);
    } catch (err) {
      if (gen !== generation) return;
      if (err instanceof ApiError && MISSING.has(err.status)) {
        notAvailable(body, `Allan reports are not available on this server (GET ${API}/reports answered ${err.status}).`);
      } else {
        notAvailable(body, err instanceof ApiError ? err.readable("Could not load the reports") : String(err));
      }
      return;
    }
    if (gen !== generation) return;
    const reports = Array.isArray(data) ? data : data.reports || [];
    clearNode(body);
    if (!reports.length) {
      body.appendChild(el("p", { class: "muted" }, `No reports yet: POST a static log to ${API}/reports/allan.`));
      return;
    }
    const table = el("table", { class: "grid" });
    const head = el("tr");
    for (const h of ["Recording", "Kind", "Created", "Status"]) head.appendChild(el("th", {}, h));
    table.appendChild(el("thead")).appendChild(head);
    const tbody = table.appendChild(el("tbody"));
    for (const r of reports) {
      const tr = el("tr", { class: "clickable" });
      const td = el("td");
      td.appendChild(el("a", { href: `#/report/${enc(r.id)}`, title: `report ${r.id}` }, r.source || r.source_name || r.id));
      tr.appendChild(td);
      tr.appendChild(el("td", {}, r.kind || "allan"));
      tr.appendChild(el("td", {}, r.created_at ? new Date(r.created_at).toLocaleString() : "–"));
      const st = el("td");
      st.appendChild(statusBadge(r.status || "done"));
      tr.appendChild(st);
      tr.addEventListener("click", () => { location.hash = `#/report/${enc(r.id)}`; });
      tbody.appendChild(tr);
    }
    body.appendChild(table);
  }

  const ALLAN_UNITS = {
    gyro: { adev: "rad/s", N: "rad/√s", B: "rad/s", K: "rad/s/√s", Q: "rad", R: "rad/s²" },
    acc: { adev: "m/s²", N: "m/s/√s", B: "m/s²", K: "m/s²/√s", Q: "m/s", R: "m/s³" },
  };
  const AXIS_COLOURS = { x: "#d92d20", y: "#12b76a", z: "#1f6feb" };

  /** The report's sensors: {gyro: {x: {tau_s, adev, N, ...}, ...}, acc: ...} at the top or under "sensors". */
  function reportSensors(report) {
    const root = report && typeof report.sensors === "object" ? report.sensors : report || {};
    const out = [];
    for (const [name, value] of Object.entries(root)) {
      if (!value || typeof value !== "object") continue;
      const axesRoot = value.axes && typeof value.axes === "object" ? value.axes : value;
      const axes = Object.entries(axesRoot).filter(([, a]) => a && Array.isArray(a.tau_s) && Array.isArray(a.adev));
      if (axes.length) out.push({ name, value, axes });
    }
    return out;
  }

  const TERMS = ["N", "B", "K", "Q", "R"];
  /** The paper behind the grade table (Table 1) and the PDR impact (Tables 3-4), as the reports cite it. */
  const REFERENCE_SHORT = "Collin et al. (2019)";

  /** One sensor of an Allan report: log-log curves with intervals and the fitted model, terms, grade, impact. */
  function renderAllanSensor(body, s) {
    const units = Object.assign({}, ALLAN_UNITS[s.name] || {}, s.value.term_units || {});
    const adevUnit = s.value.unit || units.adev || "";
    body.appendChild(el("h2", {}, s.name));
    const svg = Plot.svgEl("svg", { class: "loglog", "data-sensor": s.name }, body);
    const colour = (axis) => AXIS_COLOURS[axis] || Plot.deviceColour(axis);
    // Drawn at the element's size; drawn again when the window's size changes (redrawOnResize).
    svg.pdrRedraw = () => Plot.logLogChart(svg, s.axes.map(([axis, a]) => ({
      name: axis, colour: colour(axis), x: a.tau_s, y: a.adev, lo: a.adev_lo, hi: a.adev_hi,
    })), {
      title: `${s.name}: overlapping Allan deviation`, yLabel: `σ(τ) ${adevUnit}`, linesLabel: "– – fitted noise model",
      lines: s.axes.filter(([, a]) => a.fit && Array.isArray(a.fit.model_adev))
        .map(([axis, a]) => ({ x: a.tau_s, y: a.fit.model_adev, colour: colour(axis), dash: "5 4" })),
    });
    svg.pdrRedraw();
    const table = el("table", { class: "grid terms" });
    const head = el("tr");
    head.appendChild(el("th", {}, "axis"));
    for (const term of TERMS) head.appendChild(el("th", { class: "num" }, `${term}${units[term] ? ` (${units[term]})` : ""}`));
    table.appendChild(el("thead")).appendChild(head);
    const tbody = table.appendChild(el("tbody"));
    for (const [axis, a] of s.axes) {
      const tr = el("tr");
      tr.appendChild(el("td", {}, axis));
      for (const term of TERMS) {
        const v = a[term] && typeof a[term] === "object" ? a[term].value : a[term];
        const bound = a.fit && a.fit.upper_bound ? a.fit.upper_bound[term] : null;
        const td = el("td", { class: "num" }, Number.isFinite(v) ? v.toExponential(3)
          : Number.isFinite(bound) ? `not resolved (< ${bound.toExponential(2)})` : "not resolved");
        if (!Number.isFinite(v) && a.fit && a.fit.reason && a.fit.reason[term]) td.title = a.fit.reason[term];
        tr.appendChild(td);
      }
      tbody.appendChild(tr);
    }
    body.appendChild(table);
    const summary = {};
    for (const k of ["unit", "rate_hz", "duration_s", "n_samples"]) if (s.value[k] !== undefined) summary[k] = s.value[k];
    if (Object.keys(summary).length) body.appendChild(keyValues(summary));
    const grade = s.value.grade;
    if (grade && Array.isArray(grade.calls) && grade.calls.length) {
      body.appendChild(el("h3", { "data-role": "grade" }, `Grade: ${grade.overall || "–"} (Table 1 of ${REFERENCE_SHORT}; the worst over axes and parameters)`));
      const t = el("table", { class: "grid grade" });
      const h = el("tr");
      for (const c of ["axis", "parameter", "measured", "unit", "grade"]) h.appendChild(el("th", {}, c));
      t.appendChild(el("thead")).appendChild(h);
      const tb = t.appendChild(el("tbody"));
      for (const c of grade.calls) {
        const r = el("tr");
        for (const cell of [c.axis || "–", String(c.parameter).replace(/_/g, " "), fmt(c.value, 3), c.unit, c.grade]) {
          r.appendChild(el("td", {}, cell));
        }
        tb.appendChild(r);
      }
      body.appendChild(t);
      if (grade.note || grade.reference) {
        body.appendChild(el("p", { class: "muted citation" }, `${grade.note ? grade.note + ". " : ""}${grade.reference ? `Reference: ${grade.reference}.` : ""}`));
      }
    }
    const impact = s.value.pdr_impact;
    if (impact && impact.axes && Object.keys(impact.axes).length) {
      body.appendChild(el("h3", {}, "Predicted PDR impact of the bias instability"));
      const t = el("table", { class: "grid impact" });
      const h = el("tr");
      for (const c of ["axis", "bias (°/h)", "2 % position error", "3 % position error", "3° heading error"]) h.appendChild(el("th", {}, c));
      t.appendChild(el("thead")).appendChild(h);
      const tb = t.appendChild(el("tbody"));
      for (const [axis, v] of Object.entries(impact.axes)) {
        const r = el("tr");
        const readable = v.readable || {};
        for (const cell of [axis, fmt(v.bias_deg_h, 3), readable["2pct"] || fmtDuration(v.time_to_2pct_s),
          readable["3pct"] || fmtDuration(v.time_to_3pct_s), readable["3deg"] || fmtDuration(v.time_to_3deg_s)]) {
          r.appendChild(el("td", {}, cell));
        }
        tb.appendChild(r);
      }
      body.appendChild(t);
    }
  }

  async function showReport(id) {
    show("report");
    const gen = generation;
    const body = $("report-body");
    notAvailable(body, "Loading…");
    $("report-title").textContent = "Allan report";
    let data;
    try {
      data = await apiJson(`${API}/reports/${enc(id)}`);
    } catch (err) {
      if (gen !== generation) return;
      notAvailable(body, err instanceof ApiError && MISSING.has(err.status) && err.code !== "not_found"
        ? `Allan reports are not available on this server (HTTP ${err.status}).`
        : err instanceof ApiError ? err.readable("Could not load the report") : String(err));
      return;
    }
    if (gen !== generation) return;
    let report = data.result !== undefined ? data.result : data.report !== undefined ? data.report : data;
    if (typeof report === "string") {
      try { report = JSON.parse(report); } catch (_) { report = { text: report }; }
    }
    clearNode(body);
    // Named by the recording's file: the uploaded name, else the file name of the recording's source.
    const rec = report && report.recording;
    const fileName = (p) => String(p || "").replace(/\\/g, "/").replace(/\/+$/, "").split("/").pop();
    const name = fileName(data.source) || (rec && fileName(rec.source)) || "recording";
    $("report-title").textContent = `Allan report: ${name}`;
    if (data.created_at) body.appendChild(el("p", { class: "muted" }, `created ${new Date(data.created_at).toLocaleString()}`));
    if (data.status && data.status !== "done") body.appendChild(el("p", { class: "warn-box" },
      `Report status: ${data.status}${data.error ? ` (${data.error})` : ""}`));
    const sensors = reportSensors(report || {});
    if (!sensors.length) {
      body.appendChild(el("p", { class: "muted" }, data.status && data.status !== "done"
        ? "The report is not ready yet." : "This report has no Allan curves."));
    }
    for (const s of sensors) renderAllanSensor(body, s);
    if (rec && typeof rec === "object") {
      body.appendChild(el("h2", {}, "Recording"));
      const device = rec.device && typeof rec.device === "object"
        ? Object.entries(rec.device).filter(([, v]) => v).map(([k, v]) => `${k} ${v}`).join(", ") : rec.device;
      body.appendChild(keyValues(Object.assign({}, rec, { source: name, device })));
    }
    if (report && Array.isArray(report.flags) && report.flags.length) {
      body.appendChild(el("h2", {}, "Flags"));
      const ul = el("ul", { class: "warnings" });
      for (const f of report.flags) ul.appendChild(el("li", {}, f));
      body.appendChild(ul);
    }
    if (report && report.settings && typeof report.settings === "object") {
      const det = el("details");
      det.appendChild(el("summary", {}, "Analysis settings"));
      det.appendChild(keyValues(report.settings));
      body.appendChild(det);
    }
    await showReportImages(id, data, body, gen, new Set(sensors.map((x) => x.name)));
  }

  function reportFiles(data) {
    return (data.files || []).map((f) => (typeof f === "string" ? { name: f } : f)).filter((f) => f && f.name);
  }

  const reportFileUrl = (id, f) => f.url || `${API}/reports/${enc(id)}/files/${enc(f.name)}`;

  /** The report's PNG plots that the page did not draw itself (each plot once: a sensor's curves are drawn above). */
  async function showReportImages(id, data, body, gen, drawn) {
    for (const f of reportFiles(data).filter((x) => /\.png$/i.test(x.name) && !drawn.has(x.name.replace(/\.png$/i, "")))) {
      try {
        const blob = await (await apiFetch(reportFileUrl(id, f), "image/png")).blob();
        if (gen !== generation) return;
        const img = el("img", { alt: f.name, src: URL.createObjectURL(blob), class: "report-png" });
        body.appendChild(img);
      } catch (err) {
        if (gen === generation) body.appendChild(el("p", { class: "muted" }, err.readable ? err.readable(f.name) : String(err)));
      }
    }
  }

  async function downloadReportHtml() {
    const id = decodeURIComponent(location.hash.replace(/^#\/reports?\//, ""));
    let data = {};
    try { data = await apiJson(`${API}/reports/${enc(id)}`); } catch (_) { /* fall back to the default name */ }
    const f = reportFiles(data).find((x) => /\.html?$/i.test(x.name)) || { name: "report.html" };
    try {
      const base = String(data.source || id).split("/").pop().replace(/\.[^.]*$/, "");
      await download(reportFileUrl(id, f), `allan-report-${base}.html`, "text/html");
    } catch (err) {
      reportError(err, "The report HTML could not be downloaded");
    }
  }

  /** A nested definition list of a JSON value (model cards, report metadata). */
  function keyValues(obj, depth) {
    const dl = el("dl", { class: "kv" });
    for (const [k, v] of Object.entries(obj)) {
      dl.appendChild(el("dt", {}, k));
      const dd = el("dd");
      if (v && typeof v === "object" && !Array.isArray(v) && (depth || 0) < 4) dd.appendChild(keyValues(v, (depth || 0) + 1));
      else if (Array.isArray(v)) {
        const scalars = v.every((x) => x === null || typeof x !== "object");
        if (scalars) dd.textContent = v.length > 40 ? `${v.slice(0, 40).join(", ")} … (${v.length} items)` : v.join(", ");
        else for (const x of v.slice(0, 50)) dd.appendChild(x && typeof x === "object" ? keyValues(x, (depth || 0) + 1) : el("div", {}, x));
      } else if (typeof v === "number") dd.textContent = fmt(v, 4);
      else dd.textContent = v === null ? "–" : typeof v === "object" ? JSON.stringify(v) : String(v);
      dl.appendChild(dd);
    }
    return dl;
  }

  async function showModels() {
    show("models");
    const gen = generation;
    const body = $("models-body");
    notAvailable(body, "Loading…");
    let data;
    try {
      data = await apiJson(`${API}/models`);
    } catch (err) {
      if (gen !== generation) return;
      notAvailable(body, err instanceof ApiError && MISSING.has(err.status)
        ? `Model cards are not available on this server (GET ${API}/models answered ${err.status}).`
        : err instanceof ApiError ? err.readable("Could not load the models") : String(err));
      return;
    }
    if (gen !== generation) return;
    const models = Array.isArray(data) ? data : data.models || [];
    clearNode(body);
    if (!models.length) { body.appendChild(el("p", { class: "muted" }, "No trained models are installed.")); return; }
    const grid = el("div", { class: "cards" });
    for (const m of models) grid.appendChild(modelCard(m));
    body.appendChild(grid);
  }

  const METRIC_NAMES = { macro_f1: "macro F1", macro_f1_target_classes: "macro F1 (target classes)", accuracy: "accuracy",
    balanced_accuracy: "balanced accuracy", coverage: "coverage", ece: "calibration error (ECE)", n_windows: "windows",
    n_groups: "groups", n_recordings: "recordings" };

  /** A definition list of [label, value] pairs, skipping empty values. */
  function pairs(list) {
    const dl = el("dl", { class: "kv" });
    for (const [k, v] of list) {
      if (v === undefined || v === null || v === "") continue;
      dl.appendChild(el("dt", {}, k));
      const dd = el("dd");
      if (v instanceof Node) dd.appendChild(v); else dd.textContent = String(v);
      dl.appendChild(dd);
    }
    return dl;
  }

  /** One model card: what the model does, how well (with the protocol), on what data, with which features and
   * versions; the fitted internals only as a download of the raw artifact. */
  function modelCard(m) {
    const card = el("div", { class: "card", "data-model": m.name || "" });
    card.appendChild(el("h3", {}, m.name || "model"));
    const w = m.window || {};
    const windowText = w.length_s ? `${fmt(w.length_s, 2)} s windows every ${fmt(w.hop_s, 2)} s${w.rate_hz ? ` at ${fmt(w.rate_hz, 1)} Hz` : ""}` : "";
    const versions = m.versions && typeof m.versions === "object"
      ? Object.entries(m.versions).map(([k, v]) => `${k} ${v}`).join(", ") : "";
    card.appendChild(pairs([["Task", m.task], ["Estimator", m.estimator],
      ["Classes", Array.isArray(m.classes) ? m.classes.join(", ") : ""], ["Window", windowText],
      ["Date", m.date ? new Date(m.date).toLocaleDateString() : ""], ["Versions", versions]]));
    card.appendChild(el("h4", {}, "Metrics"));
    const evals = Array.isArray(m.evaluations) ? m.evaluations : [];
    if (!evals.length) card.appendChild(el("p", { class: "muted" }, "No evaluation is recorded with this model."));
    for (const ev of evals) {
      const sec = el("div", { class: "evaluation", "data-role": "evaluation" });
      sec.appendChild(el("p", { class: "protocol" }, `Protocol: ${ev.protocol || "not stated"}`));
      const rows = Object.entries(ev.metrics || {}).map(([k, v]) => [METRIC_NAMES[k] || k,
        Number.isInteger(v) ? String(v) : fmt(v, 3)]);
      if (Array.isArray(ev.target_classes) && ev.target_classes.length) rows.push(["target classes", ev.target_classes.join(", ")]);
      sec.appendChild(pairs(rows));
      if (ev.command) sec.appendChild(el("code", { class: "command" }, ev.command));
      card.appendChild(sec);
    }
    const t = m.training || {};
    card.appendChild(el("h4", {}, "Training data"));
    const classWindows = t.class_windows && typeof t.class_windows === "object"
      ? Object.entries(t.class_windows).map(([k, v]) => `${k} ${v}`).join(", ") : "";
    card.appendChild(pairs([["Data", Array.isArray(t.paths) ? t.paths.join(", ") : ""], ["Recordings", t.recordings],
      ["Groups", t.groups], ["Windows", t.windows], ["Simulated logs", t.simulated_logs || ""],
      ["Windows per class", classWindows]]));
    const f = m.features || {};
    card.appendChild(el("h4", {}, "Features"));
    const names = el("details", { class: "feature-names" });
    names.appendChild(el("summary", {}, `${f.count || 0} features`));
    names.appendChild(el("p", { class: "names" }, (f.names || []).join(", ")));
    card.appendChild(pairs([["Groups", Array.isArray(f.groups) ? f.groups.join(", ") : ""],
      ["Required streams", Array.isArray(f.required_streams) ? f.required_streams.join(", ") : ""],
      ["Feature set", f.set_version !== undefined ? `version ${f.set_version}` : ""], ["Names", names]]));
    const tools = el("div", { class: "toolbar" });
    const dl = el("button", { type: "button", "data-role": "download-model" },
      `Download model.json${m.raw_bytes ? ` (${fmt(m.raw_bytes / 1024, 0)} KiB, fitted internals)` : ""}`);
    dl.addEventListener("click", async () => {
      try {
        await download(`${API}/models/${enc(m.name)}/model.json`, `${m.name}.model.json`);
      } catch (err) {
        reportError(err, "The model could not be downloaded");
      }
    });
    tools.appendChild(dl);
    card.appendChild(tools);
    if (m.name) {
      const det = el("details", { class: "model-card" });
      det.appendChild(el("summary", {}, "Model card text"));
      det.addEventListener("toggle", async () => {
        if (!det.open || det.dataset.loaded) return;
        det.dataset.loaded = "1";
        try {
          const full = await apiJson(`${API}/models/${enc(m.name)}`);
          det.appendChild(el("pre", { class: "card-text" }, full.card_markdown || "This model has no card text."));
        } catch (err) {
          det.appendChild(el("p", { class: "muted" }, err.readable ? err.readable("The model card is not available") : String(err)));
        }
      });
      card.appendChild(det);
    }
    return card;
  }

  /** "Warming up" under the header while the service compiles its kernels (/health), polled until ready. */
  async function watchServiceState() {
    let state = "ok";
    try {
      state = (await (await fetch(`${API}/health`)).json()).status;
    } catch (err) {
      state = "ok";  // no answer: the requests of the page report it
    }
    const box = $("service-state");
    box.textContent = "The service is warming up (compiling its processing code): the first upload may wait.";
    box.hidden = state !== "warming up";
    if (state === "warming up") setTimeout(watchServiceState, 2000);
  }

  // -- wiring -----------------------------------------------------------------------------------
  function redrawSession() {
    if (current) renderSessionData(false);
  }

  /** The charts are drawn at their element's size in pixels (labels and ticks keep their size on screen), so a new
   * size (a phone turned, a window resized) draws them again, once the resizing has paused: the session's charts and
   * map (which keeps the user's view, or fits the track to its new size), and an Allan report's curves. */
  let resizeTimer = null;
  const RESIZE_PAUSE_MS = 150;
  function redrawOnResize() {
    clearTimeout(resizeTimer);
    resizeTimer = setTimeout(() => {
      if (current && !$("view-session").hidden) renderSessionData(true);
      for (const svg of document.querySelectorAll("#view-report:not([hidden]) svg.loglog")) if (svg.pdrRedraw) svg.pdrRedraw();
    }, RESIZE_PAUSE_MS);
  }

  document.addEventListener("DOMContentLoaded", () => {
    $("signin-form").addEventListener("submit", signIn);
    $("sign-out").addEventListener("click", () => { signOut(); location.hash = "#/sessions"; });
    $("floor-filter").addEventListener("change", redrawSession);
    $("colour-by").addEventListener("change", () => { if (current) renderSessionData(true); });
    $("heading-mode").addEventListener("change", changeHeading);
    $("zoom-in").addEventListener("click", () => map && map.zoom(1 / 1.5));
    $("zoom-out").addEventListener("click", () => map && map.zoom(1.5));
    $("zoom-reset").addEventListener("click", () => map && map.fit());
    const dl = (format, ext) => async () => {
      if (!current) return;
      try {
        await download(`${API}/sessions/${enc(current.id)}/track?format=${format}&heading=${current.heading}`,
          `${current.id}.${ext}`);
      } catch (err) {
        reportError(err, `The ${ext.toUpperCase()} download failed`);
      }
    };
    $("dl-csv").addEventListener("click", dl("csv", "csv"));
    $("delete-session").addEventListener("click", async () => {
      if (!current) return;
      const name = (current.detail && (current.detail.name || current.detail.session_id)) || current.id;
      if (!window.confirm(`Delete the session "${name}" with its raw data and results? This cannot be undone.`)) return;
      try {
        await apiFetch(`${API}/sessions/${enc(current.id)}`, undefined, "DELETE");
        navigateWithNotice("#/sessions", `Session "${name}" deleted.`);
      } catch (err) {
        reportError(err, "The session could not be deleted");
      }
    });
    $("dl-geojson").addEventListener("click", dl("geojson", "geojson"));
    $("dl-report-html").addEventListener("click", downloadReportHtml);
    $("delete-report").addEventListener("click", async () => {
      const id = decodeURIComponent(location.hash.replace(/^#\/reports?\//, ""));
      const name = $("report-title").textContent.replace(/^Allan report: /, "");
      if (!id || !window.confirm(`Delete the Allan report of "${name}" with its files? This cannot be undone.`)) return;
      try {
        await apiFetch(`${API}/reports/${enc(id)}`, undefined, "DELETE");
        navigateWithNotice("#/reports", `Report "${name}" deleted.`);
      } catch (err) {
        reportError(err, "The report could not be deleted");
      }
    });
    window.addEventListener("hashchange", route);
    window.addEventListener("resize", redrawOnResize);
    route();
    watchServiceState();
  });
})();
