// The swarm's top view: a metric grid in ENU metres (x east to the right, y north up), the site, every
// vehicle with heading, trail, slot and leader, and the events, fed by the server's WebSocket (messages.py).
// window.swarmState holds what the page knows, for people and for tests.
"use strict";

const TRAIL_S = 30;  // s of track behind each vehicle
const COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2",
  "#7f7f7f", "#bcbd22"];

const state = window.swarmState = {
  connected: false, scene: null, frame: null, status: null, frames: 0, errors: [], trails: [],
  events: [], actions: [], latency: [],  // live: the flight's events, action replies, s from copy to receipt
  view: { cx: 0, cy: 0, scale: 4 },  // centre m ENU, px per m
};

const canvas = document.getElementById("view");
const ctx = canvas.getContext("2d");
const el = (id) => document.getElementById(id);
const colour = (i) => COLOURS[i % COLOURS.length];
let sliderHeld = false;
let socket = null;

function send(message) {
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
}

function connect() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  socket = new WebSocket(`${scheme}://${location.host}/ws`);
  socket.onopen = () => { state.connected = true; el("connection").textContent = "connected"; };
  socket.onclose = () => {
    state.connected = false;
    el("connection").textContent = "disconnected";
  };
  socket.onmessage = (event) => receive(JSON.parse(event.data));
}

function receive(message) {
  if (message.type === "scene") onScene(message);
  else if (message.type === "frame") onFrame(message);
  else if (message.type === "status") onStatus(message);
  else if (message.type === "error") state.errors.push(message.text);
  else if (message.type === "action") onAction(message);
  draw();
}

function onScene(scene) {
  state.scene = scene;
  state.trails = scene.vehicles.map(() => []);
  el("title").textContent = `swarm-gcs: ${scene.mission}`;
  const [x0, y0, x1, y1] = scene.bounds;
  fit(x0, y0, x1, y1);
  el("controls").hidden = !scene.replay;
  if (scene.replay) {
    el("slider").min = scene.t0;
    el("slider").max = scene.t1;
  }
  state.events = scene.events.slice();
  el("events").replaceChildren(...scene.events.map(eventItem));
  el("actions").hidden = scene.replay;
  document.body.classList.toggle("replay", scene.replay);
  if (!scene.replay && !scene.actions) el("reply").textContent = "read-only: actions need --web-token (console)";
  el("progress").hidden = scene.replay;
  el("target").replaceChildren(...["all", ...scene.vehicles].map((name) => {
    const option = document.createElement("option");
    option.textContent = name;
    return option;
  }));
  const rows = el("vehicles").tBodies[0];
  rows.replaceChildren(...scene.vehicles.map((name, i) => {
    const tr = document.createElement("tr");
    tr.innerHTML = `<td><span class="swatch" style="background:${colour(i)}"></span></td><td></td><td></td><td></td><td class="link"></td>`;
    tr.cells[1].textContent = name;
    return tr;
  }));
}

function eventItem(e) {
  const li = document.createElement("li");
  li.dataset.t = e.t === null ? "" : e.t;
  li.innerHTML = `<span class="kind">${e.kind}</span>${e.t === null ? "" : `t=${e.t.toFixed(2)} s `}`;
  li.append(document.createTextNode(e.text));
  return li;
}

function onLive(frame) {
  state.latency.push(Date.now() / 1000 - frame.stamp);
  if (state.latency.length > 1000) state.latency.shift();
  frame.events.forEach((e, k) => {  // a page that joined late has some of them from its scene already
    if (frame.first_event + k < state.events.length) return;
    state.events.push(e);
    el("events").append(eventItem(e));
  });
  const p = frame.progress, fmt = (v, unit) => (v === null ? "–" : `${v.toFixed(1)} ${unit}`);
  el("progress").textContent = `leader to goal ${fmt(p.leader_to_goal_m, "m")}, formation rms `
    + `${fmt(p.formation_rms_m, "m")}, in formation ${fmt(p.formation_s, "s")}`;
  const rows = el("vehicles").tBodies[0].rows;
  frame.vehicles.forEach((v, i) => {
    if (!rows[i]) return;
    const rate = (x) => (x === null ? "–" : x.toFixed(0));
    const over = frame.budget !== null && v.up !== null && v.up + v.down > frame.budget;
    rows[i].cells[4].textContent = `${rate(v.up)}/${rate(v.down)}`;
    rows[i].cells[4].className = over || !state.connected ? "lost" : "";
    if (v.taken) { rows[i].cells[2].textContent += " (taken)"; rows[i].cells[2].className = "lost"; }
  });
}

