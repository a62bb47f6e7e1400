
"use strict";
const META = JSON.parse(document.getElementById("softpipe-data").textContent);
const W = META.width, H = META.height;
const A = {};
const TYPES = {u1: Uint8Array, u2: Uint16Array, u4: Uint32Array, f4: Float32Array, f8: Float64Array};
let state = {x: -1, y: -1, pic: 0, picked: null};
let zoomPixels = null;

async function inflate(b64) {
  const bin = atob(b64), bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
  return await new Response(stream).arrayBuffer();
}

function fmtG(v, p) {            // Python's format(v, f".{p}g")
  if (Number.isNaN(v)) return "nan";
  if (!Number.isFinite(v)) return v > 0 ? "inf" : "-inf";
  if (v === 0) return Object.is(v, -0) ? "-0" : "0";
  const s = v.toExponential(p - 1);
  let [m, e] = s.split("e"); e = parseInt(e, 10);
  if (e >= -4 && e < p) {
    let f = v.toFixed(Math.max(p - 1 - e, 0));
    if (f.includes(".")) f = f.replace(/0+$/, "").replace(/\.$/, "");
    return f;
  }
  if (m.includes(".")) m = m.replace(/0+$/, "").replace(/\.$/, "");
  return m + "e" + (e < 0 ? "-" : "+") + String(Math.abs(e)).padStart(2, "0");
}
const tup = (a, p = 4) => "(" + Array.from(a, c => fmtG(c, p)).join(", ") + ")";
function swatch(rgba) {
  if (!Array.from(rgba).every(Number.isFinite)) return "";
  const c = Array.from(rgba).slice(0, 3).map(v => Math.round(Math.min(Math.max(v, 0), 1) * 255));
  return `<span class="sw" style="background:rgb(${c.join(",")})"></span>`;
}
const esc = s => String(s).replace(/[&<>"]/g, c => ({"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;"}[c]));

function row(name, i, n) { return A[name].subarray(i * n, (i + 1) * n); }

function drawOf(g) {             // global post-clip triangle → draw
  let k = 0;
  for (let d = 0; d < META.draws.length; d++) if (META.draws[d].tri_offset <= g) k = d;
  return k;
}
function triRow(g) {             // global triangle id → row in the t_ arrays
  const ids = A.t_id; let lo = 0, hi = ids.length;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (ids[mid] < g) lo = mid + 1; else hi = mid; }
  return lo < ids.length && ids[lo] === g ? lo : -1;
}
function historyRange(x, y) {
  const p = y * W + x, px = A.h_pixel; let lo = 0, hi = px.length;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (px[mid] < p) lo = mid + 1; else hi = mid; }
  if (lo < px.length && px[lo] === p) return [lo, A.h_start[lo], A.h_start[lo + 1]];
  return null;
}
function triWindow(r) {          // window corners: a triangle's vertices', or a clipped piece's, a line's, a point's own
  const own = A.t_own || A.t_clipped;
  if (own[r]) { let m = 0; for (let i = 0; i < r; i++) m += own[i]; return row("t_window", m, 9); }
  const w = new Float32Array(9);
  for (let c = 0; c < 3; c++) w.set(row("v_win", A.t_vert[r * 3 + c], 3), 3 * c);
  return w;
}
function winner(x, y) { const g = A.win[y * W + x]; return g ? g - 1 : -1; }
function kindOf(k) { return META.draws[k].kind || "triangles"; }      // "triangles" | "lines" | "points"
function primName(k) { return kindOf(k).slice(0, -1); }                  // "triangle" | "line" | "point"

// ---------------------------------------------------------------- pictures and overlays
const pics = META.pictures.map((p, k) => ({...p, img: document.getElementById("pic-" + k)}));
const stage = document.getElementById("stage");
const SHOW = Math.max(2 * W, Math.min(8 * W, 720));        // at most this wide: small framebuffers magnified
const SCALE = Math.max(1, Math.min(8, Math.floor(SHOW / W)));   // the canvas's pixels per framebuffer pixel
stage.width = W * SCALE; stage.height = H * SCALE; stage.style.maxWidth = SHOW + "px";
const thumbs = [];

