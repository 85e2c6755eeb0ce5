// socialnav episode viewer: plain JavaScript, no library, no network. Reads the JSON embedded in
// <script id="episode-data" type="application/json"> (see socialnav/viz/report_data.py for the layout).
(function () {
  "use strict";
  const DATA = JSON.parse(document.getElementById("episode-data").textContent);
  const $ = (id) => document.getElementById(id);
  const canvas = $("viewer-canvas");
  const ctx = canvas.getContext("2d");
  const ROBOT_FACE = "#ffd23f", ROBOT_EDGE = "#111111", RED = "#d62728";
  const HUMANS = ["#1f77b4", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#ff7f0e", "#7f7f7f"];
  const colour = (a) => (a === 0 ? ROBOT_EDGE : HUMANS[(a - 1) % HUMANS.length]);
  const state = { ep: null, k: 0, playing: false, last: null, acc: 0 };

  function option(select, value, text) {
    const o = document.createElement("option");
    o.value = value;
    o.textContent = text;
    select.appendChild(o);
  }
  function esc(text) {
    return String(text).replace(/[&<>"']/g, (c) => ({"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;"})[c]);
  }
  function fill(select, items) {
    const keep = select.value;
    select.innerHTML = "";
    items.forEach(([v, t]) => option(select, v, t));
    if (items.some(([v]) => v === keep)) select.value = keep;
  }

  // ------------------------------------------------------------------ selection
  function cellsOf(policy) {
    return DATA.cells.filter((c) => c.policy === policy);
  }
  function currentCell() {
    return DATA.cells[Number($("sel-cell").value)];
  }
  function refreshPolicies() {
    fill($("sel-policy"), [...new Set(DATA.cells.map((c) => c.policy))].map((p) => [p, p]));
    refreshCells();
  }
  function refreshCells() {
    const policy = $("sel-policy").value;
    fill($("sel-cell"), DATA.cells.map((c, i) => [String(i), c]).filter(([, c]) => c.policy === policy)
      .map(([i, c]) => [i, c.scenario + " / " + c.visibility]));
    refreshEpisodes();
  }
  function refreshEpisodes() {
    const cell = currentCell();
    if (!cell) return;
    const metric = $("sel-metric").value;
    const items = [];
    const picks = (cell.picks || {})[metric] || {};
    Object.keys(picks).forEach((which) => { // best first, then by rank (q0.25, median, ...) to worst
      if (picks[which] !== undefined) {
        const ep = DATA.episodes[picks[which]];
        items.push([String(picks[which]), which + " by metric: " + ep.id + " (" + fmt(ep.values[metric]) + ")"]);
      }
    });
    const listed = cell.episodes.slice().sort((a, b) => cmp(DATA.episodes[a].values[metric], DATA.episodes[b].values[metric]));
    listed.forEach((e) => {
      const ep = DATA.episodes[e];
      items.push([String(e) + ":", ep.id + " · " + ep.outcome + " · " + fmt(ep.values[metric])]);
    });
    fill($("sel-episode"), items);
    load(parseInt($("sel-episode").value, 10));
  }
  function cmp(a, b) {
    const fa = Number.isFinite(a), fb = Number.isFinite(b);
    if (!fa || !fb) return fa ? -1 : fb ? 1 : 0;
    return a - b;
  }
  function fmt(v) {
    return Number.isFinite(v) ? (Math.abs(v) >= 100 ? v.toFixed(0) : v.toPrecision(3)) : "–";
  }

  // ------------------------------------------------------------------ episode
  function load(index) {
    const ep = DATA.episodes[index];
    if (!ep) return;
    if (!ep.P) {
      ep.P = ep.pos.map((v) => (v === null ? NaN : v / DATA.scale)); // decode once: (S * A * 2) metres; NaN: not in view
      ep.S = ep.P.length / (2 * ep.radii.length);
      ep.W = (ep.walls || []).map((w) => w.map((v) => v / DATA.scale)); // [x, y, x, y, ...] metres
      // routes planned at the start (socialnav/viz/routes.py): [agent, [x, y, x, y, ...] metres]
      ep.R = Object.keys(ep.routes || {}).map((a) => [Number(a), ep.routes[a].map((v) => v / DATA.scale)]);
    }
    state.ep = ep;
    state.k = 0;
    $("scrub").max = String(ep.S - 1);
    $("scrub").value = "0";
    // labels and ids come from the user (--label, scenario names): text, never markup
    const rows = Object.keys(ep.values).map((k) => "<tr><td>" + esc(DATA.metric_labels[k] || k) + "</td><td>" + fmt(ep.values[k]) + "</td></tr>");
    $("episode-info").innerHTML = "<b>" + esc(ep.id) + "</b> · " + esc(ep.policy) + " · <b>" + esc(ep.outcome) + "</b> · " +
      ((ep.n_main - 1) * ep.dt).toFixed(2) + " s" + (ep.S > ep.n_main ? " (+ " + ((ep.S - ep.n_main) * ep.dt).toFixed(2) + " s after arrival)" : "") +
      "<table class='mini'>" + rows.join("") + "</table>";
    fitView();
    draw();
  }
  function P(k, a) {
    const ep = state.ep, i = 2 * (k * ep.radii.length + a);
    return [ep.P[i], ep.P[i + 1]];
  }
  let view = null;
  function fitView() {
    const ep = state.ep;
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    const take = (x, y) => {
      if (!Number.isFinite(x) || !Number.isFinite(y)) return; // an agent not in view then (a log)
      x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
    };
    for (let i = 0; i < ep.P.length; i += 2) take(ep.P[i], ep.P[i + 1]);
    ep.goals.forEach(([x, y]) => take(x, y));
    const pad = Math.max(...ep.radii) + 0.6;
    x0 -= pad; x1 += pad; y0 -= pad; y1 += pad;
    // walls within WALL_CONTEXT m of the agents (as socialnav/viz/geometry.py's scene_bounds)
    const c = 2.0, ax0 = x0 - c, ax1 = x1 + c, ay0 = y0 - c, ay1 = y1 + c;
    ep.W.forEach((w) => {
      for (let i = 0; i < w.length; i += 2) {
        take(Math.min(Math.max(w[i], ax0), ax1), Math.min(Math.max(w[i + 1], ay0), ay1));
      }
    });
    const s = Math.min(canvas.width / (x1 - x0), canvas.height / (y1 - y0));
    view = { s: s, ox: (canvas.width - s * (x1 - x0)) / 2 - s * x0, oy: (canvas.height + s * (y1 - y0)) / 2 + s * y0 };
  }
  const X = (x) => view.ox + view.s * x;
  const Y = (y) => view.oy - view.s * y;

  function circle(x, y, r, fill, stroke, width, dash) {
    ctx.beginPath();
    ctx.arc(X(x), Y(y), r * view.s, 0, 2 * Math.PI);
    ctx.setLineDash(dash || []);
    if (fill) { ctx.fillStyle = fill; ctx.fill(); }
    if (stroke) { ctx.strokeStyle = stroke; ctx.lineWidth = width || 1; ctx.stroke(); }
    ctx.setLineDash([]);
  }
  function velocityRect(k, a) {
    // M_II rectangle: width 2r, length tau*|v| along the executed velocity, rear edge on the centre
    const ep = state.ep;
    if (k < 1) return null;
    const [x, y] = P(k, a), [px, py] = P(k - 1, a);
    const vx = (x - px) / ep.dt, vy = (y - py) / ep.dt, sp = Math.hypot(vx, vy);
    if (!(sp > 1e-6)) return null; // standing, or not in view (NaN)
    const ux = vx / sp, uy = vy / sp, nx = -uy, ny = ux, r = ep.radii[a], t = DATA.tau;
    const tx = x + t * vx, ty = y + t * vy;
    return [[x + r * nx, y + r * ny], [x - r * nx, y - r * ny], [tx - r * nx, ty - r * ny], [tx + r * nx, ty + r * ny]];
  }
  function draw() {
    const ep = state.ep;
    ctx.fillStyle = "#ffffff";
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    if (!ep) return;
    const k = state.k, A = ep.radii.length;
    // grid, 1 m
    ctx.strokeStyle = "#eeeeee";
    ctx.lineWidth = 1;
    for (let g = -50; g <= 50; g++) {
      ctx.beginPath(); ctx.moveTo(X(g), 0); ctx.lineTo(X(g), canvas.height); ctx.stroke();
      ctx.beginPath(); ctx.moveTo(0, Y(g)); ctx.lineTo(canvas.width, Y(g)); ctx.stroke();
    }
    ep.W.forEach((w) => { // walls: solid polygons filled, segments as thick lines
      ctx.beginPath();
      for (let i = 0; i < w.length; i += 2) (i ? ctx.lineTo(X(w[i]), Y(w[i + 1])) : ctx.moveTo(X(w[i]), Y(w[i + 1])));
      ctx.strokeStyle = "#4a4a4a";
      if (w.length > 4) {
        ctx.closePath(); ctx.fillStyle = "#9a9a9a"; ctx.fill(); ctx.lineWidth = 1;
      } else {
        ctx.lineWidth = Math.max(4, 0.08 * view.s);
      }
      ctx.stroke();
    });
    if (ep.R.length && $("ov-routes") && $("ov-routes").checked) { // dashed, thin, under the agents
      ep.R.forEach(([a, r]) => {
        ctx.beginPath();
        for (let i = 0; i < r.length; i += 2) (i ? ctx.lineTo(X(r[i]), Y(r[i + 1])) : ctx.moveTo(X(r[i]), Y(r[i + 1])));
        ctx.setLineDash([6, 4]); ctx.strokeStyle = colour(a); ctx.globalAlpha = 0.6; ctx.lineWidth = 1.2;
        ctx.stroke(); ctx.globalAlpha = 1; ctx.setLineDash([]);
      });
    }
    for (let a = 0; a < A; a++) { // goals
      const [gx, gy] = ep.goals[a];
      ctx.fillStyle = colour(a);
      ctx.font = (a === 0 ? 20 : 14) + "px sans-serif";
      ctx.textAlign = "center"; ctx.textBaseline = "middle";
      ctx.fillText("★", X(gx), Y(gy));
    }
    if ($("ov-trails").checked) {
      for (let a = 0; a < A; a++) {
        ctx.beginPath();
        let pen = false; // lifted where the agent is not in view
        for (let j = 0; j <= k; j++) {
          const [x, y] = P(j, a);
          if (!Number.isFinite(x)) { pen = false; continue; }
          pen ? ctx.lineTo(X(x), Y(y)) : ctx.moveTo(X(x), Y(y));
          pen = true;
        }
        ctx.strokeStyle = colour(a); ctx.globalAlpha = 0.6; ctx.lineWidth = 1.5; ctx.stroke(); ctx.globalAlpha = 1;
      }
    }
    if ($("ov-m2").checked) {
      for (let a = 0; a < A; a++) {
        const rect = velocityRect(k, a);
        if (!rect) continue;
        ctx.beginPath();
        rect.forEach(([x, y], i) => (i ? ctx.lineTo(X(x), Y(y)) : ctx.moveTo(X(x), Y(y))));
        ctx.closePath();
        const bad = a === 0 && ep.m2[k] === "1";
        ctx.strokeStyle = bad ? RED : colour(a); ctx.lineWidth = bad ? 2 : 1; ctx.stroke();
        if (bad) { ctx.fillStyle = "rgba(214,39,40,0.2)"; ctx.fill(); }
      }
    }
    for (let a = A - 1; a >= 0; a--) {
      const [x, y] = P(k, a);
      if (!Number.isFinite(x)) continue;
      circle(x, y, ep.radii[a], a === 0 ? ROBOT_FACE : colour(a), colour(a), a === 0 ? 2 : 1);
    }
    if ($("ov-m1").checked) {
      const [x, y] = P(k, 0);
      const bad = ep.m1[k] === "1";
      circle(x, y, ep.radii[0] + DATA.eps, null, bad ? RED : "#555555", bad ? 2.5 : 1, [5, 4]);
    }
    if ($("ov-m6").checked && ep.side && k >= ep.side[0]) {
      const [x, y] = P(ep.side[0], 0);
      ctx.setLineDash([8, 3, 2, 3]); ctx.strokeStyle = "#444444"; ctx.lineWidth = 1;
      ctx.beginPath(); ctx.moveTo(0, Y(y)); ctx.lineTo(canvas.width, Y(y)); ctx.stroke(); ctx.setLineDash([]);
      ctx.fillStyle = "#222222"; ctx.font = "14px sans-serif"; ctx.textAlign = "left";
      ctx.fillText("M_VI: " + ep.side[1], X(x) + 12, Y(y) - 12);
    }
    for (let j = 0; j <= k; j++) {
      if (ep.collision[j] !== "1") continue;
      const [x, y] = P(j, 0);
      ctx.strokeStyle = RED; ctx.lineWidth = 3;
      ctx.beginPath(); ctx.moveTo(X(x) - 9, Y(y) - 9); ctx.lineTo(X(x) + 9, Y(y) + 9);
      ctx.moveTo(X(x) + 9, Y(y) - 9); ctx.lineTo(X(x) - 9, Y(y) + 9); ctx.stroke();
    }
    ctx.fillStyle = "#000000"; ctx.font = "15px sans-serif"; ctx.textAlign = "left"; ctx.textBaseline = "top";
    let label = "t = " + (k * ep.dt).toFixed(2) + " s";
    if (k >= ep.n_main) label += " (after arrival)";
    if (ep.m1[k] === "1" && $("ov-m1").checked) label += "  M_I!";
    if (ep.m2[k] === "1" && $("ov-m2").checked) label += "  M_II!";
    ctx.fillText(label, 10, 10);
    $("time-label").textContent = label;
  }

  // ------------------------------------------------------------------ playback
  function tick(now) {
    if (!state.playing) return;
    const ep = state.ep;
    if (state.last !== null) state.acc += ((now - state.last) / 1000) * Number($("sel-speed").value);
    state.last = now;
    while (state.acc >= ep.dt && state.k < ep.S - 1) { state.acc -= ep.dt; state.k += 1; }
    $("scrub").value = String(state.k);
    draw();
    if (state.k >= ep.S - 1) { setPlaying(false); return; }
    requestAnimationFrame(tick);
  }
  function setPlaying(on) {
    state.playing = on;
    $("btn-play").textContent = on ? "❚❚ Pause" : "▶ Play";
    if (on) {
      if (state.k >= state.ep.S - 1) state.k = 0;
      state.last = null; state.acc = 0;
      requestAnimationFrame(tick);
    }
  }

  $("btn-play").addEventListener("click", () => setPlaying(!state.playing));
  $("scrub").addEventListener("input", () => { state.k = Number($("scrub").value); draw(); });
  $("sel-policy").addEventListener("change", refreshCells);
  $("sel-cell").addEventListener("change", refreshEpisodes);
  $("sel-metric").addEventListener("change", refreshEpisodes);
  $("sel-episode").addEventListener("change", () => { setPlaying(false); load(parseInt($("sel-episode").value, 10)); });
  ["ov-trails", "ov-m1", "ov-m2", "ov-m6", "ov-routes"].forEach((id) => $(id) && $(id).addEventListener("change", draw));
  fill($("sel-metric"), DATA.metrics.map((m) => [m.key, m.label]));
  refreshPolicies();
  if (location.hash === "#play") setPlaying(true);
})();