function onAction(reply) {
  state.actions.push(reply);
  el("reply").textContent = `${reply.line}: ${reply.ok ? "done" : "refused"}${reply.text ? `: ${reply.text}` : ""}`;
  el("reply").className = reply.ok ? "obeyed" : "refused";
}

function onFrame(frame) {
  const previous = state.frame;
  if (previous && (frame.t < previous.t || frame.t - previous.t > TRAIL_S)) {
    state.trails = state.trails.map(() => []);  // a seek: the old track is not this one's
  }
  frame.vehicles.forEach((v, i) => {
    if (v.x === null || v.y === null || !state.trails[i]) return;
    const trail = state.trails[i];
    trail.push([frame.t, v.x, v.y]);
    while (trail.length && trail[0][0] < frame.t - TRAIL_S) trail.shift();
  });
  state.frame = frame;
  state.frames += 1;
  el("clock").textContent = `t = ${frame.t.toFixed(2)} s`;
  el("phase").textContent = `phase: ${frame.phase ?? "–"}`;
  el("formation").textContent = `formation: ${frame.formation ?? "as planned"}`;
  const rows = el("vehicles").tBodies[0].rows;
  frame.vehicles.forEach((v, i) => {
    if (!rows[i]) return;
    rows[i].cells[1].textContent = (state.scene?.vehicles[i] ?? i) + (i === frame.leader ? " (leader)" : "");
    rows[i].cells[2].textContent = v.lost ? "lost" : v.crashed ? "crashed" : (v.mode ?? "–");
    rows[i].cells[2].className = v.lost || v.crashed ? "lost" : "";
    rows[i].cells[3].textContent = v.z === null ? "–" : v.z.toFixed(1);
  });
  let latest = null;
  for (const li of el("events").children) {
    const future = li.dataset.t !== "" && Number(li.dataset.t) > frame.t;
    li.className = future ? "future" : "";
    if (!future && li.dataset.t !== "") latest = li;
  }
  if (latest) latest.className = "latest";
  if (!sliderHeld && state.scene?.replay) el("slider").value = frame.t;
  if (frame.stamp !== undefined) onLive(frame);
}

function onStatus(status) {
  state.status = status;
  el("play").textContent = status.playing ? "pause" : "play";
  el("speed").value = String(status.speed);
}

// ---- the view: metres <-> pixels ----

function fit(x0, y0, x1, y1) {
  resize();
  const w = canvas.width, h = canvas.height;
  state.view.cx = (x0 + x1) / 2;
  state.view.cy = (y0 + y1) / 2;
  state.view.scale = Math.min(w / Math.max(x1 - x0, 1), h / Math.max(y1 - y0, 1));
}

function px(x, y) {
  const v = state.view;
  return [canvas.width / 2 + (x - v.cx) * v.scale, canvas.height / 2 - (y - v.cy) * v.scale];
}

function resize() {
  const ratio = window.devicePixelRatio || 1;
  const w = Math.round(canvas.clientWidth * ratio), h = Math.round(canvas.clientHeight * ratio);
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
}

function niceStep(metres) {
  const p = Math.pow(10, Math.floor(Math.log10(metres)));
  return [1, 2, 5, 10].map((k) => k * p).find((s) => s >= metres);
}

