// carbody annotate: the page. The server holds the marks and fits them; this script draws what
// it says and sends each edit (place, move, remove, hide, accept a ghost, pick a view).
"use strict";

const TOKEN = document.querySelector('meta[name="carbody-token"]').content;
const HIT_PX = 9;          // a press this close (screen px) to a mark or a ghost takes it
const DRAG_PX = 4;         // a press that moves further is a drag, not a click
const MIN_GHOST_R = 5;     // screen px

const app = {
  setup: null, state: null, photo: new Image(), current: null,
  view: { scale: 1, ox: 0, oy: 0 }, press: null, pointer: null,
  hover: null,             // the mark or ghost under the pointer (its name shows)
  latencies: [],           // {revision, ms, kind: "quick" | "refined"}: click to drawn
  pending: 0, ready: false,
};
window.carbody = app;      // the tests and the benchmark read it

const $ = (id) => document.getElementById(id);
const canvas = $("photo");
const ctx = canvas.getContext("2d");

// ---------------------------------------------------------------- server

async function api(path, body) {
  const options = body === undefined ? {} : {
    method: "POST", body: JSON.stringify(body),
    headers: { "Content-Type": "application/json", "X-Carbody-Token": TOKEN },
  };
  const response = await fetch(path, options);
  if (response.status === 204) return null;
  const data = await response.json();
  if (!response.ok) throw new Error(data.error || response.statusText);
  return data;
}

function say(text) { $("status").textContent = text; }

async function edit(body) {
  const started = performance.now();
  app.pending += 1;
  try {
    const state = await api("/api/edit", body);
    // placed, accepted or hidden: on to the next keypoint asked; removed: ask it again
    if (body.op === "remove") app.current = body.name;
    else if (body.op !== "view" && body.name === app.current) app.current = null;
    apply(state);
    const ms = performance.now() - started;
    app.latencies.push({ revision: state.revision, ms, kind: "quick", op: body.op });
    describeTiming(state, ms);
    if (state.fit.ok && !state.refined) awaitRefined(state.revision, started);
  } catch (error) {
    say(error.message);
  } finally {
    app.pending -= 1;
  }
}

async function awaitRefined(revision, started) {
  try {
    const state = await api(`/api/refined?revision=${revision}`);
    if (state && state.revision === revision && app.state.revision === revision) {
      apply(state);
      app.latencies.push({ revision, ms: performance.now() - started, kind: "refined" });
      describeTiming(state, null);
    }
  } catch (error) { /* a newer edit answers instead */ }
}

function describeTiming(state, ms) {
  const fit = state.fit;
  let text = `${Object.keys(state.marks).length} marks`;
  if (fit.ok) {
    const v = fit.view;
    text += ` · view ${v.azimuth_deg.toFixed(0)}°, ${v.elevation_deg.toFixed(0)}° up` +
      (v.distance_mm ? ` · camera ${(v.distance_mm / 1000).toFixed(1)} m` : " · far camera");
    text += state.refined ? " · full fit" : ` · quick fit ${(fit.seconds * 1000).toFixed(0)} ms`;
  } else if (fit.error) {
    text += ` · ${fit.error}`;
  }
  if (ms !== null) text += ` · updated in ${ms.toFixed(0)} ms`;
  if (state.saved) text += " · saved";
  say(text);
}

// ---------------------------------------------------------------- state

function apply(state) {
  if (app.state && state.revision < app.state.revision) return;  // a late answer to an older edit
  app.state = state;
  const c = app.current;
  const open = (n) => n && !(n in state.marks) && !state.hidden.includes(n);
  if (!c || (!(c in state.marks) && !open(c))) app.current = state.ask[0] || null;
  render();
}

function keypoint(name) { return app.setup.byName[name]; }

function label(name) {
  const k = keypoint(name);
  if (!k) return name;
  return k.side === "centre" ? k.label : `${k.label} (${k.side})`;
}

function askList() {
  const s = app.state;
  const list = s.ask.slice();
  if (app.current && !list.includes(app.current) && !(app.current in s.marks)) list.unshift(app.current);
  return list;
}

function step(delta) {
  const list = askList();
  if (!list.length) return;
  const i = list.indexOf(app.current);
  app.current = list[(i + delta + list.length) % list.length];
  render();
}

