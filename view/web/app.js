// lop-view page: plain WebGL 1 and 2D canvases, no library. Receives the topology and frames
// from lop-view's WebSocket (/ws, wire format in view/src/wire.rs) and sends control requests.
"use strict";

const $ = (id) => document.getElementById(id);
const canvas = $("gl");
const gl = canvas.getContext("webgl", { antialias: true, preserveDrawingBuffer: true });

// ---- state -------------------------------------------------------------------------------
let topo = null;          // topology JSON
let tris = null;          // Uint32Array or Uint16Array of triangle indices
let nodeBody = null;      // body index per node
let frame = null;         // newest decoded frame
let camera = { yaw: 0.0, pitch: 0.35, dist: 0.5, center: [0, 0, 0], fitted: false };
let ws = null;
let frames = 0, fpsShown = 0, fpsT0 = performance.now();

// ---- GL setup ----------------------------------------------------------------------------
const VS = `
attribute vec3 pos; attribute vec3 nrm; attribute vec3 col;
uniform mat4 view; uniform mat4 proj; uniform vec3 offset; uniform float scale;
varying vec3 vcol;
void main() {
  vec4 p = view * vec4(pos * scale + offset, 1.0);
  vec3 n = normalize((view * vec4(nrm, 0.0)).xyz);
  float l = abs(n.z);
  vcol = col * (0.30 + 0.75 * l);
  gl_Position = proj * p;
}`;
const FS = `
precision mediump float; varying vec3 vcol; uniform float alpha;
void main() { gl_FragColor = vec4(vcol, alpha); }`;

let prog, loc, buf = {}, sphere = null, indexType = null;
function shader(type, src) {
  const s = gl.createShader(type);
  gl.shaderSource(s, src);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}
function initGL() {
  if (!gl) { $("hud").textContent = "WebGL is not available in this browser"; return false; }
  prog = gl.createProgram();
  gl.attachShader(prog, shader(gl.VERTEX_SHADER, VS));
  gl.attachShader(prog, shader(gl.FRAGMENT_SHADER, FS));
  gl.linkProgram(prog);
  loc = {
    pos: gl.getAttribLocation(prog, "pos"), nrm: gl.getAttribLocation(prog, "nrm"),
    col: gl.getAttribLocation(prog, "col"), view: gl.getUniformLocation(prog, "view"),
    proj: gl.getUniformLocation(prog, "proj"), offset: gl.getUniformLocation(prog, "offset"),
    scale: gl.getUniformLocation(prog, "scale"), alpha: gl.getUniformLocation(prog, "alpha"),
  };
  indexType = gl.getExtension("OES_element_index_uint") ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT;
  for (const k of ["pos", "nrm", "col", "idx", "spos", "snrm", "scol", "sidx"]) buf[k] = gl.createBuffer();
  sphere = makeSphere(10, 16);
  gl.bindBuffer(gl.ARRAY_BUFFER, buf.spos); gl.bufferData(gl.ARRAY_BUFFER, sphere.pos, gl.STATIC_DRAW);
  gl.bindBuffer(gl.ARRAY_BUFFER, buf.snrm); gl.bufferData(gl.ARRAY_BUFFER, sphere.pos, gl.STATIC_DRAW);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buf.sidx); gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, sphere.idx, gl.STATIC_DRAW);
  gl.enable(gl.DEPTH_TEST);
  gl.clearColor(0.08, 0.09, 0.11, 1);
  return true;
}
function makeSphere(rings, segs) {
  const pos = [], idx = [];
  for (let i = 0; i <= rings; i++) {
    const th = Math.PI * i / rings;
    for (let j = 0; j <= segs; j++) {
      const ph = 2 * Math.PI * j / segs;
      pos.push(Math.sin(th) * Math.cos(ph), Math.cos(th), Math.sin(th) * Math.sin(ph));
    }
  }
  for (let i = 0; i < rings; i++) for (let j = 0; j < segs; j++) {
    const a = i * (segs + 1) + j, b = a + segs + 1;
    idx.push(a, b, a + 1, b, b + 1, a + 1);
  }
  return { pos: new Float32Array(pos), idx: new Uint16Array(idx), count: idx.length };
}

