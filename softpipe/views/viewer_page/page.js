// softpipe's live viewer (softpipe.tools.viewer serves this page; docs/viewer.md).
// The page asks the server for a PNG of the scene each time the camera, the program, the light or the
// picture changes, and for a pixel's history on a click. One frame request is in flight at a time: while
// it is, only the newest state is remembered and asked for next, so a fast drag never queues stale frames.
"use strict";

const $ = (id) => document.getElementById(id);
const client = Math.random().toString(36).slice(2, 12);     // this page, for the server's coalescing
const DRAG_DEGREES = 0.5;                                   // degrees of orbit per pixel dragged
const CLICK_SLOP = 3;                                       // a press that moves less than this is a click

let info = null;
const state = { az: 0, el: 0, zoom: 1, program: "", light: "scene", stage: "final" };
let seq = 0, inFlight = false, wanted = false, shownUrl = null;
let selected = null;                                        // {x, y}
let times = [];                                             // when the last frames arrived, for the rate

function query(extra) {
  const q = new URLSearchParams({ az: state.az.toFixed(3), el: state.el.toFixed(3),
                                  zoom: state.zoom.toFixed(4), program: state.program, light: state.light,
                                  stage: state.stage });
  for (const [k, v] of Object.entries(extra || {})) q.set(k, String(v));
  return q.toString();
}

function showError(message) {
  const e = $("error");
  e.hidden = !message;
  e.textContent = message || "";
}

async function errorOf(response) {
  try { return (await response.json()).error; } catch (_) { return `${response.status} ${response.statusText}`; }
}

// Ask for the frame of the current state; if one is in flight, remember to ask again when it lands.
function requestFrame() {
  if (inFlight) { wanted = true; return; }
  inFlight = true;
  wanted = false;
  seq += 1;
  const asked = { ...state }, mine = seq;
  fetch(`/api/frame?${query({ seq: mine, client })}`).then(async (r) => {
    if (r.status === 409) return;                           // overtaken by a newer frame: nothing to show
    if (!r.ok) { showError(await errorOf(r)); return; }
    const blob = await r.blob();
    const url = URL.createObjectURL(blob);
    const img = $("frame");
    await new Promise((done) => { img.onload = done; img.onerror = done; img.src = url; });
    if (shownUrl) URL.revokeObjectURL(shownUrl);
    shownUrl = url;
    img.dataset.seq = String(mine);
    img.dataset.state = JSON.stringify(asked);
    img.dataset.bytes = String(blob.size);
    showError("");
    const now = performance.now();
    times = times.filter((t) => now - t < 3000).concat([now]);
    const rate = times.length > 2 ? (times.length - 1) / ((now - times[0]) / 1000) : 0;
    $("status").textContent = `render ${(+r.headers.get("X-Softpipe-Seconds") * 1000).toFixed(0)} ms` +
      (rate ? ` · ${rate.toFixed(1)} frames/s` : "") +
      ` · azimuth ${state.az.toFixed(0)}°, elevation ${state.el.toFixed(0)}°, zoom ${state.zoom.toFixed(2)}×`;
    document.body.dataset.ready = "1";
  }).catch((e) => showError(String(e))).finally(() => {
    inFlight = false;
    if (wanted) requestFrame();
    else if (selected && !document.body.dataset.historyFor) loadHistory();
  });
}

function cell(tag, text) {
  const c = document.createElement(tag);
  c.textContent = text;
  return c;
}