function outlineTri() {          // the highlighted primitive's image-space outline (a closed path), or null
  const g = state.picked !== null ? state.picked : (state.x >= 0 ? winner(state.x, state.y) : -1);
  if (g < 0) return null;
  const r = triRow(g); if (r < 0) return null;
  const w = triWindow(r), kind = kindOf(drawOf(g));
  if (kind === "lines") return [[w[0], H - w[1]], [w[3], H - w[4]]];          // the segment a → b
  if (kind === "points") {                 // the square of side size around the point
    const s = A.t_size[r] / 2, x = w[0], y = H - w[1];
    return [[x - s, y - s], [x + s, y - s], [x + s, y + s], [x - s, y + s]];
  }
  return [[w[0], H - w[1]], [w[3], H - w[4]], [w[6], H - w[7]]];
}
function tracePath(ctx, t, P) {   // the outline's corners through P (image → canvas), closed unless a segment
  ctx.beginPath(); ctx.moveTo(...P(t[0]));
  for (let i = 1; i < t.length; i++) ctx.lineTo(...P(t[i]));
  if (t.length > 2) ctx.closePath();
  ctx.stroke();
}
function paint(ctx, pic, scale) {
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(pic.img, 0, 0, W * scale, H * scale);
  const t = outlineTri();
  if (t && pic.outline) {
    ctx.strokeStyle = "#ff3df5"; ctx.lineWidth = Math.max(1.5, scale * 1.5 > 3 ? 3 : 1.5);
    tracePath(ctx, t, q => [q[0] * scale, q[1] * scale]);
  }
  if (state.x >= 0 && pic.outline) {           // (a shadow map is the light's view: no pixel of ours)
    ctx.strokeStyle = "#f5c542"; ctx.lineWidth = 1;
    const s = Math.max(scale, 1), pad = scale < 2 ? 2 : 0;
    ctx.strokeRect(state.x * scale - pad - 0.5, state.y * scale - pad - 0.5, s + 2 * pad + 1, s + 2 * pad + 1);
  }
}
function paintAll() {
  paint(stage.getContext("2d"), pics[state.pic], SCALE);
  thumbs.forEach((c, k) => paint(c.getContext("2d"), pics[k], c.width / W));
  paintZoom();
}

function buildTabs() {
  const nav = document.getElementById("tabs");
  const tw = 96, th = Math.max(1, Math.round(tw * H / W));
  pics.forEach((p, k) => {
    const b = document.createElement("button");
    b.type = "button"; b.dataset.pic = k; b.title = p.name;
    const c = document.createElement("canvas"); c.width = tw; c.height = th;
    b.appendChild(c); b.appendChild(document.createTextNode(p.name));
    b.addEventListener("click", () => { state.pic = k; setActive(); paintAll(); stage.focus(); });
    nav.appendChild(b); thumbs.push(c);
  });
  setActive();
}
function setActive() {
  document.querySelectorAll("#tabs button").forEach((b, k) => b.classList.toggle("active", k === state.pic));
}

// ---------------------------------------------------------------- the zoom
function paintZoom() {
  const c = document.getElementById("zoom"), ctx = c.getContext("2d");
  const N = 11, S = c.width / N, half = (N - 1) / 2;
  ctx.fillStyle = "#000"; ctx.fillRect(0, 0, c.width, c.height);
  if (state.x < 0) return;
  const x0 = state.x - half, y0 = state.y - half;
  for (let j = 0; j < N; j++) for (let i = 0; i < N; i++) {
    const x = x0 + i, y = y0 + j;
    if (x < 0 || y < 0 || x >= W || y >= H) continue;
    const o = (y * W + x) * 4;
    ctx.fillStyle = `rgb(${zoomPixels[o]},${zoomPixels[o + 1]},${zoomPixels[o + 2]})`;
    ctx.fillRect(i * S, j * S, S, S);
  }
  ctx.strokeStyle = "rgba(255,255,255,0.15)"; ctx.lineWidth = 1;
  for (let i = 0; i <= N; i++) {
    ctx.beginPath(); ctx.moveTo(i * S + 0.5, 0); ctx.lineTo(i * S + 0.5, c.height); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(0, i * S + 0.5); ctx.lineTo(c.width, i * S + 0.5); ctx.stroke();
  }
  const pos = META.pattern.positions;
  const hist = historyRange(state.x, state.y);
  const mark = {};
  if (hist) for (let r = hist[1]; r < hist[2]; r++) {
    const s = A.f_sample[r], v = A.f_verdict[r];
    if (v === 0) mark[s] = "w"; else if (!mark[s]) mark[s] = v === 1 ? "f" : "d";
  }
  for (let j = 0; j < N; j++) for (let i = 0; i < N; i++) {
    const cx = (i + 0.5) * S, cy = (j + 0.5) * S, sel = i === half && j === half;
    ctx.strokeStyle = sel ? "#fff" : "rgba(255,255,255,0.55)"; ctx.lineWidth = 1;
    ctx.beginPath(); ctx.moveTo(cx - 3, cy); ctx.lineTo(cx + 3, cy); ctx.moveTo(cx, cy - 3); ctx.lineTo(cx, cy + 3); ctx.stroke();
    pos.forEach((p, s) => {           // window y is up: the image row grows down
      const sx = (i + p[0]) * S, sy = (j + 1 - p[1]) * S;
      ctx.beginPath(); ctx.arc(sx, sy, sel ? 3 : 2, 0, 2 * Math.PI);
      if (sel && mark[s] === "w") { ctx.fillStyle = "#f5c542"; ctx.fill(); }
      ctx.strokeStyle = sel && mark[s] === "f" ? "#ff4040" : (sel ? "#f5c542" : "rgba(245,197,66,0.6)");
      ctx.stroke();
    });
  }
  ctx.strokeStyle = "#f5c542"; ctx.lineWidth = 2; ctx.strokeRect(half * S + 1, half * S + 1, S - 2, S - 2);
  const t = outlineTri();
  if (t) {
    ctx.strokeStyle = "#ff3df5"; ctx.lineWidth = 2;
    tracePath(ctx, t, q => [(q[0] - x0) * S, (q[1] - y0) * S]);
  }
}