// ---- math --------------------------------------------------------------------------------
function perspective(fovy, aspect, near, far) {
  const f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
  return [f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0];
}
function lookAt(eye, c, up) {
  let z = [eye[0] - c[0], eye[1] - c[1], eye[2] - c[2]];
  const zl = Math.hypot(...z); z = z.map((v) => v / zl);
  let x = [up[1] * z[2] - up[2] * z[1], up[2] * z[0] - up[0] * z[2], up[0] * z[1] - up[1] * z[0]];
  const xl = Math.hypot(...x); x = x.map((v) => v / xl);
  const y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]];
  const d = (a) => -(a[0] * eye[0] + a[1] * eye[1] + a[2] * eye[2]);
  return [x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0, d(x), d(y), d(z), 1];
}

// ---- colours -----------------------------------------------------------------------------
// Temperature ramp: body colour at 37 °C → amber → red-orange → pale yellow at 100 °C.
function heat(base, t) {
  const u = Math.min(Math.max((t - 37) / 63, 0), 1);
  if (u <= 0) return base;
  const stops = [[0, base], [0.4, [1.0, 0.69, 0.0]], [0.7, [1.0, 0.25, 0.0]], [1.0, [1.0, 0.95, 0.75]]];
  for (let i = 1; i < stops.length; i++) {
    if (u <= stops[i][0]) {
      const [u0, c0] = stops[i - 1], [u1, c1] = stops[i], w = (u - u0) / (u1 - u0);
      return [0, 1, 2].map((k) => c0[k] + (c1[k] - c0[k]) * w);
    }
  }
  return stops[3][1];
}
const BURNED = [0.13, 0.08, 0.06];
const MODELS = ["GC", "MSD", "FEM"], STATES = ["rest", "active", "reset"];