// The history of the selected pixel in every draw: trace.pixel_history(x, y)'s table, as it prints.
async function loadHistory() {
  if (!selected) return;
  const { x, y } = selected;
  const key = `${x},${y},${query()}`;
  document.body.dataset.historyFor = key;
  const pixel = $("pixel");
  pixel.dataset.x = String(x);
  pixel.dataset.y = String(y);
  pixel.dataset.ready = "0";
  $("pixel-heading").textContent = `Pixel (${x}, ${y})`;
  const marker = $("marker"), img = $("frame");
  const sx = img.clientWidth / info.width, sy = img.clientHeight / info.height;
  Object.assign(marker.style, { left: `${x * sx}px`, top: `${y * sy}px`, width: `${Math.max(sx, 3)}px`,
                                height: `${Math.max(sy, 3)}px` });
  marker.hidden = false;
  const r = await fetch(`/api/history?${query({ x, y })}`);
  if (document.body.dataset.historyFor !== key) return;     // another pixel or camera was asked for since
  const box = $("history");
  box.replaceChildren();
  if (!r.ok) { showError(await errorOf(r)); return; }
  const data = await r.json();
  if (!data.draws.length) box.append(cell("p", `No fragment reached pixel (${x}, ${y}).`));
  for (const d of data.draws) {
    const part = document.createElement("div");
    part.className = "draw";
    part.dataset.draw = String(d.draw);
    part.append(cell("h3", `draw ${d.draw + 1}: ${d.name} (${d.program})`), cell("p", d.heading));
    part.lastChild.className = "heading";
    const table = document.createElement("table");
    const head = document.createElement("tr");
    for (const c of d.columns) head.append(cell("th", c));
    table.append(document.createElement("thead"), document.createElement("tbody"));
    table.tHead.append(head);
    const merger = d.columns.indexOf("merger");
    const written = d.rows.map((row, i) => (row[merger] === "written" ? i : -1)).filter((i) => i >= 0);
    d.rows.forEach((row, i) => {
      const tr = document.createElement("tr");
      if (i === written[written.length - 1]) tr.className = "winner";
      for (const v of row) tr.append(cell("td", v));
      table.tBodies[0].append(tr);
    });
    part.append(table);
    box.append(part);
  }
  pixel.dataset.ready = "1";
}

function changed() {
  delete document.body.dataset.historyFor;                 // the history follows the new frame
  requestFrame();
}

function pixelAt(event) {
  const img = $("frame"), r = img.getBoundingClientRect();
  const x = Math.floor((event.clientX - r.left) * info.width / r.width);
  const y = Math.floor((event.clientY - r.top) * info.height / r.height);
  return (x >= 0 && y >= 0 && x < info.width && y < info.height) ? { x, y } : null;
}

function setUp() {
  const view = $("view");
  let press = null;
  view.addEventListener("pointerdown", (e) => {
    press = { x: e.clientX, y: e.clientY, az: state.az, el: state.el, moved: false };
    view.setPointerCapture(e.pointerId);
    view.classList.add("dragging");
  });
  view.addEventListener("pointermove", (e) => {
    if (!press) return;
    const dx = e.clientX - press.x, dy = e.clientY - press.y;
    if (!press.moved && Math.hypot(dx, dy) < CLICK_SLOP) return;
    press.moved = true;
    state.az = press.az - dx * DRAG_DEGREES;                // drag right: the scene turns right
    state.el = Math.max(-info.max_elevation, Math.min(info.max_elevation, press.el + dy * DRAG_DEGREES));
    changed();
  });
  const release = (e) => {
    if (!press) return;
    view.classList.remove("dragging");
    const click = !press.moved;
    press = null;
    if (click) {
      const p = pixelAt(e);
      if (p) { selected = p; loadHistory(); }
    }
  };
  view.addEventListener("pointerup", release);
  view.addEventListener("pointercancel", () => { press = null; view.classList.remove("dragging"); });
  view.addEventListener("wheel", (e) => {
    e.preventDefault();
    const [low, high] = info.zoom;
    state.zoom = Math.max(low, Math.min(high, state.zoom * Math.exp(-e.deltaY * 0.001)));
    changed();
  }, { passive: false });
  for (const id of ["program", "light", "stage"]) {
    $(id).addEventListener("change", () => { state[id] = $(id).value; changed(); });
  }
  $("reset").addEventListener("click", () => { Object.assign(state, { az: 0, el: 0, zoom: 1 }); changed(); });
}

function fill(select, options, value) {
  for (const [v, label, title] of options) {
    const o = document.createElement("option");
    o.value = v;
    o.textContent = label;
    if (title) o.title = title;
    select.append(o);
  }
  select.value = value;
}

async function start() {
  const r = await fetch("/api/info");
  if (!r.ok) { showError(await errorOf(r)); return; }
  info = await r.json();
  const img = $("frame");
  const scale = Math.max(1, Math.floor(640 / Math.max(info.width, info.height * 4 / 3)));   // a small frame, zoomed
  img.width = info.width * scale;
  img.height = info.height * scale;
  fill($("program"), [["", "the scene's own"]].concat(info.programs.map((p) => [p, p])), info.program || "");
  state.program = $("program").value;
  fill($("light"), Object.entries(info.lights).map(([k, v]) => [k, k, v]), "scene");
  fill($("stage"), info.stages.map((s) => [s, s]), "final");
  setUp();
  requestFrame();
}

start();