function target() {
  // the keypoint a click on the photo places: the one asked (a hidden one picked from the list
  // is shown again), or the first still to ask
  const s = app.state, c = app.current;
  if (c && !(c in s.marks)) return c;
  return s.ask[0] || null;
}

// ---------------------------------------------------------------- photo view

function resize() {
  const r = canvas.getBoundingClientRect();
  canvas.width = Math.round(r.width * devicePixelRatio);
  canvas.height = Math.round(r.height * devicePixelRatio);
  render();
}

function fitPhoto() {
  const r = canvas.getBoundingClientRect();
  const [w, h] = app.setup.image_size;
  const scale = Math.min(r.width / w, r.height / h) * 0.98;
  app.view = { scale, ox: (r.width - w * scale) / 2, oy: (r.height - h * scale) / 2 };
  render();
}

function toScreen(uv) { const v = app.view; return [uv[0] * v.scale + v.ox, uv[1] * v.scale + v.oy]; }
function toImage(xy) { const v = app.view; return [(xy[0] - v.ox) / v.scale, (xy[1] - v.oy) / v.scale]; }

// client (page) coordinates of a photo pixel: for the tests' mouse
app.imageToClient = (u, v) => {
  const r = canvas.getBoundingClientRect();
  const [x, y] = toScreen([u, v]);
  return [r.left + x, r.top + y];
};

function eventXY(e) { const r = canvas.getBoundingClientRect(); return [e.clientX - r.left, e.clientY - r.top]; }

function hit(xy) {
  // the mark or ghost under the pointer, marks first
  const s = app.state;
  let best = null, bestD = HIT_PX;
  const consider = (name, uv, kind) => {
    const p = toScreen(uv), d = Math.hypot(p[0] - xy[0], p[1] - xy[1]);
    if (d < bestD) { best = { name, kind }; bestD = d; }
  };
  for (const [n, uv] of Object.entries(s.marks)) consider(n, uv, "mark");
  if (best) return best;
  if (s.fit.ok) for (const [n, g] of Object.entries(s.fit.ghosts)) consider(n, g.uv, "ghost");
  return best;
}

function inside(uv) { const [w, h] = app.setup.image_size; return uv[0] >= 0 && uv[1] >= 0 && uv[0] <= w && uv[1] <= h; }

canvas.addEventListener("mousedown", (e) => {
  if (!app.state) return;
  // back on the photo, the keys are the page's again (not the list's or the folder box's)
  if (document.activeElement && document.activeElement !== document.body) document.activeElement.blur();
  const xy = eventXY(e);
  app.press = { xy, at: xy, grab: e.button === 0 ? hit(xy) : null, moved: false, view: { ...app.view } };
  e.preventDefault();
});

window.addEventListener("mousemove", (e) => {
  const p = app.press;
  if (!p) {                                      // no button down: name what is under the pointer
    if (!app.state) return;
    const xy = eventXY(e), r = canvas.getBoundingClientRect();
    const onPhoto = xy[0] >= 0 && xy[1] >= 0 && xy[0] <= r.width && xy[1] <= r.height;
    const over = onPhoto ? hit(xy) : null, name = over ? over.name : null;
    if (name !== app.hover) { app.hover = name; render(); }
    return;
  }
  const xy = eventXY(e);
  if (Math.hypot(xy[0] - p.xy[0], xy[1] - p.xy[1]) > DRAG_PX) p.moved = true;
  p.at = xy;
  if (p.moved && !p.grab) {
    app.view.ox = p.view.ox + xy[0] - p.xy[0];
    app.view.oy = p.view.oy + xy[1] - p.xy[1];
  }
  render();
});

window.addEventListener("mouseup", (e) => {
  const p = app.press;
  app.press = null;
  if (!p) return;
  const uv = toImage(p.at);
  if (p.grab && p.moved) {                       // a mark or a ghost dragged into place
    app.current = p.grab.name;
    if (inside(uv)) edit({ op: "place", name: p.grab.name, uv });
    else render();
  } else if (p.grab) {                           // a mark or a ghost selected
    app.current = p.grab.name;
    render();
  } else if (!p.moved && e.button === 0) {       // a click on the photo: the keypoint asked
    const name = target();
    if (name && inside(uv)) edit({ op: "place", name, uv });
  }
});