// ---------------------------------------------------------------- the tables
function historyTable(x, y) {
  const thead = document.querySelector("#history thead"), tbody = document.querySelector("#history tbody");
  const before = document.getElementById("before");
  const hist = historyRange(x, y);
  thead.innerHTML = ""; tbody.innerHTML = "";
  if (!hist) {
    const g = winner(x, y);
    before.textContent = (META.held.step > 1 && g >= 0)
      ? `The page does not hold this pixel's history (${META.held.statement}); its winning triangle is outlined.`
      : "No fragment reached this pixel.";
    return;
  }
  const [j, r0, r1] = hist;
  const draws = new Set(); for (let r = r0; r < r1; r++) draws.add(A.f_draw[r]);
  const vnames = [];                        // the union of the varyings of the draws here, in order
  draws.forEach(k => META.draws[k].varyings.forEach(([n, s]) => { if (!vnames.some(v => v[0] === n)) vnames.push([n, s]); }));
  const anyShadow = [...draws].some(k => META.draws[k].shadow_lights > 0);
  const anyStencil = [...draws].some(k => META.draws[k].stencil);
  const kinds = new Set([...draws].map(kindOf));       // a line's t, a point's gl_PointCoord
  const where = kinds.has("lines") || kinds.has("points")
    ? [[kinds.has("lines") && kinds.has("points") ? "t / point coord" : (kinds.has("lines") ? "t" : "point coord")]] : [];
  const cols = ["draw", "#", "prim", "tri", "sample", "depth", ...where.map(c => c[0]), ...vnames.map(v => v[0]),
                ...(anyShadow ? ["shadow V_j"] : []), "shader output", "merger", ...(anyStencil ? ["stencil"] : []),
                "color after"];
  thead.innerHTML = "<tr>" + cols.map(c => `<th>${esc(c)}</th>`).join("") + "</tr>";
  const first = A.f_draw[r0];
  before.innerHTML = `${r1 - r0} fragment(s); color before draw ${first + 1} (${esc(META.draws[first].name)}): ` +
    swatch(row("h_before", j, 4)) + esc(tup(row("h_before", j, 4)));
  const g = winner(x, y);
  let win = -1;
  for (let r = r0; r < r1; r++) if (A.f_verdict[r] === 0) win = r;
  const kv = A.f_vary.length / Math.max(A.f_draw.length, 1), ks = A.f_shadow.length / Math.max(A.f_draw.length, 1) / 3;
  let html = "";
  for (let r = r0; r < r1; r++) {
    const k = A.f_draw[r], d = META.draws[k];
    const cells = [[`${k + 1}: ${d.name}`, "draw"], [A.f_index[r], "index"], [A.f_prim[r], "primitive_id"],
                   [A.f_tri[r], "triangle"], [A.f_sample[r], "sample"], [A.f_depth[r].toFixed(6), "depth"]];
    if (where.length) {
      const pc = A.f_pc ? row("f_pc", r, 2) : [NaN, NaN], kind = kindOf(k);
      cells.push([kind === "lines" ? fmtG(pc[0], 4) : (kind === "points" ? tup(pc) : ""), "point_coord"]);
    }
    const flat = row("f_vary", r, kv);
    vnames.forEach(([n]) => {
      let o = 0, hit = null;
      for (const [m, s] of d.varyings) { if (m === n) { hit = [o, s]; break; } o += s; }
      cells.push([hit ? (hit[1] === 1 ? fmtG(flat[hit[0]], 4) : tup(flat.subarray(hit[0], hit[0] + hit[1]))) : "", "v:" + n]);
    });
    if (anyShadow) {
      const parts = [];
      for (let l = 0; l < d.shadow_lights; l++) {
        const c = A.f_shadow.subarray((r * ks + l) * 3, (r * ks + l) * 3 + 3);
        parts.push(c[0] === c[1] && c[1] === c[2] ? fmtG(c[0], 3) : tup(c));
      }
      cells.push([parts.join(" "), "shadow"]);
    }
    const color = row("f_color", r, 4), after = row("f_after", r, 4);
    cells.push([swatch(color) + esc(tup(color)), "color", true]);
    cells.push([META.verdicts[A.f_verdict[r]] + (r === win ? " ★" : ""), "verdict"]);
    if (anyStencil) cells.push([d.stencil ? `${A.f_stencil[2 * r]} → ${A.f_stencil[2 * r + 1]}` : "", "stencil"]);
    cells.push([swatch(after) + esc(tup(after)), "color_after", true]);
    const gt = d.tri_offset + A.f_tri[r];
    html += `<tr data-row="${r}" data-tri="${gt}" class="${r === win ? "winner" : ""}${state.picked === gt ? " picked" : ""}">` +
      cells.map(([v, f, raw]) => `<td data-field="${esc(f)}">${raw ? v : esc(v)}</td>`).join("") + "</tr>";
  }
  tbody.innerHTML = html;
}