// ---- messages ----------------------------------------------------------------------------
function onTopology(t) {
  topo = t; tris = null; frame = null; camera.fitted = false;
  // Drawn vertices: the nodes, then the render surfaces' vertices.
  nodeBody = new Uint8Array(t.vertex_count);
  t.bodies.forEach((b, i) => {
    nodeBody.fill(i, b.node_offset, b.node_offset + b.node_count);
    const r = t.node_count + b.render_vertex_offset;
    nodeBody.fill(i, r, r + b.render_vertex_count);
  });
  const sel = $("ctl-body"), prev = sel.value;
  sel.innerHTML = "";
  for (const b of t.bodies) { const o = document.createElement("option"); o.textContent = b.name; sel.appendChild(o); }
  if (prev) sel.value = prev;
  if (!sel.value && t.bodies.length) sel.value = t.bodies[0].name;
}
function onTriangles(dv) {
  const n = dv.getUint32(4, true);
  const arr = indexType === gl.UNSIGNED_INT ? new Uint32Array(n * 3) : new Uint16Array(n * 3);
  for (let i = 0; i < n * 3; i++) arr[i] = dv.getUint32(8 + 4 * i, true);
  tris = arr;
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buf.idx);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, tris, gl.STATIC_DRAW);
}
function onFrame(ab) {
  const dv = new DataView(ab);
  const n = dv.getUint32(4, true), nb = dv.getUint32(8, true), nt = dv.getUint32(12, true);
  const f32 = (o) => dv.getFloat32(o, true);
  const v3 = (o) => [f32(o), f32(o + 4), f32(o + 8)];
  const f = { n, simTime: f32(16), ageMs: f32(20), tools: [], bodies: [] };
  let o = 24;
  // The newest state of each tool, in tool order.
  for (let i = 0; i < nt; i++, o += 48) {
    f.tools.push({ tool: dv.getUint32(o, true), flags: dv.getUint32(o + 4, true),
      device: v3(o + 8), proxy: v3(o + 20), radius: f32(o + 32), force: v3(o + 36) });
  }
  for (let i = 0; i < nb; i++, o += 40) {
    f.bodies.push({ model: dv.getUint32(o, true), state: dv.getUint32(o + 4, true),
      switches: dv.getUint32(o + 8, true), resets: dv.getUint32(o + 12, true),
      ke: f32(o + 16), maxSpeed: f32(o + 20), stepMs: f32(o + 24), periodMs: f32(o + 28),
      realTime: f32(o + 32) });
  }
  f.pos = new Float32Array(ab.slice(o, o + 12 * n)); o += 12 * n;
  f.temp = new Float32Array(ab.slice(o, o + 4 * n)); o += 4 * n;
  f.flags = new Uint8Array(ab, o, n);
  frame = f;
  frames++;
  if (!camera.fitted) fitCamera(f.pos);
  updateBodies();
}
function fitCamera(p) {
  let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < p.length; i += 3) for (let k = 0; k < 3; k++) {
    lo[k] = Math.min(lo[k], p[i + k]); hi[k] = Math.max(hi[k], p[i + k]);
  }
  // Rounded to the centimetre, so the view does not depend on the frame it was fitted to.
  camera.center = [0, 1, 2].map((k) => Math.round((lo[k] + hi[k]) * 50) / 100);
  const r = Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2;
  camera.dist = Math.max(Math.round(r * 2.2 * 100) / 100, 0.05);
  camera.fitted = true;
}
function updateBodies() {
  if (!topo || !frame) return;
  const rows = ['<tr><th>body</th><th>model</th><th>state</th><th>switches</th><th>max speed</th>' +
    '<th title="the period of its next step; longer than configured where a step costs more">period</th>' +
    '<th title="simulated over wall time in the last second">real time</th></tr>'];
  topo.bodies.forEach((b, i) => {
    const s = frame.bodies[i] || {};
    const c = b.color.map((v) => Math.round(v * 255)).join(",");
    rows.push(`<tr><td><span class="swatch" style="background:rgb(${c})"></span>${b.name}` +
      `${b.importance === "important" ? "*" : ""}</td><td>${MODELS[s.model] || "?"}</td>` +
      `<td>${STATES[s.state] || "?"}</td><td>${s.switches ?? ""}</td>` +
      `<td>${s.maxSpeed !== undefined ? (s.maxSpeed * 1000).toFixed(1) + " mm/s" : ""}</td>` +
      `<td>${s.periodMs ? +s.periodMs.toFixed(2) + " ms" : ""}</td>` +
      `<td>${s.realTime ? "×" + s.realTime.toFixed(2) : ""}</td></tr>`);
  });
  $("bodies").innerHTML = rows.join("");
}
function onTelemetry(t) {
  $("tel").textContent = `${t.rate_hz.toFixed(0)} Hz · overruns ${t.overruns} · stale ticks ` +
    `${t.stale_ticks} · force ${t.force.toFixed(2)} N`;
  plot("plot-jitter", t.history.jitter, "#7fb8ff");
  plot("plot-compute", t.history.compute, "#b9a2ff");
  plot("plot-age", t.history.age, "#ffb36b");
}
function plot(id, data, color) {
  const c = $(id), w = (c.width = c.clientWidth), h = (c.height = c.clientHeight), g = c.getContext("2d");
  g.clearRect(0, 0, w, h);
  if (!data.length) return;
  const max = Math.max(...data, 1e-9) * 1.15;
  g.strokeStyle = color; g.lineWidth = 1.5; g.beginPath();
  data.forEach((v, i) => {
    const x = (i / Math.max(data.length - 1, 1)) * (w - 70), y = h - 3 - (v / max) * (h - 6);
    i ? g.lineTo(x, y) : g.moveTo(x, y);
  });
  g.stroke();
  g.fillStyle = "#aab4bf"; g.font = "10px sans-serif";
  g.fillText(`max ${(max / 1.15).toFixed(1)}`, w - 66, 10);
  g.fillText(`now ${data[data.length - 1].toFixed(1)}`, w - 66, h - 4);
}
// The control token comes from the URL lop-view printed (`#token=…`: a fragment, so it never
// leaves the browser in an HTTP request). Without it, or once lop-view refused it, the panel
// is read-only.
const token = new URLSearchParams(location.hash.slice(1)).get("token") || "";
function readOnly() {
  $("ctl-ro").hidden = false;
  $("ctl-panel").disabled = true;
}
if (!token) readOnly();
function onControl(r) {
  if (r.read_only) readOnly();
  const m = $("ctl-msg");
  m.className = r.ok ? "" : "err";
  let s = r.ok ? "ok" : `${r.status_name}`;
  if (r.message) s += `: ${r.message}`;
  if (r.body) s += `\n${r.body}: pin ${r.pin}, model ${r.model}${r.paused ? ", paused" : ""}`;
  else if (r.ok) s += r.paused ? " (paused)" : " (running)";
  m.textContent = s;
  $("ctl-params").innerHTML = (r.params || []).map((p) =>
    `<tr><td>${p.key}</td><td>${p.value}</td><td>${p.live ? "live" : ""}</td></tr>`).join("");
}
function send(req) {
  if (!token) { readOnly(); return; }
  if (ws && ws.readyState === 1) ws.send(JSON.stringify({ ...req, token }));
  else onControl({ ok: false, status_name: "error", message: "not connected to lop-view" });
}

