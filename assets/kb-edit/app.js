// citygen kb edit: the page. Talks to the server's JSON API (docs/kb-editor.md) with the
// session token; every edit is checked by the server before the draft takes it.
"use strict";

const TOKEN = document.body.dataset.token;
const $ = (id) => document.getElementById(id);
const ATTRS = ["color", "material", "nbfloor", "minFloors", "maxFloors", "minHeight", "maxHeight",
  "floorsize", "rooftype", "roofangle", "roofColor", "doorCol", "openingCol", "windowfcolor",
  "windowheight", "windowwidth", "doorwidth", "doorheight", "minopeningwidth", "windowstyle", "windowmaterial",
  "programme", "infer"];
const KM_PER_DEG = 111.195;

const app = {
  st: null, fps: [], zone: "earth", building: null, tool: "select", draft: [],
  view: { cx: 0, cy: 0, k: 1, cos: 1 }, drag: null, viewer: null,
};

function esc(s) {
  return String(s ?? "").replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" }[c]));
}

function say(text, bad) {
  const m = $("message");
  m.textContent = text || "";
  m.className = bad ? "bad" : text ? "good" : "";
}

async function api(path, body) {
  const opts = { headers: { "X-Citygen-Token": TOKEN } };
  if (body !== undefined) {
    opts.method = "POST";
    opts.headers["Content-Type"] = "application/json";
    opts.body = JSON.stringify(body);
  }
  const r = await fetch(path, opts);
  if (path.startsWith("/api/preview") && r.ok) return r.arrayBuffer();
  const j = await r.json();
  if (!r.ok) throw new Error(j.error || r.statusText);
  return j;
}

async function edit(op) {
  try {
    app.st = await api("/api/edit", op);
    say("Edit checked and applied to the draft (not saved yet).");
    render();
    return true;
  } catch (e) {
    say(e.message, true);
    return false;
  }
}

function zoneOf(path) { return app.st.zones.find((z) => z.path === path); }

// ---------------------------------------------------------------------------------- map --

const canvas = $("map");
const ctx = canvas.getContext("2d");

function toPx(lon, lat) {
  const v = app.view;
  return [canvas.width / 2 + (lon - v.cx) * v.k * v.cos, canvas.height / 2 - (lat - v.cy) * v.k];
}
function toLonLat(x, y) {
  const v = app.view;
  return [v.cx + (x - canvas.width / 2) / (v.k * v.cos), v.cy - (y - canvas.height / 2) / v.k];
}

function fitTo(lo, hi) {
  const v = app.view;
  v.cx = (lo[0] + hi[0]) / 2;
  v.cy = (lo[1] + hi[1]) / 2;
  v.cos = Math.cos(v.cy * Math.PI / 180);
  v.k = Math.min(canvas.width / ((hi[0] - lo[0]) * v.cos + 1e-9), canvas.height / (hi[1] - lo[1] + 1e-9)) * 0.9;
}