function triangleTable() {
  const el = document.getElementById("triangle");
  const g = state.picked !== null ? state.picked : (state.x >= 0 ? winner(state.x, state.y) : -1);
  if (g < 0) { el.textContent = "nothing won this pixel"; return; }
  const r = triRow(g), k = drawOf(g), d = META.draws[k], kind = kindOf(k), name = primName(k);
  const f3 = a => tup(a, 5);
  // polygon mode: a triangle's edge (a line) or corner (a point), whose vertices are the triangle's
  const size = kind === "lines" ? `, width ${fmtG(A.t_size[r], 4)}` : (kind === "points" ? `, size ${fmtG(A.t_size[r], 4)}` : "");
  const of = d.polygon_mode ? `, an ${name === "line" ? "edge" : "corner"} of triangle ${A.t_prim[r]} (polygon mode)` :
    `, primitive ${A.t_prim[r]}`;
  let s = `<p>${state.picked !== null ? "picked" : "winning"} ${name}: draw ${k + 1} (${esc(d.name)}), ` +
    `post-clip ${name} ${g - d.tri_offset}${of}${size}${A.t_clipped[r] ? " (a piece clipping cut)" : ""}</p>`;
  s += `<table id="vertices"><thead><tr><th>vertex</th><th>space</th><th>position</th></tr></thead><tbody>`;
  const corners = d.polygon_mode || kind === "triangles" ? 3 : (kind === "lines" ? 2 : 1);
  for (let c = 0; c < corners; c++) {
    const v = A.t_vert[r * 3 + c];
    const obj = Array.from(row("v_obj", v, 4)).filter(Number.isFinite);
    s += `<tr data-vertex="${c}"><td rowspan="3">${A.t_vindex[r * 3 + c]}</td><td>${esc(d.object_space)}</td>` +
         `<td data-space="object">${f3(obj)}</td></tr>` +
         `<tr><td>clip</td><td data-space="clip">${f3(row("v_clip", v, 4))}</td></tr>` +
         `<tr><td>window</td><td data-space="window">${f3(row("v_win", v, 3))}</td></tr>`;
  }
  s += "</tbody></table>";
  if (A.t_clipped[r] || d.polygon_mode) {
    const w = triWindow(r), n = kind === "triangles" ? 3 : (kind === "lines" ? 2 : 1);
    s += `<p class="muted">${A.t_clipped[r] ? "after clipping" : `the ${name}`}, window: ` +
      `${[0, 1, 2].slice(0, n).map(c => f3(w.subarray(3 * c, 3 * c + 3))).join(" ")}</p>`;
  }
  el.innerHTML = s;
}

function select(x, y, keepPick) {
  x = Math.min(Math.max(x, 0), W - 1); y = Math.min(Math.max(y, 0), H - 1);
  state.x = x; state.y = y;
  if (!keepPick) state.picked = null;
  const h = document.getElementById("pixel");
  h.dataset.x = x; h.dataset.y = y;
  const g = winner(x, y);
  h.textContent = `pixel (${x}, ${y})` + (g >= 0 ? ` — draw ${drawOf(g) + 1}: ${META.draws[drawOf(g)].name}` : "");
  historyTable(x, y); triangleTable(); paintAll();
}

