// mjx-balance explore: the folder's maps drawn as inline SVG, a cell's run on a click.
// Plain JavaScript, no library: the server (report/explore/server.py) sends JSON from
// /api/folder, /api/map and /api/run; everything here only draws it.
"use strict";
(function () {
  const SVG = "http://www.w3.org/2000/svg";
  const $ = (id) => document.getElementById(id);
  const VIRIDIS = ["#440154", "#472d7b", "#3b528b", "#2c728e", "#21918c", "#28ae80", "#5ec962",
                   "#addc30", "#fde725"];
  const NOT_COMPUTED = "#ffffff";
  const NO_VALUE = "#d9d9d9";
  const PUSH_COLOUR = "#f4a582";
  const PROBABILITY = "*share";  // the map select's entry of a cohort's share of subjects
  // the share map's lines: the base body's boundary, and the levels' (cohort_probability.png)
  const BASE_COLOUR = "#d55e00";
  const LEVEL_DASHES = [["95", "none"], ["50", "7 3"], ["5", "1.5 2.5"]];
  const S = {folder: null, map: null, key: null, layer: "outcome", request: 0, cell: null,
             timer: null, run: null, frame: 0, playing: false};

  // -- small helpers -----------------------------------------------------------------------
  function svg(tag, attrs, parent, text) {
    const node = document.createElementNS(SVG, tag);
    for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, v);
    if (text !== undefined) node.textContent = text;
    if (parent) parent.appendChild(node);
    return node;
  }
  function html(tag, parent, text) {
    const node = document.createElement(tag);
    if (text !== undefined) node.textContent = text;
    if (parent) parent.appendChild(node);
    return node;
  }
  async function getJSON(url) {
    let response;
    try {
      response = await fetch(url, {cache: "no-store"});
    } catch (e) {
      throw new Error("the server does not answer (was it stopped?)");
    }
    let body = null;
    try { body = await response.json(); } catch (e) { body = null; }
    if (!response.ok || (body && body.error)) {
      throw new Error((body && body.error) || `${response.status} ${response.statusText}`);
    }
    return body;
  }
  function showError(text) { $("error").textContent = text; $("error").hidden = false; }
  function clearError() { $("error").hidden = true; $("error").textContent = ""; }
  function num(v) {
    if (v === 0) return "0";
    const a = Math.abs(v);
    return a >= 1e5 || a < 1e-3 ? v.toExponential(2) : String(Number(v.toPrecision(4)));
  }
  function fmt(value, unit) {
    if (value === null || value === undefined || value === "") return "–";
    if (typeof value !== "number") return String(value);
    return unit && unit !== "1" ? `${num(value)} ${unit}` : num(value);
  }
  function hexRGB(h) { return [1, 3, 5].map((i) => parseInt(h.slice(i, i + 2), 16)); }
  function ramp(t) {
    t = Math.min(1, Math.max(0, t));
    const x = t * (VIRIDIS.length - 1), i = Math.min(Math.floor(x), VIRIDIS.length - 2);
    const a = hexRGB(VIRIDIS[i]), b = hexRGB(VIRIDIS[i + 1]), f = x - i;
    return `rgb(${a.map((c, k) => Math.round(c + (b[k] - c) * f)).join(",")})`;
  }
  function scale(lo, hi, a, b, log) {
    if (hi === lo) { hi = lo + 1; }
    if (log) {
      const l0 = Math.log(lo), l1 = Math.log(hi);
      return (v) => a + (Math.log(v) - l0) / (l1 - l0) * (b - a);
    }
    return (v) => a + (v - lo) / (hi - lo) * (b - a);
  }
  function ticks(lo, hi, log) {
    if (!(hi > lo)) return [lo];
    const out = [];
    if (log) {
      for (let k = Math.floor(Math.log10(lo)); k <= Math.ceil(Math.log10(hi)); k++) {
        for (const m of [1, 2, 5]) {
          const v = Number((m * 10 ** k).toPrecision(6));
          if (v >= lo * 0.999 && v <= hi * 1.001) out.push(v);
        }
      }
      return out;
    }
    const raw = (hi - lo) / 5, mag = 10 ** Math.floor(Math.log10(raw));
    const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= raw);
    for (let k = Math.ceil(lo / step - 1e-9); k * step <= hi + step * 1e-9; k++) {
      out.push(k === 0 ? 0 : Number((k * step).toPrecision(10)));
    }
    return out;
  }
  function axes(parent, x, y, box, opts) {
    const g = svg("g", {class: "axis"}, parent);
    const [l, r, t, b] = box;
    svg("path", {d: `M${l},${t}V${b}H${r}`, fill: "none"}, g);
    for (const v of opts.xticks) {
      svg("line", {x1: x(v), x2: x(v), y1: b, y2: b + 4}, g);
      svg("text", {x: x(v), y: b + 17, "text-anchor": "middle"}, g, num(v));
    }
    for (const v of opts.yticks) {
      svg("line", {x1: l - 4, x2: l, y1: y(v), y2: y(v)}, g);
      svg("text", {x: l - 6, y: y(v) + 4, "text-anchor": "end"}, g, num(v));
    }
    if (opts.xlabel) {
      svg("text", {x: (l + r) / 2, y: b + 36, "text-anchor": "middle"}, g, opts.xlabel);
    }
    if (opts.ylabel) {
      svg("text", {x: 14, y: (t + b) / 2, "text-anchor": "middle",
                   transform: `rotate(-90 14 ${(t + b) / 2})`}, g, opts.ylabel);
    }
  }

  // -- the map -----------------------------------------------------------------------------
  function layerInfo() { return S.folder.layers.find((l) => l.column === S.layer); }
  function grid() { return S.key === PROBABILITY ? S.folder.probability : S.map; }

  function colours() {
    const g = grid(), n = g.forces.length * g.durations.length;
    if (S.key === PROBABILITY) {
      return {fill: g.share.map((v) => (v === null ? NOT_COMPUTED : ramp(v))),
              range: [0, 1], log: false, label: "share of subjects recovering", unit: "1"};
    }
    const outcome = g.cells.outcome || new Array(n).fill(null);
    if (S.layer === "outcome") {
      const palette = Object.fromEntries(S.folder.outcomes.map((o) => [o.name, o.colour]));
      return {fill: outcome.map((o) => (o === null ? NOT_COMPUTED : palette[o] || NO_VALUE))};
    }
    const info = layerInfo();
    const raw = g.cells[S.layer] || new Array(n).fill(null);
    const vals = raw.map((v, i) => (info.recovered_only && outcome[i] !== "recovered" ? null : v));
    const finite = vals.filter((v) => v !== null && Number.isFinite(v));
    let lo = Math.min(...finite), hi = Math.max(...finite);
    const log = info.scale === "log" && lo > 0 && hi / lo > 10;
    const t = (v) => (hi > lo ? (log ? Math.log(v / lo) / Math.log(hi / lo) : (v - lo) / (hi - lo))
                              : 0.5);
    const fill = vals.map((v, i) => (outcome[i] === null ? NOT_COMPUTED
                                     : v === null ? NO_VALUE : ramp(t(v))));
    return {fill, range: finite.length ? [lo, hi] : null, log, label: info.label,
            unit: info.unit, recoveredOnly: info.recovered_only};
  }

  function drawMap() {
    const holder = $("map");
    holder.textContent = "";
    const g = grid();
    if (!g) return;
    const W = 760, H = 480, box = [70, W - 14, 12, H - 52];
    const fx = g.force_edges, dy = g.duration_edges, nd = g.durations.length;
    const x = scale(fx[0], fx[fx.length - 1], box[0], box[1], false);
    const y = scale(dy[0], dy[dy.length - 1], box[3], box[2], g.log_durations);
    const root = svg("svg", {id: "map-svg", viewBox: `0 0 ${W} ${H}`, role: "img",
                             "aria-label": "force x duration map"}, holder);
    const pat = svg("pattern", {id: "hatch", width: 7, height: 7, patternUnits: "userSpaceOnUse",
                                patternTransform: "rotate(45)"}, svg("defs", {}, root));
    svg("line", {x1: 0, y1: 0, x2: 0, y2: 7, stroke: "#262626", "stroke-width": 1.2}, pat);
    const {fill} = colours();
    const cells = svg("g", {class: "cells", "shape-rendering": "crispEdges"}, root);
    const hatch = svg("g", {}, root);
    const outcome = S.key === PROBABILITY ? [] : (g.cells.outcome || []);
    const hatched = new Set(S.folder.outcomes.filter((o) => o.hatch).map((o) => o.name));
    for (let fi = 0; fi < g.forces.length; fi++) {
      for (let di = 0; di < nd; di++) {
        const i = fi * nd + di;
        const r = {x: x(fx[fi]), y: y(dy[di + 1]), width: x(fx[fi + 1]) - x(fx[fi]),
                   height: y(dy[di]) - y(dy[di + 1])};
        svg("rect", {...r, fill: fill[i], class: "cell", "data-i": i,
                     "data-force": String(g.forces[fi]), "data-duration": String(g.durations[di])},
            cells);
        if (S.layer === "outcome" && hatched.has(outcome[i])) {
          svg("rect", {...r, fill: "url(#hatch)", "pointer-events": "none"}, hatch);
        }
      }
    }
    axes(root, x, y, box, {xticks: ticks(fx[0], fx[fx.length - 1], false),
                           yticks: ticks(dy[0], dy[dy.length - 1], g.log_durations),
                           xlabel: "push force F [N]  (+ forward)",
                           ylabel: "push duration T [s]" + (g.log_durations ? "  (log scale)" : "")});
    drawBoundaries(root, x, y);
    if (S.key !== PROBABILITY) drawMarks(root, x, y, g);
  }

  function line(parent, points, x, y, attrs) {
    const d = points.map((p, k) => `${k ? "L" : "M"}${x(p[0]).toFixed(1)},${y(p[1]).toFixed(1)}`);
    return svg("path", {d: d.join(""), fill: "none", "pointer-events": "none", ...attrs}, parent);
  }

  function drawBoundaries(root, x, y) {
    const g = svg("g", {class: "boundaries"}, root);
    const kind = S.folder.kind, others = $("others").checked;
    S.folder.maps.forEach((m, k) => {
      const mine = m.key === S.key;
      if (mine || !others || kind === "sweep") return;
      const attrs = kind === "compare"
        ? {stroke: S.folder.series[k % S.folder.series.length], "stroke-width": 2.2,
           "stroke-dasharray": ["6 3", "2 3", "9 3 2 3"][k % 3]}
        : {stroke: "#606060", "stroke-width": 1, "stroke-opacity": 0.7};
      for (const pts of m.boundary || []) line(g, pts, x, y, attrs);
    });
    const own = S.folder.maps.find((m) => m.key === S.key);
    for (const pts of (own && own.boundary) || []) {
      line(g, pts, x, y, {stroke: "#000", "stroke-width": 3, class: "own-boundary"});
    }
    // the share map: the base body's boundary (orange) and where 95 / 50 / 5 % of the
    // subjects recover (solid / dashed / dotted), as cohort_probability.png draws them
    if (S.key === PROBABILITY) {
      const p = S.folder.probability;
      for (const pts of p.base || []) {
        line(g, pts, x, y, {stroke: BASE_COLOUR, "stroke-width": 9, class: "base-boundary"});
      }
      for (const [level, dash] of LEVEL_DASHES) {
        for (const pts of (p.levels || {})[level] || []) {
          line(g, pts, x, y, {stroke: "#fff", "stroke-width": 4.5, class: "level-boundary"});
          line(g, pts, x, y, {stroke: "#000", "stroke-width": 2, "stroke-dasharray": dash,
                              class: "level-boundary", "data-level": level});
        }
      }
    }
    // with one step (dashed) and with two (dotted): capturability (docs/model.md)
    const steps = S.key !== PROBABILITY && S.map ? S.map.step_boundaries : null;
    (steps || []).forEach((lines, k) => {
      for (const pts of lines) {
        line(g, pts, x, y, {stroke: "#000", "stroke-width": 4.5, class: "step-boundary"});
        line(g, pts, x, y, {stroke: "#fff", "stroke-width": 2.5, class: "step-boundary",
                            "stroke-dasharray": k ? "1.5 2.5" : "7 3"});
      }
    });
  }

  function drawMarks(root, x, y, g) {
    const marks = svg("g", {class: "marks"}, root);
    for (const [f, d] of g.explored || []) {
      svg("circle", {cx: x(f), cy: y(d), r: 3.2, fill: "#fff", stroke: "#000",
                     "stroke-width": 1, class: "explored", "pointer-events": "none"}, marks);
    }
    const lo = g.duration_edges[0], hi = g.duration_edges[g.duration_edges.length - 1];
    const fx = g.force_edges;
    const pts = (g.table || []).filter((p) => p.force >= fx[0] && p.force <= fx[fx.length - 1]);
    const shown = pts.filter((p) => p.max_acting_time >= lo && p.max_acting_time <= hi);
    if (shown.length > 1) {
      line(marks, shown.map((p) => [p.force, p.max_acting_time]), x, y,
           {stroke: "#1f3fbf", "stroke-width": 1.8});
    }
    for (const p of pts) {
      const t = Math.min(hi, Math.max(lo, p.max_acting_time));
      const attrs = {class: "table-point", "data-force": String(p.force),
                     "data-duration": String(p.max_acting_time), "data-table": "1"};
      if (t === p.max_acting_time) {
        svg("circle", {cx: x(p.force), cy: y(t), r: 5, fill: "#fff", stroke: "#1f3fbf",
                       "stroke-width": 2, ...attrs}, marks);
      } else {
        const up = p.max_acting_time > hi ? -1 : 1, cx = x(p.force), cy = y(t);
        svg("path", {d: `M${cx - 6},${cy + up * 8}L${cx + 6},${cy + up * 8}L${cx},${cy}Z`,
                     fill: "#1f3fbf", ...attrs}, marks);
      }
    }
    if (S.cell) {
      const [cf, cd] = [Number(S.cell.force), Number(S.cell.duration)];
      const fi = g.forces.findIndex((f) => Math.abs(f - cf) <= 1e-9 * Math.max(1, Math.abs(f)));
      const di = g.durations.findIndex((d) => Math.abs(d - cd) <= 1e-9);
      if (fi >= 0 && di >= 0) {
        const fe = g.force_edges, de = g.duration_edges;
        svg("rect", {x: x(fe[fi]), y: y(de[di + 1]), width: x(fe[fi + 1]) - x(fe[fi]),
                     height: y(de[di]) - y(de[di + 1]), fill: "none", stroke: "#000",
                     "stroke-width": 3, "stroke-dasharray": "4 2", class: "selected",
                     "pointer-events": "none"}, marks);
      }
    }
  }

  function drawLegend() {
    const box = $("legend");
    box.textContent = "";
    const item = (label) => { const s = html("span", box); return [s, label]; };
    const c = colours();
    if (S.key !== PROBABILITY && S.layer === "outcome") {
      const counts = S.map.counts || {};
      for (const o of S.folder.outcomes) {
        const [s] = item();
        const sw = svg("svg", {viewBox: "0 0 28 14"}, s);
        svg("rect", {x: 0, y: 0, width: 28, height: 14, fill: o.colour, stroke: "#555"}, sw);
        if (o.hatch) svg("path", {d: "M0,14L14,0M14,14L28,0", stroke: "#262626"}, sw);
        s.appendChild(document.createTextNode(`${o.name.replace("_", " ")} (${counts[o.name] || 0})`));
      }
    } else if (c.range) {
      const [s] = item();
      const bar = svg("svg", {class: "bar", viewBox: "0 0 220 14"}, s);
      for (let k = 0; k < 44; k++) {
        svg("rect", {x: k * 5, y: 0, width: 5.5, height: 14, fill: ramp(k / 43)}, bar);
      }
      s.insertBefore(document.createTextNode(fmt(c.range[0], c.unit) + " "), bar);
      s.appendChild(document.createTextNode(" " + fmt(c.range[1], c.unit) +
                                            (c.log ? " (log scale)" : "")));
      if (S.key !== PROBABILITY) {
        const [n] = item();
        n.textContent = c.recoveredOnly ? "grey: did not recover" : "grey: no value";
      }
    }
    const [w] = item();
    w.textContent = "white: not computed (yet)";
    if (S.key === PROBABILITY) {
      const p = S.folder.probability;
      if ((p.base || []).length) {
        const [s] = item();
        const sw = svg("svg", {viewBox: "0 0 28 14"}, s);
        svg("line", {x1: 0, y1: 7, x2: 28, y2: 7, "stroke-width": 5, stroke: BASE_COLOUR}, sw);
        s.appendChild(document.createTextNode("the base configuration's body recovers"));
      }
      for (const [level, dash] of LEVEL_DASHES) {
        if (!((p.levels || {})[level] || []).length) continue;
        const [s] = item();
        const sw = svg("svg", {viewBox: "0 0 28 14"}, s);
        svg("line", {x1: 0, y1: 7, x2: 28, y2: 7, "stroke-width": 2, stroke: "#000",
                     "stroke-dasharray": dash}, sw);
        s.appendChild(document.createTextNode(`P(recover) ≥ ${level} %`));
      }
    }
    if (S.key !== PROBABILITY) {
      const [b] = item();
      b.textContent = "black line: recovery boundary on the grid (feet in place)";
      if (((S.map.step_boundaries || [])[0] || []).length) {
        const [st] = item();
        st.textContent = "white dashed: with one step; white dotted: with two (capturability)";
      }
      if ((S.map.table || []).length) {
        const [t] = item();
        t.textContent = "blue: max acting time (table.csv)";
      }
      const [e] = item();
      e.textContent = "white dot: run kept in the folder";
    }
    if (S.folder.kind === "compare" && $("others").checked) {
      S.folder.maps.forEach((m, k) => {
        if (m.key === S.key) return;
        const [s] = item();
        const sw = svg("svg", {viewBox: "0 0 28 14"}, s);
        svg("line", {x1: 0, y1: 7, x2: 28, y2: 7, "stroke-width": 2.5,
                     stroke: S.folder.series[k % S.folder.series.length],
                     "stroke-dasharray": ["6 3", "2 3", "9 3 2 3"][k % 3]}, sw);
        s.appendChild(document.createTextNode(`${m.label} boundary`));
      });
    }
  }

  // -- hover ---------------------------------------------------------------------------------
  function tipRows(rows) {
    const t = html("table");
    for (const [k, v] of rows) {
      const tr = html("tr", t);
      html("td", tr, k);
      html("td", tr, v);
    }
    return t;
  }
  function cellRows(i, target) {
    const g = grid();
    const force = Number(target.dataset.force), duration = Number(target.dataset.duration);
    if (target.dataset.table) {
      return [["max acting time", `${fmt(duration, "s")} at ${fmt(force, "N")} (table.csv)`],
              ["", "click: open this push's run"]];
    }
    if (S.key === PROBABILITY) {
      return [["force", fmt(force, "N")], ["duration", fmt(duration, "s")],
              ["share recovering", g.share[i] === null ? "–"
                : `${num(g.share[i])} (of ${g.counted[i]} subjects)`],
              ["95 % interval", g.share[i] === null || g.low === undefined ? "–"
                : `${num(g.low[i])} to ${num(g.high[i])} (Wilson)`],
              ["", "pick a subject's map to open a run"]];
    }
    if (!g.cells.outcome || g.cells.outcome[i] === null) {
      return [["force", fmt(force, "N")], ["duration", fmt(duration, "s")],
              ["", "not computed yet"]];
    }
    return S.folder.hover.map((h) => {
      const v = h.column === "force" ? force : h.column === "duration" ? duration
        : (g.cells[h.column] || [])[i];
      return [h.label, fmt(v, h.unit)];
    });
  }
  function showTip(event) {
    const target = event.target;
    if (!target.dataset || target.dataset.force === undefined) { hideTip(); return; }
    const tip = $("tooltip");
    tip.textContent = "";
    tip.appendChild(tipRows(cellRows(Number(target.dataset.i), target)));
    tip.hidden = false;
    const w = tip.offsetWidth, h = tip.offsetHeight;
    let left = event.clientX + 14, top = event.clientY + 14;
    if (left + w > window.innerWidth - 4) left = event.clientX - w - 14;
    if (top + h > window.innerHeight - 4) top = Math.max(4, event.clientY - h - 14);
    tip.style.left = `${Math.max(4, left)}px`;
    tip.style.top = `${top}px`;
  }
  function hideTip() { $("tooltip").hidden = true; }

  // -- a run ---------------------------------------------------------------------------------
  function outcomeText(s) {
    if (s.outcome === "recovered") return `recovered, settled at ${fmt(s.settle_time, "s")}`;
    if (s.outcome === "fell") {
      return `fell at ${fmt(s.fall_time, "s")}` + (s.fall_cause ? ` (${s.fall_cause})` : "");
    }
    if (s.outcome === "not_settled") return "not settled by the end of the window";
    return s.outcome;
  }

  async function openRun(force, duration) {
    if (S.key === PROBABILITY) { showError("pick one subject's map to open a run"); return; }
    const id = ++S.request;
    clearError();
    S.cell = {force, duration};
    drawMap();
    const started = performance.now(), status = $("run-status");
    const tick = () => {
      status.textContent = `computing ${force} N for ${duration} s with the scalar reference ` +
        `(MuJoCo C + OSQP)… ${((performance.now() - started) / 1000).toFixed(1)} s`;
    };
    tick();
    clearInterval(S.timer);
    S.timer = setInterval(tick, 100);
    $("run-section").classList.add("busy");
    try {
      const q = new URLSearchParams({map: S.key, force: String(force), duration: String(duration)});
      const run = await getJSON(`/api/run?${q}`);
      if (id !== S.request) return;
      showRun(run, (performance.now() - started) / 1000);
      history.replaceState(null, "", `#${q}`);
    } catch (e) {
      if (id === S.request) { status.textContent = "No run open."; showError(e.message); }
    } finally {
      if (id === S.request) {
        clearInterval(S.timer);
        $("run-section").classList.remove("busy");
      }
    }
  }

  function mapCell(force, duration) {
    const g = S.map;
    const fi = g.forces.findIndex((f) => Math.abs(f - force) <= 1e-9 * Math.max(1, Math.abs(f)));
    const di = g.durations.findIndex((d) => Math.abs(d - duration) <= 1e-9);
    if (fi < 0 || di < 0 || !g.cells.outcome) return null;
    const i = fi * g.durations.length + di;
    return g.cells.outcome[i] === null ? null : {outcome: g.cells.outcome[i],
                                                 fall_cause: (g.cells.fall_cause || [])[i]};
  }

  function showRun(run, seconds) {
    S.run = run;
    const s = run.summary;
    $("run-title").textContent = `${fmt(run.force, "N")} for ${fmt(run.duration, "s")}: ` +
      outcomeText(s);
    const c = run.computed || {};
    $("run-status").textContent = run.cached
      ? `served from the folder (${run.file}; computed ${c.at || "earlier"} in ` +
        `${fmt(c.seconds, "s")}), answered in ${seconds.toFixed(2)} s`
      : `computed now in ${fmt(c.seconds, "s")} and kept in the folder: ${run.file}` +
        (run.note ? ` (${run.note})` : "");
    const cell = mapCell(run.force, run.duration), agree = $("run-agreement");
    agree.hidden = !cell || cell.outcome === s.outcome;
    if (cell && cell.outcome !== s.outcome) {
      agree.textContent = `The map (the batched engine${S.map.physics ? ", physics " +
        S.map.physics : ""}) says ${cell.outcome} here; the scalar reference says ${s.outcome}.` +
        " Close to the boundary the two paths can decide a cell differently (docs/engine.md).";
    }
    const table = $("run-summary");
    table.textContent = "";
    const head = html("tr", table);
    html("th", head, "this run (reference)");
    html("th", head, "");
    for (const col of run.shown) {
      const tr = html("tr", table);
      html("td", tr, col.label);
      html("td", tr, fmt(s[col.column], col.unit));
    }
    $("computed").textContent = `Computed by ${c.by || "the scalar reference"} in the map's ` +
      `configuration (convention ${run.convention}, window ${fmt(run.t_end, "s")}), mjx_balance ` +
      `${c.version || "?"}, ${c.at || ""}; kept in ${run.file}. The same run, its replay in ` +
      "MuJoCo's 3-D viewer and its GIF:";
    $("commands").textContent = [run.commands.simulate, run.commands.view,
                                 run.commands.animate].join("\n");
    $("run-body").hidden = false;
    drawPanels(run);
    drawFigure(run);
    if (S.map && !S.map.explored.some(([f, d]) => f === run.force && d === run.duration)) {
      S.map.explored.push([run.force, run.duration]);
      drawMap();
    }
  }

  // -- the series ------------------------------------------------------------------------------
  function segments(t, v, x, y) {
    const out = [];
    let cur = [];
    for (let k = 0; k < t.length; k++) {
      if (v[k] === null) { if (cur.length) out.push(cur); cur = []; continue; }
      cur.push(`${x(t[k]).toFixed(1)},${y(v[k]).toFixed(1)}`);
    }
    if (cur.length) out.push(cur);
    return out;
  }

  function drawPanels(run) {
    const holder = $("panels");
    holder.textContent = "";
    const t = run.series.time, tmax = t[t.length - 1];
    for (const p of run.panels) {
      const div = html("div", holder);
      div.className = "panel";
      const values = p.columns.flatMap((c) => (run.series[c.column] || []).filter((v) => v !== null));
      let lo = Math.min(...values), hi = Math.max(...values);
      if (!values.length) { lo = -1; hi = 1; }
      const span = Math.max(hi - lo, 1e-9), near = [], far = [];
      for (const b of p.bounds) {
        (b.values.every((v) => v >= lo - span && v <= hi + span) ? near : far).push(b);
      }
      for (const b of near) { lo = Math.min(lo, ...b.values); hi = Math.max(hi, ...b.values); }
      if (hi - lo < 1e-12) { lo -= 1; hi += 1; }
      const pad = (hi - lo) * 0.06;
      const W = 340, H = 190, box = [56, W - 8, 24, H - 24];
      const x = scale(0, tmax, box[0], box[1], false);
      const y = scale(lo - pad, hi + pad, box[3], box[2], false);
      const root = svg("svg", {viewBox: `0 0 ${W} ${H}`, class: "chart", role: "img",
                               "aria-label": p.title}, div);
      svg("text", {x: box[0], y: 15, "font-weight": 600}, root,
          `${p.title}${p.unit && p.unit !== "1" ? " [" + p.unit + "]" : ""}`);
      svg("rect", {x: x(0), y: box[2], width: Math.max(0, x(Math.min(run.duration, tmax)) - x(0)),
                   height: box[3] - box[2], fill: PUSH_COLOUR, "fill-opacity": 0.35}, root);
      axes(root, x, y, box, {xticks: ticks(0, tmax, false), yticks: ticks(lo - pad, hi + pad, false)});
      for (const b of near) {
        for (const v of b.values) {
          svg("line", {x1: box[0], x2: box[1], y1: y(v), y2: y(v), stroke: p.bound_colour,
                       "stroke-dasharray": "5 3", "stroke-width": 1.2}, root);
        }
      }
      p.columns.forEach((c, k) => {
        for (const seg of segments(t, run.series[c.column] || [], x, y)) {
          svg("polyline", {points: seg.join(" "), fill: "none", "stroke-width": 1.6,
                           stroke: S.folder.series[k % S.folder.series.length]}, root);
        }
      });
      svg("line", {class: "cursor", x1: box[0], x2: box[0], y1: box[2], y2: box[3],
                   stroke: "#000", "stroke-width": 1, "data-x0": 0, "data-tmax": tmax}, root);
      root.dataset.left = box[0];
      root.dataset.right = box[1];
      const keys = html("div", div);
      keys.className = "keys";
      p.columns.forEach((c, k) => {
        const s = html("span", keys);
        const b = html("b", s);
        b.style.background = S.folder.series[k % S.folder.series.length];
        s.appendChild(document.createTextNode(c.label));
      });
      for (const b of p.bounds) {
        html("span", keys, `${near.includes(b) ? "dashed" : "off-scale"}: ${b.label} ` +
          `[${b.values.map((v) => num(v)).join(", ")}]`);
      }
      if (run.duration > 0) html("span", keys, "shaded: the push");
    }
  }

  // -- the stick figure ------------------------------------------------------------------------
  function drawFigure(run) {
    const holder = $("figure");
    holder.textContent = "";
    const f = run.figure, P = f.points;
    const xs = [], zs = [];
    for (const [px, pz] of Object.values(P)) {
      xs.push(...px.filter((v) => v !== null));
      zs.push(...pz.filter((v) => v !== null));
    }
    const reach = Math.abs(run.force) * f.arrow_m_per_n;
    const x0 = Math.min(...xs) - 0.15 - (run.force < 0 ? reach : 0);
    const x1 = Math.max(...xs) + 0.15 + (run.force > 0 ? reach : 0);
    const z0 = Math.min(0, ...zs) - 0.08, z1 = Math.max(...zs) + 0.12;
    const W = 400, mpp = Math.max((x1 - x0) / W, (z1 - z0) / 330), H = (z1 - z0) / mpp;
    const X = (v) => (v - x0) / mpp, Z = (v) => H - (v - z0) / mpp;
    const root = svg("svg", {viewBox: `0 0 ${W} ${H.toFixed(0)}`, role: "img",
                             "aria-label": "the body over time"}, holder);
    const defs = svg("defs", {}, root);
    const head = svg("marker", {id: "arrow", viewBox: "0 0 10 10", refX: 9, refY: 5,
                                markerWidth: 6, markerHeight: 6, orient: "auto-start-reverse"}, defs);
    svg("path", {d: "M0,0L10,5L0,10Z", fill: "#CC79A7"}, head);
    svg("line", {x1: 0, x2: W, y1: Z(0), y2: Z(0), stroke: "#777", "stroke-width": 1.5}, root);
    const el = {};
    for (const [name, colour, width] of [["foot", "#333", 5], ["lower", "#0072B2", 6],
                                         ["upper", "#D55E00", 6]]) {
      el[name] = svg("line", {stroke: colour, "stroke-width": width, "stroke-linecap": "round"}, root);
    }
    el.arrow = svg("line", {stroke: "#CC79A7", "stroke-width": 3, "marker-end": "url(#arrow)"}, root);
    el.cop = svg("path", {fill: "#E69F00"}, root);
    el.com = svg("circle", {r: 5, fill: "#009E73", stroke: "#000"}, root);
    el.time = svg("text", {x: 8, y: 18}, root);
    el.note = svg("text", {x: 8, y: 36}, root);
    S.figure = {el, X, Z, run, mpp};
    S.frame = 0;
    const slider = $("time");
    slider.max = String(f.time.length - 1);
    slider.value = "0";
    setFrame(0);
  }

  function setFrame(k) {
    const {el, X, Z, run} = S.figure, f = run.figure, P = f.points;
    S.frame = k;
    const at = (name) => [X(P[name][0][k]), Z(P[name][1][k])];
    const seg = (node, a, b) => {
      const [ax, az] = at(a), [bx, bz] = at(b);
      node.setAttribute("x1", ax); node.setAttribute("y1", az);
      node.setAttribute("x2", bx); node.setAttribute("y2", bz);
    };
    seg(el.foot, "heel", "toe");
    seg(el.lower, "ankle", "hip");
    seg(el.upper, "hip", "head");
    const t = f.time[k], pushing = run.force !== 0 && t < run.duration;
    const [cx, cz] = at("upper_com");
    el.arrow.setAttribute("visibility", pushing ? "visible" : "hidden");
    const tail = cx - run.force * f.arrow_m_per_n / S.figure.mpp;  // pushes towards the CoM
    el.arrow.setAttribute("x1", tail); el.arrow.setAttribute("y1", cz);
    el.arrow.setAttribute("x2", cx); el.arrow.setAttribute("y2", cz);
    const cop = X(f.cop[k] ?? 0), ground = Z(0);
    el.cop.setAttribute("d", `M${cop},${ground}l-6,10h12Z`);
    el.com.setAttribute("cx", X(f.com[k] ?? 0));
    el.com.setAttribute("cy", ground);
    el.time.textContent = `t = ${t.toFixed(2)} s${pushing ? "  (pushed)" : ""}`;
    el.note.textContent = "green: CoM on the floor; orange: CoP";
    $("time-text").textContent = `${t.toFixed(2)} s`;
    for (const chart of document.querySelectorAll("#panels svg.chart")) {
      const c = chart.querySelector(".cursor"), l = Number(chart.dataset.left);
      const r = Number(chart.dataset.right), tmax = Number(c.dataset.tmax);
      const xx = l + (tmax > 0 ? Math.min(t, tmax) / tmax : 0) * (r - l);
      c.setAttribute("x1", xx); c.setAttribute("x2", xx);
    }
  }

  function play() {
    if (!S.figure) return;
    S.playing = !S.playing;
    $("play").textContent = S.playing ? "Pause" : "Play";
    if (!S.playing) return;
    const times = S.figure.run.figure.time;
    if (S.frame >= times.length - 1) setFrame(0);
    let last = performance.now(), t = times[S.frame];
    const step = (now) => {
      if (!S.playing || !S.figure || S.figure.run.figure.time !== times) return;
      t += (now - last) / 1000 * Number($("speed").value);
      last = now;
      let k = S.frame;
      while (k < times.length - 1 && times[k + 1] <= t) k++;
      setFrame(k);
      $("time").value = String(k);
      if (k >= times.length - 1) { S.playing = false; $("play").textContent = "Play"; return; }
      requestAnimationFrame(step);
    };
    requestAnimationFrame(step);
  }

  // -- the folder, its maps, refreshing ------------------------------------------------------
  function header() {
    const f = S.folder, m = f.maps.find((x) => x.key === S.key) || f.maps[0] || {};
    $("title").textContent = `mjx-balance explore: ${f.name}`;
    const what = {sweep: "sweep folder", compare: `compare folder, ${f.maps.length} variants`,
                  cohort: `cohort folder, ${f.maps.length} subjects`}[f.kind];
    $("subtitle").textContent = `${f.path} (${what})` +
      (m.convention ? `; convention ${m.convention}, window ${fmt(m.t_end, "s")}` : "") +
      `; mjx_balance ${f.version}`;
  }

  function status() {
    const g = grid();
    if (!g) return;
    if (S.key === PROBABILITY) {
      $("status").textContent = `the share of the ${g.subjects} subjects whose map recovers ` +
        "each cell (subjects whose cell is computed)";
      return;
    }
    const parts = [`${g.done} of ${g.total} cells computed`];
    if (!g.complete) parts.push("a run is writing this map: the page refreshes as it goes");
    if (g.physics) parts.push(`the map by the batched engine (physics ${g.physics})`);
    if (g.command) parts.push(`last written by: ${g.command}`);
    if (g.error) parts.push(g.error);
    $("status").textContent = parts.join("; ");
    const links = [...S.folder.files.map((n) => [n, n]),
                   ...g.files.map((n) => [(g.key ? g.key + "/" : "") + n, n])];
    const files = $("files");
    files.textContent = "";
    if (links.length) files.appendChild(document.createTextNode("The folder's figures: "));
    links.forEach(([path, name], k) => {
      const a = html("a", files, name);
      a.href = "/files/" + path.split("/").map(encodeURIComponent).join("/");
      a.target = "_blank";
      a.rel = "noopener";
      if (k < links.length - 1) files.appendChild(document.createTextNode(", "));
    });
  }

  function redraw() {
    $("layer-choice").hidden = S.key === PROBABILITY;
    drawMap(); drawLegend(); status(); header();
  }

  async function loadMap(key) {
    if (key !== PROBABILITY) S.map = await getJSON(`/api/map?${new URLSearchParams({map: key})}`);
    S.key = key;
    $("map-select").value = key;
    redraw();
  }

  function controls() {
    const f = S.folder, sel = $("map-select");
    sel.textContent = "";
    for (const m of f.maps) {
      const o = html("option", sel, m.label + (m.complete ? "" : ` (${m.done}/${m.total})`));
      o.value = m.key;
    }
    if (f.probability) {
      const o = html("option", sel, `all ${f.probability.subjects} subjects: share recovering`);
      o.value = PROBABILITY;
    }
    $("map-choice").hidden = f.kind === "sweep";
    $("others-choice").hidden = f.kind === "sweep";
    $("others-label").textContent = f.kind === "cohort" ? "every subject's boundary"
      : "every variant's boundary";
    const layers = $("layer-select");
    if (!layers.options.length) {
      for (const l of f.layers) html("option", layers, l.label).value = l.column;
    }
  }

  function wanted() {
    const q = new URLSearchParams(location.hash.slice(1));
    return {map: q.get("map"), force: q.get("force"), duration: q.get("duration")};
  }

  async function poll() {
    try {
      const f = await getJSON(`/api/folder?${new URLSearchParams({stamp: S.folder.stamp})}`);
      if (!f.unchanged) {
        S.folder = f;
        controls();
        const keep = S.key === PROBABILITY || f.maps.some((m) => m.key === S.key);
        await loadMap(keep ? S.key : (f.maps[0] || {}).key);
      }
    } catch (e) {
      $("status").textContent = e.message;
    }
    setTimeout(poll, 3000);
  }

  async function init() {
    try {
      S.folder = await getJSON("/api/folder");
    } catch (e) {
      showError(e.message);
      return;
    }
    controls();
    const w = wanted();
    const keys = S.folder.maps.map((m) => m.key);
    if (!keys.length) {
      $("status").textContent = "no subject's map yet: the page refreshes as the cohort runs";
      header();
    } else {
      try {
        if (S.folder.probability) keys.push(PROBABILITY);
        await loadMap(w.map !== null && keys.includes(w.map) ? w.map : keys[0]);
      } catch (e) {
        showError(e.message);
      }
      if (w.force !== null || w.duration !== null) openRun(w.force ?? "", w.duration ?? "");
    }
    setTimeout(poll, 3000);
  }

  $("map-select").addEventListener("change", (e) => {
    loadMap(e.target.value).catch((err) => showError(err.message));
  });
  $("layer-select").addEventListener("change", (e) => { S.layer = e.target.value; redraw(); });
  $("others").addEventListener("change", redraw);
  $("map").addEventListener("mousemove", showTip);
  $("map").addEventListener("mouseleave", hideTip);
  $("map").addEventListener("click", (e) => {
    const d = e.target.dataset;
    if (d && d.force !== undefined) openRun(d.force, d.duration);
  });
  $("play").addEventListener("click", play);
  $("time").addEventListener("input", (e) => { S.playing = false; $("play").textContent = "Play";
                                               if (S.figure) setFrame(Number(e.target.value)); });
  window.addEventListener("hashchange", () => {
    const w = wanted();
    if (w.force !== null) openRun(w.force, w.duration ?? "");
  });
  init();
})();