canvas.addEventListener("wheel", (e) => {
  e.preventDefault();
  const xy = eventXY(e), before = toImage(xy);
  const factor = Math.exp(-e.deltaY * 0.0015);
  app.view.scale = Math.min(40, Math.max(0.05, app.view.scale * factor));
  app.view.ox = xy[0] - before[0] * app.view.scale;
  app.view.oy = xy[1] - before[1] * app.view.scale;
  render();
}, { passive: false });

canvas.addEventListener("contextmenu", (e) => e.preventDefault());

// ---------------------------------------------------------------- keys

document.addEventListener("keydown", (e) => {
  if (!app.state || e.ctrlKey || e.metaKey || e.altKey) return;
  const tag = (e.target.tagName || "").toLowerCase();
  if (tag === "input" || tag === "select" || tag === "textarea") return;
  const key = e.key;
  if (key === "s" || key === "S") save();
  else if (key === "Enter") acceptCurrent();
  else if (key === "h" || key === "H") hideCurrent();
  else if (key === "n" || key === "N") step(+1);
  else if (key === "p" || key === "P") step(-1);
  else if (key === "Backspace" || key === "Delete") removeCurrent();
  else if (key === "f" || key === "F") fitPhoto();
  else return;
  e.preventDefault();
});

function acceptCurrent() {
  const s = app.state, c = app.current;
  if (c && s.fit.ok && s.fit.ghosts[c]) edit({ op: "accept", name: c });
}
function hideCurrent() { const c = target(); if (c) edit({ op: "hide", name: c }); }
function removeCurrent() { const c = app.current; if (c && (c in app.state.marks || app.state.hidden.includes(c))) edit({ op: "remove", name: c }); }

async function save() {
  try {
    const r = await api("/api/save", { coco: $("coco").checked });
    apply(r.state);
    say(`saved ${r.saved.join(", ")}`);
  } catch (error) { say(`not saved: ${error.message}`); }
}

async function reconstruct() {
  try {
    apply(await api("/api/reconstruct", { folder: $("folder").value.trim() }));
    pollReconstruction();
  } catch (error) { say(`cannot reconstruct: ${error.message}`); }
}

async function pollReconstruction() {
  const state = await api("/api/state");
  apply(state);
  if (state.reconstruction.state === "running") setTimeout(pollReconstruction, 800);
}

// ---------------------------------------------------------------- drawing: the photo

function render() {
  if (!app.setup || !app.state) return;
  const s = app.state, fit = s.fit, dpr = devicePixelRatio;
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  const v = app.view;
  if (app.photo.complete && app.photo.naturalWidth) {
    ctx.imageSmoothingEnabled = v.scale < 3;
    ctx.drawImage(app.photo, v.ox, v.oy, app.setup.image_size[0] * v.scale, app.setup.image_size[1] * v.scale);
  }
  ctx.font = "11px system-ui, sans-serif";
  if (fit.ok) {
    ctx.strokeStyle = "rgba(66, 165, 245, 0.85)";
    ctx.lineWidth = 1.2;
    for (const line of fit.wireframe) {
      ctx.beginPath();
      line.forEach((uv, i) => { const p = toScreen(uv); i ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1]); });
      ctx.stroke();
    }
    for (const [name, g] of Object.entries(fit.ghosts)) drawGhost(name, g);
  }
  for (const [name, uv] of Object.entries(s.marks)) drawMark(name, uv, fit.ok ? fit.marks[name] : null);
  const p = app.press;
  if (p && p.grab && p.moved) {                  // where a dragged point would land
    ctx.strokeStyle = "#ffeb3b"; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.arc(p.at[0], p.at[1], 6, 0, 2 * Math.PI); ctx.stroke();
  }
  $("settled").hidden = !s.settled;
  renderSide();
}

function drawGhost(name, g) {
  const p = toScreen(g.uv), current = name === app.current;
  const r = Math.max(MIN_GHOST_R, g.sd_px * app.view.scale);
  ctx.setLineDash([3, 3]);
  ctx.strokeStyle = current ? "#ffeb3b" : "rgba(118, 255, 3, 0.9)";
  ctx.lineWidth = current ? 2.2 : 1.2;
  ctx.beginPath(); ctx.arc(p[0], p[1], r, 0, 2 * Math.PI); ctx.stroke();
  ctx.setLineDash([]);
  ctx.fillStyle = ctx.strokeStyle;
  ctx.beginPath(); ctx.arc(p[0], p[1], 2, 0, 2 * Math.PI); ctx.fill();
  if (current || name === app.hover || app.view.scale > 1.2)
    text(label(name) + (current ? "  ⏎ accept" : ""), p[0] + r + 3, p[1] - 3, ctx.strokeStyle);
}