// ---- connection (reconnects on close) ----------------------------------------------------
function connect() {
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = "arraybuffer";
  ws.onmessage = (e) => {
    if (typeof e.data === "string") {
      const m = JSON.parse(e.data);
      if (m.type === "topology") onTopology(m);
      else if (m.type === "telemetry") onTelemetry(m);
      else if (m.type === "control") onControl(m);
      else if (m.type === "status") setStatus(m.connected ? `attached to ${m.prefix}` : `waiting for lopd (${m.prefix})…`, m.connected);
    } else {
      const dv = new DataView(e.data);
      const kind = dv.getUint32(0, true);
      if (kind === 1) onTriangles(dv);
      else if (kind === 2 && topo && tris) onFrame(e.data);
    }
  };
  ws.onclose = () => { setStatus("viewer disconnected; reconnecting…", false); setTimeout(connect, 1000); };
}
function setStatus(text, ok) { const s = $("status"); s.textContent = text; s.className = ok ? "ok" : "bad"; }

// ---- drawing -----------------------------------------------------------------------------
let posData = null, nrmData = null, colData = null;
function draw() {
  requestAnimationFrame(draw);
  const w = canvas.clientWidth, h = canvas.clientHeight;
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  gl.viewport(0, 0, w, h);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  if (!topo || !tris || !frame || frame.n !== topo.vertex_count) return;
  const n = frame.n;
  if (!posData || posData.length !== 3 * n) {
    nrmData = new Float32Array(3 * n); colData = new Float32Array(3 * n);
  }
  posData = frame.pos;
  // Smooth normals from the triangles, colours from body, temperature and burn flags.
  nrmData.fill(0);
  const p = posData;
  for (let t = 0; t < tris.length; t += 3) {
    const a = 3 * tris[t], b = 3 * tris[t + 1], c = 3 * tris[t + 2];
    const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
    const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    for (const k of [a, b, c]) { nrmData[k] += nx; nrmData[k + 1] += ny; nrmData[k + 2] += nz; }
  }
  for (let i = 0; i < n; i++) {
    const col = frame.flags[i] & 1 ? BURNED : heat(topo.bodies[nodeBody[i]].color, frame.temp[i]);
    colData[3 * i] = col[0]; colData[3 * i + 1] = col[1]; colData[3 * i + 2] = col[2];
  }
  const eye = [
    camera.center[0] + camera.dist * Math.cos(camera.pitch) * Math.sin(camera.yaw),
    camera.center[1] + camera.dist * Math.sin(camera.pitch),
    camera.center[2] + camera.dist * Math.cos(camera.pitch) * Math.cos(camera.yaw),
  ];
  gl.useProgram(prog);
  gl.uniformMatrix4fv(loc.view, false, lookAt(eye, camera.center, [0, 1, 0]));
  gl.uniformMatrix4fv(loc.proj, false, perspective(0.8, w / h, camera.dist * 0.05, camera.dist * 10));
  const attr = (l, b, data, usage) => {
    gl.bindBuffer(gl.ARRAY_BUFFER, b);
    if (data) gl.bufferData(gl.ARRAY_BUFFER, data, usage);
    gl.enableVertexAttribArray(l); gl.vertexAttribPointer(l, 3, gl.FLOAT, false, 0, 0);
  };
  // Organs.
  attr(loc.pos, buf.pos, posData, gl.DYNAMIC_DRAW);
  attr(loc.nrm, buf.nrm, nrmData, gl.DYNAMIC_DRAW);
  attr(loc.col, buf.col, colData, gl.DYNAMIC_DRAW);
  gl.uniform3f(loc.offset, 0, 0, 0); gl.uniform1f(loc.scale, 1); gl.uniform1f(loc.alpha, 1);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buf.idx);
  gl.drawElements(gl.TRIANGLES, tris.length, indexType, 0);
  // Each tool: its god-object (cyan, solid) and its device's tool tip (grey, translucent).
  if (frame.tools.length) {
    attr(loc.pos, buf.spos, null); attr(loc.nrm, buf.snrm, null);
    gl.disableVertexAttribArray(loc.col);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buf.sidx);
    for (const t of frame.tools) drawTool(t);
  }
  const now = performance.now();
  if (now - fpsT0 > 1000) { fpsShown = frames * 1000 / (now - fpsT0); frames = 0; fpsT0 = now; }
  $("hud").textContent = `t ${frame.simTime.toFixed(2)} s · ${fpsShown.toFixed(0)} frames/s · ` +
    `frame age ${frame.ageMs.toFixed(1)} ms · ` + toolsText(frame.tools);
}
// One tool sphere: the god-object, then the device's tip over it.
function drawTool(t) {
  gl.uniform1f(loc.scale, Math.max(t.radius, 1e-4));
  gl.vertexAttrib3f(loc.col, 0.2, 0.85, 0.9);
  gl.uniform1f(loc.alpha, 1);
  gl.uniform3f(loc.offset, ...t.proxy);
  gl.drawElements(gl.TRIANGLES, sphere.count, gl.UNSIGNED_SHORT, 0);
  gl.enable(gl.BLEND); gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA); gl.depthMask(false);
  gl.vertexAttrib3f(loc.col, 0.8, 0.8, 0.8);
  gl.uniform1f(loc.alpha, 0.45);
  gl.uniform3f(loc.offset, ...t.device);
  gl.drawElements(gl.TRIANGLES, sphere.count, gl.UNSIGNED_SHORT, 0);
  gl.disable(gl.BLEND); gl.depthMask(true);
}
// The force and state of each tool (with one tool, or none, without its index).
function toolsText(tools) {
  const one = (t) => `force ${Math.hypot(...t.force).toFixed(2)} N` +
    `${t.flags & 1 ? " · contact" : ""}${t.flags & 16 ? " · grab" : ""}${t.flags & 32 ? " · heat" : ""}`;
  if (tools.length <= 1) return one(tools[0] || { force: [0, 0, 0], flags: 0 });
  return tools.map((t) => `tool ${t.tool}: ${one(t)}`).join(" · ");
}