function drawGrid() {
  const v = state.view, w = canvas.width, h = canvas.height;
  const step = niceStep(80 / v.scale);
  const xMin = v.cx - w / 2 / v.scale, xMax = v.cx + w / 2 / v.scale;
  const yMin = v.cy - h / 2 / v.scale, yMax = v.cy + h / 2 / v.scale;
  ctx.lineWidth = 1;
  ctx.font = "11px sans-serif";
  ctx.fillStyle = "#888";
  for (let x = Math.ceil(xMin / step) * step; x <= xMax; x += step) {
    const [sx] = px(x, 0);
    ctx.strokeStyle = Math.abs(x) < step / 2 ? "#bbb" : "#eee";
    ctx.beginPath(); ctx.moveTo(sx, 0); ctx.lineTo(sx, h); ctx.stroke();
    ctx.fillText(`${+x.toFixed(6)} m`, sx + 2, h - 4);
  }
  for (let y = Math.ceil(yMin / step) * step; y <= yMax; y += step) {
    const [, sy] = px(0, y);
    ctx.strokeStyle = Math.abs(y) < step / 2 ? "#bbb" : "#eee";
    ctx.beginPath(); ctx.moveTo(0, sy); ctx.lineTo(w, sy); ctx.stroke();
    ctx.fillText(`${+y.toFixed(6)} m`, 2, sy - 2);
  }
  ctx.fillText("x east →, y north ↑", w - 120, 14);
}

function path(points, close) {
  ctx.beginPath();
  points.forEach(([x, y], k) => { const [sx, sy] = px(x, y); if (k) ctx.lineTo(sx, sy); else ctx.moveTo(sx, sy); });
  if (close) ctx.closePath();
}

function circle(x, y, r) {
  const [sx, sy] = px(x, y);
  ctx.beginPath();
  ctx.arc(sx, sy, Math.max(r * state.view.scale, 1), 0, 2 * Math.PI);
}

function drawSite(scene, frame) {
  const fence = scene.fence;
  ctx.setLineDash([6, 4]);
  ctx.strokeStyle = "#c0392b";
  circle(0, 0, fence.radius); ctx.stroke();
  if (fence.polygon) { path(fence.polygon, true); ctx.lineWidth = 2; ctx.stroke(); ctx.lineWidth = 1; }
  ctx.setLineDash([]);
  ctx.fillStyle = "rgba(192, 57, 43, 0.15)";
  for (const zone of fence.exclusions) {
    if (zone.polygon) path(zone.polygon, true); else circle(zone.x, zone.y, zone.r);
    ctx.fill(); ctx.stroke();
  }
  ctx.fillStyle = "rgba(120, 85, 50, 0.45)";
  ctx.strokeStyle = "#6b4c2a";
  for (const p of scene.prisms) { path(p.footprint, true); ctx.fill(); ctx.stroke(); }
  for (const c of scene.cylinders) { circle(c.x, c.y, c.r); ctx.fill(); ctx.stroke(); }
  ctx.fillStyle = "rgba(90, 90, 90, 0.45)";
  ctx.strokeStyle = "#444";
  const centres = frame && frame.obstacles ? frame.obstacles : scene.obstacles.map((o) => [o.x, o.y]);
  scene.obstacles.forEach((o, k) => { circle(centres[k][0], centres[k][1], o.r); ctx.fill(); ctx.stroke(); });
  ctx.strokeStyle = "#2c7"; ctx.setLineDash([3, 5]);
  path(scene.waypoints, false); ctx.stroke(); ctx.setLineDash([]);
  ctx.fillStyle = "#2c7";
  for (const [x, y] of scene.waypoints) { circle(x, y, 3 / state.view.scale); ctx.fill(); }
  const [gx, gy] = px(scene.goal[0], scene.goal[1]);
  ctx.strokeStyle = "#1a7f37"; ctx.lineWidth = 2;
  ctx.beginPath(); ctx.arc(gx, gy, 9, 0, 2 * Math.PI); ctx.moveTo(gx - 6, gy); ctx.lineTo(gx + 6, gy);
  ctx.moveTo(gx, gy - 6); ctx.lineTo(gx, gy + 6); ctx.stroke(); ctx.lineWidth = 1;
  ctx.fillStyle = "#1a7f37"; ctx.fillText("goal", gx + 11, gy - 6);
}