function drawMark(name, uv, info) {
  const p = toScreen(uv), current = name === app.current;
  const status = info ? info.status : "kept";
  const colour = { kept: "#ff1744", rejected: "#e040fb", renamed: "#ff9100", suspect: "#ff9100" }[status];
  if (info && info.reprojected) {                 // the mark to where the car puts it
    const q = toScreen(info.reprojected);
    ctx.strokeStyle = "rgba(0, 230, 118, 0.9)"; ctx.lineWidth = 1;
    ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
    ctx.fillStyle = "#00e676";
    ctx.beginPath(); ctx.arc(q[0], q[1], 2.2, 0, 2 * Math.PI); ctx.fill();
  }
  ctx.fillStyle = colour;
  ctx.beginPath(); ctx.arc(p[0], p[1], 4, 0, 2 * Math.PI); ctx.fill();
  if (status === "rejected") {                    // crossed out, as on the overlay
    ctx.strokeStyle = colour; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.moveTo(p[0] - 7, p[1] - 7); ctx.lineTo(p[0] + 7, p[1] + 7);
    ctx.moveTo(p[0] + 7, p[1] - 7); ctx.lineTo(p[0] - 7, p[1] + 7); ctx.stroke();
  }
  if (current) {
    ctx.strokeStyle = "#fff"; ctx.lineWidth = 2;
    ctx.beginPath(); ctx.arc(p[0], p[1], 8, 0, 2 * Math.PI); ctx.stroke();
  }
  let note = "";
  if (info && info.residual_px !== null) note = ` ${info.residual_px.toFixed(1)} px`;
  if (info && info.note) note += ` — ${info.note}`;
  if (current || name === app.hover || status !== "kept" || app.view.scale > 1.2)
    text(label(name) + note, p[0] + 7, p[1] + 12, colour);
  else if (note) text(note.trim(), p[0] + 6, p[1] + 12, colour);
}

function text(t, x, y, colour) {
  ctx.lineWidth = 3; ctx.strokeStyle = "rgba(0,0,0,0.75)"; ctx.strokeText(t, x, y);
  ctx.fillStyle = colour; ctx.fillText(t, x, y);
}

// ---------------------------------------------------------------- drawing: the side panel

function cameraAxes(azimuth, elevation) {
  // SPEC's camera: d toward the camera, image-right r, image-up w
  const t = azimuth * Math.PI / 180, f = elevation * Math.PI / 180;
  const d = [Math.sin(t) * Math.cos(f), -Math.cos(t) * Math.cos(f), Math.sin(f)];
  const fw = d.map((c) => -c);
  let r = [fw[1], -fw[0], 0];
  const n = Math.hypot(r[0], r[1]) || 1;
  r = r.map((c) => c / n);
  const w = [r[1] * fw[2] - r[2] * fw[1], r[2] * fw[0] - r[0] * fw[2], r[0] * fw[1] - r[1] * fw[0]];
  return { d, r, w };
}

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];