// ---- input -------------------------------------------------------------------------------
let drag = null;
canvas.addEventListener("mousedown", (e) => { drag = [e.clientX, e.clientY]; });
window.addEventListener("mouseup", () => { drag = null; });
window.addEventListener("mousemove", (e) => {
  if (!drag) return;
  camera.yaw -= (e.clientX - drag[0]) * 0.01;
  camera.pitch = Math.max(-1.5, Math.min(1.5, camera.pitch + (e.clientY - drag[1]) * 0.01));
  drag = [e.clientX, e.clientY];
});
canvas.addEventListener("wheel", (e) => { e.preventDefault(); camera.dist *= Math.exp(e.deltaY * 0.001); }, { passive: false });
const body = () => $("ctl-body").value;
$("btn-get").onclick = () => send({ op: "get", body: body() });
$("btn-release").onclick = () => send({ op: "release", body: body() });
$("btn-set").onclick = () => send({ op: "set", body: body(), key: $("ctl-key").value, value: $("ctl-value").value });
$("btn-reset").onclick = () => send({ op: "reset" });
$("btn-pause").onclick = () => send({ op: "pause" });
$("btn-resume").onclick = () => send({ op: "resume" });
for (const b of document.querySelectorAll("[data-pin]")) b.onclick = () => send({ op: "pin", body: body(), model: b.dataset.pin });

if (initGL()) { connect(); requestAnimationFrame(draw); }