function pixelAt(ev) {
  const r = stage.getBoundingClientRect();
  return [Math.floor((ev.clientX - r.left) * W / r.width), Math.floor((ev.clientY - r.top) * H / r.height)];
}

async function main() {
  try {
    for (const [name, a] of Object.entries(META.arrays)) {
      const T = TYPES[a.dtype], n = T.BYTES_PER_ELEMENT, bytes = new Uint8Array(await inflate(a.b64));
      const count = bytes.length / n;
      let arr;
      if (a.shuffle) {
        const out = new Uint8Array(bytes.length);
        for (let b = 0; b < n; b++) for (let i = 0, o = b * count; i < count; i++) out[i * n + b] = bytes[o + i];
        arr = new T(out.buffer);
      } else arr = new T(bytes.buffer);
      if (a.columns) {
        const N = a.shape[0], m = count / Math.max(N, 1), rowsOut = new T(count);
        for (let j = 0; j < m; j++) for (let i = 0; i < N; i++) rowsOut[i * m + j] = arr[j * N + i];
        arr = rowsOut;
      }
      A[name] = arr;
    }
    const after = Float32Array.from(A.f_color);       // the color after: stored where it is not the shader's
    for (let r = 0, m = 0; r < A.f_after_same.length; r++)
      if (!A.f_after_same[r]) { after.set(A.f_after.subarray(4 * m, 4 * m + 4), 4 * r); m++; }
    A.f_after = after;
  } catch (e) {
    document.getElementById("summary").textContent = "This browser could not read the page's data (" + e +
      "): it needs DecompressionStream (Chrome 80+, Firefox 113+, Safari 16.4+).";
    throw e;
  }
  await Promise.all(pics.map(p => p.img.decode()));
  const d = META.draws;
  document.getElementById("summary").textContent = `${W}×${H}, ${META.pattern.positions.length} sample(s) per pixel` +
    ` (${META.pattern.name}); ${d.length} draw(s): ` + d.map((x, k) =>
      `${k + 1}. ${x.name} (${x.program}, ${x.triangles} ${x.kind || "triangles"} after clipping and culling of ` +
      `${x.input_triangles}${x.polygon_mode ? " triangles (polygon mode)" : ""}, ` +
      `${x.fragments} fragments, ${x.path} path)`).join("; ");
  document.getElementById("held").textContent = "This page holds " + META.held.statement + ".";
  const c = document.createElement("canvas"); c.width = W; c.height = H;
  const final = pics.find(p => p.name === "final") || pics[pics.length - 1];
  const ctx = c.getContext("2d"); ctx.drawImage(final.img, 0, 0);
  zoomPixels = ctx.getImageData(0, 0, W, H).data;
  state.pic = Math.max(0, pics.indexOf(final));
  buildTabs();
  stage.addEventListener("click", ev => { const [x, y] = pixelAt(ev); select(x, y); stage.focus(); });
  stage.addEventListener("mousemove", ev => {
    const [x, y] = pixelAt(ev), g = winner(x, y);
    document.getElementById("hover").textContent = `(${x}, ${y})` + (g >= 0 ? ` ${META.draws[drawOf(g)].name}` : "");
    if (document.getElementById("follow").checked && (x !== state.x || y !== state.y)) select(x, y);
  });
  document.addEventListener("keydown", ev => {
    const step = ev.shiftKey ? 10 : 1;
    const move = {ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step]}[ev.key];
    if (!move || ev.target.tagName === "INPUT") return;
    ev.preventDefault();
    select((state.x < 0 ? W >> 1 : state.x) + move[0], (state.y < 0 ? H >> 1 : state.y) + move[1]);
  });
  document.querySelector("#history tbody").addEventListener("click", ev => {
    const tr = ev.target.closest("tr"); if (!tr) return;
    const g = +tr.dataset.tri;
    state.picked = state.picked === g ? null : g;
    select(state.x, state.y, true);
  });
  let first = -1;                 // start on the middle pixel that a triangle won, if any
  for (let y = H >> 1, x = W >> 1, r = 0; r < Math.max(W, H) && first < 0; r++)
    for (const [dx, dy] of [[r, 0], [-r, 0], [0, r], [0, -r]]) {
      const xx = x + dx, yy = y + dy;
      if (xx >= 0 && yy >= 0 && xx < W && yy < H && A.win[yy * W + xx]) { first = yy * W + xx; break; }
    }
  if (first >= 0) select(first % W, Math.floor(first / W)); else paintAll();
  document.body.dataset.ready = "1";
}
main();