function drawReference(c, azimuth, elevation, highlight) {
  // the library's mean car seen from the view, the keypoint asked in red
  const g = c.getContext("2d"), ref = app.setup.reference, cp = ref.control_points;
  const { d, r, w } = cameraAxes(azimuth, elevation);
  const halves = [[1, false], [-1, true]];
  const segments = [];
  for (const [sx, mirror] of halves) {
    ref.central_curves.forEach((central, ci) => {
      if (mirror && central) return;
      const pts = [0, 1, 2, 3].map((k) => { const p = cp[4 * ci + k]; return [p[0] * sx, p[1], p[2]]; });
      const mid = pts.reduce((a, p) => [a[0] + p[0] / 4, a[1] + p[1] / 4, a[2] + p[2] / 4], [0, 0, 0]);
      segments.push({ pts, depth: dot(mid, d) });
    });
  }
  const all = segments.flatMap((s) => s.pts.map((p) => [dot(p, r), -dot(p, w)]));
  const xs = all.map((p) => p[0]), ys = all.map((p) => p[1]);
  const [x0, x1, y0, y1] = [Math.min(...xs), Math.max(...xs), Math.min(...ys), Math.max(...ys)];
  const W = c.width, H = c.height, pad = 12;
  const s = Math.min((W - 2 * pad) / (x1 - x0), (H - 2 * pad) / (y1 - y0));
  const ox = (W - s * (x1 - x0)) / 2 - s * x0, oy = (H - s * (y1 - y0)) / 2 - s * y0;
  const at = (p) => [ox + s * dot(p, r), oy - s * dot(p, w)];
  g.clearRect(0, 0, W, H);
  const depths = segments.map((q) => q.depth), dmin = Math.min(...depths), dmax = Math.max(...depths);
  segments.sort((a, b) => a.depth - b.depth);
  for (const seg of segments) {
    const near = (seg.depth - dmin) / (dmax - dmin || 1);
    g.strokeStyle = `rgba(38, 50, 56, ${0.15 + 0.75 * near})`;
    g.lineWidth = 0.6 + near;
    const q = seg.pts.map(at);
    g.beginPath(); g.moveTo(...q[0]); g.bezierCurveTo(...q[1], ...q[2], ...q[3]); g.stroke();
  }
  if (highlight) {
    const k = keypoint(highlight);
    const p0 = cp[k.point_index], p = [k.side === "right" ? -p0[0] : p0[0], p0[1], p0[2]];
    const q = at(p);
    g.fillStyle = "#d50000";
    g.beginPath(); g.arc(q[0], q[1], 5, 0, 2 * Math.PI); g.fill();
    g.strokeStyle = "#d50000"; g.lineWidth = 2;
    g.beginPath(); g.arc(q[0], q[1], 11, 0, 2 * Math.PI); g.stroke();
  }
}

function renderSide() {
  const s = app.state, c = app.current, fit = s.fit;
  const list = askList();
  const k = c ? keypoint(c) : null;
  $("ask-name").textContent = c ? label(c) : "every keypoint asked";
  $("ask-count").textContent = `${Object.keys(s.marks).length} marked · ${list.length} to ask`;
  $("ask-desc").textContent = k ? `#${k.id}: ${k.description}` : "Save, or Reconstruct.";
  let hint = "";
  if (c && c in s.marks) hint = "marked: drag it to move it, Backspace removes it";
  else if (c && fit.ok && fit.ghosts[c]) {
    const g = fit.ghosts[c];
    hint = `click it on the photo, or Enter to accept the ghost (±${g.sd_px.toFixed(0)} px), or drag the ghost; ` +
      "H if the photo does not show it. Any other ghost off its point: drag it there, the furthest off first " +
      "(a ghost's name shows under the pointer). When no ghost is off its point, Save";
  }
  else if (c) hint = "click it on the photo, H if the photo does not show it";
  $("ask-hint").textContent = hint;
  $("accept").disabled = !(c && fit.ok && fit.ghosts[c]);
  drawReference($("reference"), s.view.azimuth_deg, Math.max(8, s.view.elevation_deg), c);
  // the list to pick from
  const pick = $("pick");
  if (pick.dataset.revision !== String(s.revision) || pick.value !== (c || "")) {
    pick.innerHTML = "";
    const add = (name, extra) => {
      const o = document.createElement("option");
      o.value = name; o.textContent = `${keypoint(name).id}. ${label(name)}${extra}`;
      pick.appendChild(o);
    };
    for (const kp of app.setup.keypoints) {
      const n = kp.name;
      add(n, n in s.marks ? " ✓" : s.hidden.includes(n) ? " (hidden)" : fit.ok && fit.ghosts[n] ? " (ghost)" : "");
    }
    pick.value = c || "";
    pick.dataset.revision = String(s.revision);
  }
  // views to pick
  $("view-source").textContent = `(${{ fit: "fitted", classifier: "the classifier's guess", picked: "picked", told: "told", default: "a guess" }[s.view.source] || s.view.source}: ${s.view.azimuth_deg.toFixed(0)}°)`;
  document.querySelectorAll("#view-choices canvas").forEach((v) => {
    const a = Number(v.dataset.azimuth);
    const off = Math.abs(((s.view.azimuth_deg - a) % 360 + 540) % 360 - 180);
    v.classList.toggle("chosen", off <= 22.5);
  });
  // diagnostics
  const summary = $("fit-summary"), diag = $("diagnostics");
  diag.innerHTML = "";
  if (!fit.ok) {
    summary.textContent = fit.error || "the car is fitted from the fifth mark on";
    return;
  }
  const m = fit.summary;
  summary.textContent = `mean residual ${m.mean_residual_px === null ? "—" : m.mean_residual_px.toFixed(1) + " px"} · wheelbase ${m.wheelbase_mm} mm` +
    (m.fits_poorly ? " · no car fits these marks well: check their names" : "") +
    (m.misses_marks ? " · the car misses the marks" : "") +
    (m.swapped ? ` · ${m.swapped.join(" / ")} look exchanged` : "");
  const rows = Object.entries(fit.marks).sort((a, b) => (b[1].status !== "kept") - (a[1].status !== "kept") || (b[1].residual_px || 0) - (a[1].residual_px || 0));
  for (const [name, info] of rows) {
    const li = document.createElement("li");
    li.className = info.status;
    li.textContent = `${label(name)}: ${info.residual_px === null ? "—" : info.residual_px.toFixed(1) + " px"}${info.note ? " — " + info.note : ""}`;
    li.addEventListener("click", () => { app.current = name; render(); });
    diag.appendChild(li);
  }
  // reconstruction
  const rec = s.reconstruction;
  $("result").hidden = rec.state === "idle";
  if (rec.state === "running") $("result-status").textContent = `running (${rec.stage}) into ${rec.folder} …`;
  else if (rec.state === "failed") $("result-status").textContent = `failed: ${rec.error}`;
  else if (rec.state === "done") {
    $("result-status").textContent = `wrote ${rec.files.length} files to ${rec.folder}`;
    const box = $("result-images");
    if (box.dataset.folder !== rec.folder + rec.files.join()) {
      box.innerHTML = "";
      for (const name of ["overlay.png", "body.png"]) {
        const img = document.createElement("img");
        img.src = `/result/${name}?t=${Date.now()}`; img.alt = name;
        box.appendChild(img);
      }
      box.dataset.folder = rec.folder + rec.files.join();
    }
  }
}