function drawVehicles(scene, frame) {
  state.trails.forEach((trail, i) => {
    if (trail.length < 2) return;
    ctx.strokeStyle = colour(i); ctx.globalAlpha = 0.5;
    path(trail.map(([, x, y]) => [x, y]), false); ctx.stroke(); ctx.globalAlpha = 1;
  });
  if (!frame) return;
  ctx.font = "12px sans-serif";
  frame.vehicles.forEach((v, i) => {
    if (v.x === null || v.y === null) return;
    const [sx, sy] = px(v.x, v.y);
    if (v.slot && i !== frame.leader) {  // the leader's record slot is its goal, drawn already
      const [qx, qy] = px(v.slot[0], v.slot[1]);
      ctx.strokeStyle = colour(i); ctx.setLineDash([2, 3]);
      ctx.beginPath(); ctx.moveTo(sx, sy); ctx.lineTo(qx, qy); ctx.stroke(); ctx.setLineDash([]);
      ctx.strokeRect(qx - 4, qy - 4, 8, 8);
    }
    const yaw = v.yaw ?? 0;  // rad ENU: counter-clockwise from east; the canvas' y points down
    ctx.save();
    ctx.translate(sx, sy); ctx.rotate(-yaw);
    ctx.beginPath(); ctx.moveTo(12, 0); ctx.lineTo(-7, 6); ctx.lineTo(-4, 0); ctx.lineTo(-7, -6); ctx.closePath();
    ctx.fillStyle = v.lost || v.crashed ? "#999" : colour(i); ctx.fill();
    ctx.restore();
    if (i === frame.leader) {
      ctx.strokeStyle = "#e6a700"; ctx.lineWidth = 2;
      ctx.beginPath(); ctx.arc(sx, sy, 15, 0, 2 * Math.PI); ctx.stroke(); ctx.lineWidth = 1;
    }
    if (v.lost || v.crashed) {
      ctx.strokeStyle = "#b00"; ctx.lineWidth = 2;
      ctx.beginPath(); ctx.moveTo(sx - 8, sy - 8); ctx.lineTo(sx + 8, sy + 8);
      ctx.moveTo(sx + 8, sy - 8); ctx.lineTo(sx - 8, sy + 8); ctx.stroke(); ctx.lineWidth = 1;
    }
    const name = scene.vehicles[i] + (i === frame.leader ? " ★" : "");
    ctx.fillStyle = "#222";
    ctx.fillText(`${name} ${v.mode ?? ""}`, sx + 14, sy - 10);
  });
}

function draw() {
  resize();
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  drawGrid();
  if (!state.scene) return;
  drawSite(state.scene, state.frame);
  drawVehicles(state.scene, state.frame);
}

// ---- controls: replay commands, zoom and pan ----

el("act").addEventListener("click", () => {
  const verb = el("verb").value, target = el("target").value;
  const line = verb === "hold" || target === "all" ? verb : `${verb} ${target}`;
  send({ cmd: "action", line, token: el("token").value });
});
el("play").addEventListener("click", () => send({ cmd: state.status && state.status.playing ? "pause" : "play" }));
el("speed").addEventListener("change", (e) => send({ cmd: "speed", value: Number(e.target.value) }));
el("slider").addEventListener("input", (e) => { sliderHeld = true; send({ cmd: "seek", t: Number(e.target.value) }); });
el("slider").addEventListener("change", () => { sliderHeld = false; });
canvas.addEventListener("wheel", (e) => {
  e.preventDefault();
  state.view.scale *= e.deltaY < 0 ? 1.2 : 1 / 1.2;
  draw();
}, { passive: false });
let drag = null;
canvas.addEventListener("mousedown", (e) => { drag = [e.clientX, e.clientY]; });
window.addEventListener("mouseup", () => { drag = null; });
window.addEventListener("mousemove", (e) => {
  if (!drag) return;
  const ratio = window.devicePixelRatio || 1;
  state.view.cx -= (e.clientX - drag[0]) * ratio / state.view.scale;
  state.view.cy += (e.clientY - drag[1]) * ratio / state.view.scale;
  drag = [e.clientX, e.clientY];
  draw();
});
window.addEventListener("resize", draw);
connect();
draw();