function inRing(pt, ring) {
  let inside = false;
  for (let i = 0, j = ring.length - 1; i < ring.length; j = i++) {
    const [xi, yi] = ring[i], [xj, yj] = ring[j];
    if ((yi > pt[1]) !== (yj > pt[1]) && pt[0] < (xj - xi) * (pt[1] - yi) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

function path(ring) {
  ctx.beginPath();
  ring.forEach(([lon, lat], i) => {
    const [x, y] = toPx(lon, lat);
    if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y);
  });
  ctx.closePath();
}

function drawZone(z, selected) {
  ctx.lineWidth = selected ? 3 : 1;
  ctx.strokeStyle = selected ? "#d0402a" : "rgba(40,80,160,0.6)";
  ctx.fillStyle = selected ? "rgba(208,64,42,0.10)" : "rgba(40,80,160,0.04)";
  if (z.circle) {
    const [x, y] = toPx(z.circle.lon, z.circle.lat);
    const r = z.circle.dist / KM_PER_DEG * app.view.k;
    if (r < 5e4) {
      ctx.beginPath();
      ctx.ellipse(x, y, r, r, 0, 0, 2 * Math.PI);
      ctx.fill();
      ctx.stroke();
      if (selected) { handle(x, y); handle(x + r, y); }
    }
  }
  for (const ring of z.polygons) {
    path(ring);
    ctx.fill();
    ctx.stroke();
    if (selected && ring.length < 200) for (const [lon, lat] of ring) handle(...toPx(lon, lat));
  }
}

function handle(x, y) {
  ctx.fillStyle = "#fff";
  ctx.strokeStyle = "#d0402a";
  ctx.lineWidth = 2;
  ctx.fillRect(x - 4, y - 4, 8, 8);
  ctx.strokeRect(x - 4, y - 4, 8, 8);
}

function visible(z) {
  const [w, n] = toLonLat(0, 0), [e, s] = toLonLat(canvas.width, canvas.height);
  if (z.circle) {
    const d = z.circle.dist / KM_PER_DEG;
    if (z.circle.lon + d / app.view.cos > w && z.circle.lon - d / app.view.cos < e && z.circle.lat + d > s && z.circle.lat - d < n) return true;
  }
  return z.polygons.some((r) => r.some(([lon, lat]) => lon > w && lon < e && lat > s && lat < n)) ||
    z.polygons.some((r) => { const c = [(w + e) / 2, (s + n) / 2]; return inRing(c, r); });
}

function drawMap() {
  const box = $("mapbox");
  if (canvas.width !== box.clientWidth || canvas.height !== box.clientHeight) {
    canvas.width = box.clientWidth;
    canvas.height = box.clientHeight;
  }
  ctx.fillStyle = "#f4f1ea";
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  ctx.lineJoin = "round";
  for (const f of app.fps) {
    for (const ring of f.rings) {
      path(ring);
      ctx.fillStyle = app.building && app.building.i === f.i ? "#f0a020" : "#b9b2a6";
      ctx.fill();
      ctx.strokeStyle = "#7d766b";
      ctx.lineWidth = 0.5;
      ctx.stroke();
    }
  }
  if (app.st) {
    for (const z of app.st.zones) if (z.depth > 0 && z.path !== app.zone && visible(z)) drawZone(z, false);
    const sel = zoneOf(app.zone);
    if (sel && sel.depth > 0) drawZone(sel, true);
  }
  if (app.draft.length) {
    ctx.strokeStyle = "#0a7d32";
    ctx.lineWidth = 2;
    ctx.setLineDash([6, 4]);
    ctx.beginPath();
    app.draft.forEach(([lon, lat], i) => { const [x, y] = toPx(lon, lat); if (i) ctx.lineTo(x, y); else ctx.moveTo(x, y); });
    if (app.tool === "polygon") ctx.closePath();
    ctx.stroke();
    ctx.setLineDash([]);
    for (const [lon, lat] of app.draft) { const [x, y] = toPx(lon, lat); ctx.fillStyle = "#0a7d32"; ctx.fillRect(x - 3, y - 3, 6, 6); }
  }
}

function setTool(t) {
  app.tool = t;
  app.draft = [];
  for (const n of ["select", "polygon", "circle"]) $("tool-" + n).classList.toggle("on", n === t);
  $("finish").disabled = t === "select";
  $("hint").textContent = {
    select: "Click a footprint to see its zone, appearance and preview; drag a selected zone's square handles to move or resize it.",
    polygon: "Click the corners of the new zone; Finish makes it a sub-zone of the selected zone.",
    circle: "Click the centre, then a point on the rim; Finish makes it a sub-zone of the selected zone.",
  }[t];
  drawMap();
}

// The handle under (x, y) of the selected zone: ["centre"|"rim"] or ["vertex", polygon, index].
function handleAt(x, y) {
  const z = zoneOf(app.zone);
  if (!z || z.depth === 0) return null;
  const near = (px, py) => Math.abs(px - x) < 7 && Math.abs(py - y) < 7;
  if (z.circle) {
    const [cx, cy] = toPx(z.circle.lon, z.circle.lat);
    const r = z.circle.dist / KM_PER_DEG * app.view.k;
    if (near(cx, cy)) return ["centre"];
    if (near(cx + r, cy)) return ["rim"];
  }
  for (let p = 0; p < z.polygons.length; p++)
    for (let i = 0; i < z.polygons[p].length; i++) {
      const [px, py] = toPx(...z.polygons[p][i]);
      if (near(px, py)) return ["vertex", p, i];
    }
  return null;
}

canvas.addEventListener("mousedown", (e) => {
  const x = e.offsetX, y = e.offsetY;
  if (app.tool === "select") {
    const h = handleAt(x, y);
    app.drag = { x, y, moved: false, handle: h, view: { ...app.view } };
  } else {
    app.drag = { x, y, moved: false, handle: null, view: { ...app.view }, drawing: true };
  }
});

window.addEventListener("mousemove", (e) => {
  const d = app.drag;
  if (!d) return;
  const r = canvas.getBoundingClientRect();
  const x = e.clientX - r.left, y = e.clientY - r.top;
  if (Math.abs(x - d.x) + Math.abs(y - d.y) > 3) d.moved = true;
  if (!d.moved) return;
  if (d.handle) {
    const z = zoneOf(app.zone);
    const ll = toLonLat(x, y);
    if (d.handle[0] === "centre") { z.circle.lon = ll[0]; z.circle.lat = ll[1]; }
    else if (d.handle[0] === "rim") {
      const c = toPx(z.circle.lon, z.circle.lat);
      z.circle.dist = Math.max(0.001, Math.hypot(x - c[0], y - c[1]) / app.view.k * KM_PER_DEG);
    } else z.polygons[d.handle[1]][d.handle[2]] = ll;
  } else {
    app.view.cx = d.view.cx - (x - d.x) / (app.view.k * app.view.cos);
    app.view.cy = d.view.cy + (y - d.y) / app.view.k;
  }
  drawMap();
});

window.addEventListener("mouseup", async (e) => {
  const d = app.drag;
  app.drag = null;
  if (!d) return;
  if (d.moved && d.handle) {
    const z = zoneOf(app.zone);
    const ok = d.handle[0] === "vertex"
      ? await edit({ op: "set_polygon", zone: z.path, index: d.handle[1], points: z.polygons[d.handle[1]] })
      : await edit({ op: "set_circle", zone: z.path, circle: z.circle });
    if (!ok) await reload();
    return;
  }
  if (d.moved || e.target !== canvas) return;
  const ll = toLonLat(d.x, d.y);
  if (app.tool === "select") return pick(ll);
  if (app.tool === "circle" && app.draft.length >= 2) app.draft = [];
  app.draft.push(ll);
  drawMap();
});

canvas.addEventListener("wheel", (e) => {
  e.preventDefault();
  const before = toLonLat(e.offsetX, e.offsetY);
  app.view.k *= Math.exp(-e.deltaY * 0.0015);
  const after = toLonLat(e.offsetX, e.offsetY);
  app.view.cx += before[0] - after[0];
  app.view.cy += before[1] - after[1];
  drawMap();
}, { passive: false });

async function pick(ll) {
  const f = app.fps.find((f) => f.rings.some((r) => inRing(ll, r)));
  if (f) return selectBuilding(f.i);
  // The deepest zone with a shape under the point.
  let best = null;
  for (const z of app.st.zones) {
    if (z.depth === 0) continue;
    const inC = z.circle && Math.hypot((ll[0] - z.circle.lon) * app.view.cos, ll[1] - z.circle.lat) * KM_PER_DEG <= z.circle.dist;
    if ((inC || z.polygons.some((r) => inRing(ll, r))) && (!best || z.depth > best.depth)) best = z;
  }
  selectZone(best ? best.path : "earth");
}

async function finishShape() {
  const parent = app.zone;
  const name = $("new-name").value.trim();
  const element = $("new-element").value;
  let op = { op: "add_zone", parent, element, designation: name };
  if (app.tool === "polygon") {
    if (app.draft.length < 3) return say("A polygon needs three points or more.", true);
    op.polygon = app.draft;
  } else {
    if (app.draft.length < 2) return say("Click the centre, then a point on the rim.", true);
    const [c, r] = app.draft;
    op.circle = { lon: c[0], lat: c[1], dist: Math.hypot((r[0] - c[0]) * app.view.cos, r[1] - c[1]) * KM_PER_DEG };
  }
  if (await edit(op)) {
    setTool("select");
    selectZone(parent + "/" + name);
  }
}

// ---------------------------------------------------------------------------- side panel --

function selectZone(p) {
  app.zone = p;
  render();
}

async function selectBuilding(i) {
  try {
    const b = await api("/api/building?i=" + i);
    app.building = b;
    app.zone = b.zone;
    render();
    await preview();
  } catch (e) { say(e.message, true); }
}

async function preview() {
  if (!app.building) return;
  const lod = $("lod").value;
  $("previewbox").classList.add("busy");
  try {
    const buf = await api("/api/preview?i=" + app.building.i + "&lod=" + lod);
    app.viewer.show(buf);
    $("previewbox").dataset.shown = app.building.id + " LOD" + lod;
  } catch (e) { say("Preview: " + e.message, true); }
  $("previewbox").classList.remove("busy");
}

function renderTree() {
  const t = $("tree");
  const kids = new Map();
  for (const z of app.st.zones) {
    if (z.parent === null) continue;
    if (!kids.has(z.parent)) kids.set(z.parent, []);
    kids.get(z.parent).push(z);
  }
  // Open: the selected zone's ancestors.
  const open = new Set();
  for (let p = app.zone; p; p = p.includes("/") ? p.slice(0, p.lastIndexOf("/")) : null) open.add(p);
  const item = (z) => {
    const ch = kids.get(z.path) || [];
    const mark = ch.length ? (open.has(z.path) ? "▾" : "▸") : "·";
    let s = `<li><a href="#" data-zone="${esc(z.path)}" class="${z.path === app.zone ? "sel" : ""}">${mark} ${esc(z.name)}</a>` +
      `<small> ${esc(z.element)}${z.appearances.length ? " · " + z.appearances.length + " app." : ""}</small>`;
    if (ch.length && open.has(z.path)) s += "<ul>" + ch.map(item).join("") + "</ul>";
    return s + "</li>";
  };
  t.innerHTML = "<ul>" + item(app.st.zones[0]) + "</ul>";
  const sel = t.querySelector("a.sel");
  if (sel) sel.scrollIntoView({ block: "nearest" });
}

function valuesTable(z) {
  const own = new Map(z.info);
  const res = new Map(z.resolved.map((v) => [v.attribute, v]));
  let rows = "";
  for (const a of ATTRS) {
    const r = res.get(a);
    const inherited = r && r.from !== z.path ? `${esc(r.value)} <small>from ${esc(r.from)}</small>` : "";
    rows += `<tr><td>${a}</td><td><input data-info="${a}" value="${esc(own.get(a) ?? "")}" placeholder="${esc(r ? r.value : "")}"></td><td>${inherited}</td></tr>`;
  }
  return `<table class="values"><tr><th>value</th><th>own</th><th>inherited</th></tr>${rows}</table>`;
}

function openingRects(o, w, h) {
  // The leaves' rectangles (x, y from the bottom-left, in window units) under root.
  const out = [];
  const bySplit = new Map((o ? o.splits : []).map((s) => [s.parent, s]));
  const walk = (node, x, y, ww, hh, depth) => {
    const s = bySplit.get(node);
    if (!s || depth > 12) return out.push({ node, x, y, w: ww, h: hh });
    const sum = s.values.reduce((a, b) => a + b, 0) || 1;
    let at = 0;
    s.children.forEach((c, i) => {
      const f = s.values[i] / sum;
      if (s.axis === "Z") walk(c, x, y + at * hh, ww, f * hh, depth + 1);
      else walk(c, x + at * ww, y, f * ww, hh, depth + 1);
      at += f;
    });
  };
  walk(o ? o.root : "w", 0, 0, w, h, 0);
  return out;
}

function drawOpening(cv, o) {
  const c = cv.getContext("2d");
  const W = cv.width, H = cv.height, m = 10;
  c.fillStyle = "#efe6d6";
  c.fillRect(0, 0, W, H);
  c.fillStyle = "#a9c1cf";
  c.strokeStyle = "#2e6b3f";
  c.lineWidth = 3;
  for (const r of openingRects(o, W - 2 * m, H - 2 * m)) {
    const x = m + r.x, y = H - m - r.y - r.h;
    c.fillRect(x, y, r.w, r.h);
    c.strokeRect(x, y, r.w, r.h);
    c.fillStyle = "#2e3b44";
    c.font = "10px sans-serif";
    c.fillText(r.node, x + 4, y + 12);
    c.fillStyle = "#a9c1cf";
  }
}

function appearanceEditor(z, k, a) {
  const vals = a.values.filter(([n]) => n !== "proba").map(([n, v]) => `${n}=${v}`).join("\n");
  const proba = (a.values.find(([n]) => n === "proba") || [, ""])[1];
  const splits = a.opening ? a.opening.splits.map((s) => `${s.parent} ${s.axis} ${s.children.join("|")} ${s.values.join(",")}`).join("\n") : "";
  return `<div class="appearance" data-index="${k}">
    <div class="row"><b>#${k + 1}</b> proba <input class="proba" size="5" value="${esc(proba)}">
      building= <input class="building" size="14" value="${esc(a.building ?? "")}" placeholder="any kind"></div>
    <textarea class="vals" rows="4" title="one name=value a line">${esc(vals)}</textarea>
    <div class="opening"><canvas class="window" width="120" height="170" title="Click a pane to split it"></canvas>
      <div><label><input type="radio" name="axis${k}" value="X" checked> split across (X)</label><br>
      <label><input type="radio" name="axis${k}" value="Z"> split up (Z)</label><br>
      parts <input class="parts" size="2" value="2"><br>
      <button class="clear-opening">One pane</button>
      <textarea class="splits" rows="3" title="parent axis child|child share,share">${esc(splits)}</textarea></div></div>
    ${a.ruleset ? `<div>ruleset: ${esc(a.ruleset)}</div>` : ""}${a.selex ? `<div>selex: ${esc(a.selex)}</div>` : ""}
    <button class="apply-appearance">Apply</button> <button class="delete-appearance">Delete</button>
  </div>`;
}

// The opening typed in an appearance editor's split list.
function readSplits(div) {
  const lines = div.querySelector(".splits").value.split("\n").map((l) => l.trim()).filter(Boolean);
  if (!lines.length) return null;
  const splits = lines.map((l) => {
    const [parent, axis, children, values] = l.split(/\s+/);
    return { parent, axis, children: (children || "").split("|"), values: (values || "").split(",").map(Number) };
  });
  const kids = new Set(splits.flatMap((s) => s.children));
  const root = splits.map((s) => s.parent).find((p) => !kids.has(p)) || splits[0].parent;
  const parents = new Set(splits.map((s) => s.parent));
  const terms = [...kids].filter((c) => !parents.has(c));
  return { root, splits, terms };
}

function readAppearance(div) {
  const values = [["proba", div.querySelector(".proba").value.trim()]].filter(([, v]) => v !== "");
  for (const line of div.querySelector(".vals").value.split("\n")) {
    const i = line.indexOf("=");
    if (i > 0) values.push([line.slice(0, i).trim(), line.slice(i + 1).trim()]);
  }
  const z = zoneOf(app.zone);
  const old = z.appearances[Number(div.dataset.index)] || {};
  return {
    building: div.querySelector(".building").value.trim() || null,
    values,
    opening: readSplits(div),
    ruleset: old.ruleset || null,
  };
}

function renderZone() {
  const z = zoneOf(app.zone) || app.st.zones[0];
  app.zone = z.path;
  const circle = z.circle || {};
  const apps = z.appearances.map((a, k) => appearanceEditor(z, k, a)).join("");
  const inheritedApps = z.appearances.length ? "" :
    `<p class="note">No appearance of its own: those of <a href="#" data-zone="${esc(z.appearances_from)}">${esc(z.appearances_from)}</a> apply.</p>`;
  $("zone").innerHTML = `<h2>${esc(z.path)}</h2>
    <p><small>&lt;${esc(z.element)}&gt; line ${z.line}</small></p>
    ${z.depth > 0 ? `<fieldset><legend>Circle</legend>
      lat <input id="c-lat" size="9" value="${circle.lat ?? ""}"> lon <input id="c-lon" size="9" value="${circle.lon ?? ""}">
      km <input id="c-dist" size="5" value="${circle.dist ?? ""}">
      <button id="set-circle">Set</button> ${z.circle ? '<button id="rm-circle">Remove</button>' : ""}
      <div>${z.polygons.map((p, i) => `polygon ${i + 1} (${p.length} points) <button data-rmpoly="${i}">Remove</button>`).join("<br>")}</div>
    </fieldset>` : ""}
    <fieldset><legend>New sub-zone (draw it on the map)</legend>
      name <input id="new-name" value="New district"> <select id="new-element">
      ${["district", "zone", "town", "region", "country", "continent"].map((e) => `<option>${e}</option>`).join("")}</select>
    </fieldset>
    <h3>Values <small>(own, else inherited; empty inherits)</small></h3>${valuesTable(z)}
    <h3>Appearances</h3>${inheritedApps}${apps}
    <button id="add-appearance">Add appearance</button>
    ${z.depth > 0 ? '<p><button id="delete-zone" class="danger">Delete this zone</button></p>' : ""}`;
  for (const div of $("zone").querySelectorAll(".appearance")) {
    const a = z.appearances[Number(div.dataset.index)];
    const cv = div.querySelector("canvas.window");
    const redraw = () => drawOpening(cv, readSplits(div));
    drawOpening(cv, a.opening);
    div.querySelector(".splits").addEventListener("input", redraw);
    div.querySelector(".clear-opening").onclick = () => { div.querySelector(".splits").value = ""; redraw(); };
    cv.addEventListener("click", (e) => {
      // Split the pane under the click into equal parts along the chosen axis.
      const o = readSplits(div) || { root: "w", splits: [], terms: ["w"] };
      const m = 10, W = cv.width - 2 * m, H = cv.height - 2 * m;
      const x = e.offsetX - m, y = cv.height - m - e.offsetY;
      const leaf = openingRects(o, W, H).find((r) => x >= r.x && x <= r.x + r.w && y >= r.y && y <= r.y + r.h);
      if (!leaf) return;
      const axis = div.querySelector(`input[name=axis${div.dataset.index}]:checked`).value;
      const n = Math.max(2, Math.min(8, parseInt(div.querySelector(".parts").value, 10) || 2));
      const children = Array.from({ length: n }, (_, i) => `${leaf.node}_${axis.toLowerCase()}${i + 1}`);
      o.splits.push({ parent: leaf.node, axis, children, values: children.map(() => +(1 / n).toFixed(4)) });
      div.querySelector(".splits").value = o.splits.map((s) => `${s.parent} ${s.axis} ${s.children.join("|")} ${s.values.join(",")}`).join("\n");
      redraw();
    });
    div.querySelector(".apply-appearance").onclick = () =>
      edit({ op: "set_appearance", zone: z.path, index: Number(div.dataset.index), appearance: readAppearance(div) });
    div.querySelector(".delete-appearance").onclick = () =>
      edit({ op: "delete_appearance", zone: z.path, index: Number(div.dataset.index) });
  }
  for (const inp of $("zone").querySelectorAll("input[data-info]")) {
    inp.addEventListener("change", () => {
      const v = inp.value.trim();
      edit({ op: "set_info", zone: z.path, values: [[inp.dataset.info, v === "" ? null : v]] });
    });
  }
  const on = (id, f) => { const el = $(id); if (el) el.onclick = f; };
  on("set-circle", () => edit({ op: "set_circle", zone: z.path,
    circle: { lat: Number($("c-lat").value), lon: Number($("c-lon").value), dist: Number($("c-dist").value) } }));
  on("rm-circle", () => edit({ op: "set_circle", zone: z.path, circle: null }));
  on("add-appearance", () => {
    const used = z.appearances.reduce((s, a) => s + (a.proba ?? 0), 0);
    const proba = Math.max(0, Math.round((1 - used) * 1000) / 1000);
    edit({ op: "add_appearance", zone: z.path, appearance: { values: [["proba", String(proba || 1)]] } });
  });
  on("delete-zone", async () => {
    if (await edit({ op: "delete_zone", zone: z.path })) selectZone(z.parent);
  });
  for (const b of $("zone").querySelectorAll("button[data-rmpoly]"))
    b.onclick = () => edit({ op: "set_polygon", zone: z.path, index: Number(b.dataset.rmpoly), points: null });
}

function renderBuilding() {
  const b = app.building;
  if (!b) { $("building").innerHTML = "<p class='note'>Click a footprint on the map.</p>"; return; }
  $("building").innerHTML = `<h3>Building ${esc(b.id)}</h3>
    <p>zone <a href="#" data-zone="${esc(b.zone)}">${esc(b.zone)}</a><br>appearance <b id="chosen">${esc(b.appearance || "none")}</b></p>
    <table class="values">${b.candidates.map((c) => `<tr class="${c.chosen ? "chosen" : ""}"><td>${esc(c.label)}</td><td>${c.weight.toFixed(3)}</td><td>${c.eligible ? "" : "not for this kind"}</td></tr>`).join("")}</table>
    <details><summary>values and where they come from</summary><table class="values">${b.values.map((v) => `<tr><td>${v.attribute}</td><td>${esc(v.value)}</td><td><small>${esc(v.from)}</small></td></tr>`).join("")}</table>
    ${b.overrides.length ? "<p>tags: " + esc(b.overrides.join(", ")) + "</p>" : ""}</details>`;
}

function render() {
  if (!app.st) return;
  $("file").textContent = app.st.file + (app.st.mode === "lenient" ? " (lenient: Save rewrites it in the strict format)" : "");
  $("dirty").textContent = app.st.dirty ? "● unsaved changes" : "saved";
  renderTree();
  renderZone();
  renderBuilding();
  const items = (list) => list.map((r) => `<li>line ${r.line}: ${esc(r.what)}</li>`).join("");
  const rep = items(app.st.repairs), conv = items(app.st.conversion);
  $("repairs").innerHTML = (app.st.mode === "lenient" ? `<p id="save-notice" class="bad">${esc(saveNotice())}</p>` : "") +
    (app.st.strict_error ? `<p class="bad">${esc(app.st.strict_error)}</p>` : "") +
    (rep ? `<details><summary>Lenient reader's repairs (${app.st.repairs.length})</summary><ul>${rep}</ul></details>` : "") +
    (conv ? `<details><summary>Changed to fit the strict format (${app.st.conversion.length})</summary><ul>${conv}</ul></details>` : "");
  drawMap();
}

// What saving a lenient KB does, for the notice and the save button's confirmation.
function saveNotice() {
  const n = app.st.repairs.length + app.st.conversion.length;
  return `Saving rewrites ${app.st.file} in the strict format with ${n} repair${n === 1 ? "" : "s"} ` +
    "(listed below) applied; its comments and layout are not kept.";
}

async function reload() {
  app.st = await api("/api/state");
  render();
}

document.addEventListener("click", (e) => {
  const a = e.target.closest("a[data-zone]");
  if (a) { e.preventDefault(); selectZone(a.dataset.zone); }
});
$("tool-select").onclick = () => setTool("select");
$("tool-polygon").onclick = () => setTool("polygon");
$("tool-circle").onclick = () => setTool("circle");
$("finish").onclick = finishShape;
$("lod").onchange = preview;
$("save").onclick = async () => {
  if (app.st && app.st.mode === "lenient") {
    const list = app.st.repairs.concat(app.st.conversion).map((r) => `line ${r.line}: ${r.what}`);
    const shown = list.slice(0, 30).join("\n") + (list.length > 30 ? `\n... and ${list.length - 30} more` : "");
    if (!window.confirm(saveNotice() + "\n\n" + shown)) return;
  }
  try {
    await api("/api/save", {});
    say("Saved.");
    await reload();
  } catch (e) { say(e.message, true); }
};
window.addEventListener("resize", drawMap);

(async function start() {
  app.viewer = new Viewer($("preview"));
  try {
    const [st, fps] = await Promise.all([api("/api/state"), api("/api/footprints")]);
    app.st = st;
    app.fps = fps;
    drawMap();
    if (fps.length) {
      const lo = [Infinity, Infinity], hi = [-Infinity, -Infinity];
      for (const f of fps) for (const r of f.rings) for (const [x, y] of r) {
        lo[0] = Math.min(lo[0], x); lo[1] = Math.min(lo[1], y); hi[0] = Math.max(hi[0], x); hi[1] = Math.max(hi[1], y);
      }
      fitTo(lo, hi);
    } else fitTo([-170, -60], [170, 75]);
    setTool("select");
    render();
    document.body.dataset.ready = "1";
  } catch (e) { say(e.message, true); }
})();