// ---------------------------------------------------------------- start

async function start() {
  const setup = await api("/api/setup");
  setup.byName = Object.fromEntries(setup.keypoints.map((k) => [k.name, k]));
  app.setup = setup;
  $("image-name").textContent = `${setup.image} → ${setup.output.split("/").pop()}`;
  $("image-name").title = `marks are saved to ${setup.output}`;
  const legend = $("key-legend");
  for (const [k, what] of setup.keys) {
    const item = document.createElement("span");
    const key = document.createElement("kbd");
    key.textContent = k;
    item.append(key, " " + what);
    legend.appendChild(item);
  }
  const choices = $("view-choices");
  for (const azimuth of setup.views) {
    const c = document.createElement("canvas");
    c.width = 160; c.height = 92; c.dataset.azimuth = azimuth; c.title = `${azimuth}°`;
    c.addEventListener("click", () => edit({ op: "view", azimuth }));
    choices.appendChild(c);
    drawReference(c, azimuth, 12, null);
  }
  $("save").addEventListener("click", save);
  $("reconstruct").addEventListener("click", reconstruct);
  $("prev").addEventListener("click", () => step(-1));
  $("next").addEventListener("click", () => step(+1));
  $("hide").addEventListener("click", hideCurrent);
  $("accept").addEventListener("click", acceptCurrent);
  $("pick").addEventListener("change", (e) => { app.current = e.target.value; e.target.blur(); render(); });
  const state = await api("/api/state");
  $("coco").checked = state.coco_output !== null;
  app.photo.onload = () => { resize(); fitPhoto(); app.ready = true; };
  app.photo.src = "/photo";
  apply(state);
  describeTiming(state, null);
  window.addEventListener("resize", resize);
  // the classifier's guess lands a few seconds after start: follow it (for half a minute)
  const follow = async (tries) => {
    if (tries <= 0 || app.state.view.source !== "default") return;
    if (!app.pending) apply(await api("/api/state"));
    setTimeout(() => follow(tries - 1), 1500);
  };
  setTimeout(() => follow(20), 1500);
}

start().catch((error) => say(`cannot start: ${error.message}`));
