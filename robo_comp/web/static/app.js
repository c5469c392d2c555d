// The page: a WebSocket to the gateway, the model, the canvas and the controls.
// Hash parameters: #t=SECONDS (replay position), speed=S, play=1, view=NAME&key=K (a view the server
// offers, with the key from the link the gateway printed).
import { Model } from "./model.js";
import { Renderer } from "./view.js";

const $ = id => document.getElementById(id);
const perf = () => performance.now() / 1000;
const model = new Model();
const renderer = new Renderer($("map"), model);
const params = new URLSearchParams(location.hash.slice(1));

const S = {
  ws: null, mode: null, view: { name: "public", kind: "public" }, token: sessionStorage.getItem("robo_comp.token") || "",
  replay: { t: 0, at: perf(), playing: false, speed: 1, duration: 0 },
  nextId: 1, pending: new Map(), follow: null, info: null, lastHud: 0, hudVersion: -1, dragging: false,
  stats: { frames: 0, drawn: 0, drawMs: 0, since: perf(), states: 0, evs: 0, lastState: 0, gaps: [], draws: [], last: 0 },
};
// for tests and the bench: the page's model, renderer and counters
window.robo = { model, renderer, S };

// ------------------------------------------------------------------ clock
function matchNow() {
  if (S.mode !== "replay") return perf();
  const r = S.replay;
  return Math.min(r.duration, r.t + (r.playing ? (perf() - r.at) * r.speed : 0));
}
function fmt(sec) {
  if (sec == null) return "";
  sec = Math.max(0, Math.floor(sec));
  const h = Math.floor(sec / 3600), m = Math.floor(sec / 60) % 60, s = sec % 60;
  return (h ? `${h}:${String(m).padStart(2, "0")}` : `${m}`) + `:${String(s).padStart(2, "0")}`;
}

// ------------------------------------------------------------------ connection
function connect() {
  const ws = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`);
  S.ws = ws;
  ws.onopen = () => status("");
  ws.onmessage = e => receive(JSON.parse(e.data));
  ws.onclose = () => { status("connection to the gateway lost; retrying…"); setTimeout(connect, 1000); };
}
function send(msg) { if (S.ws && S.ws.readyState === 1) S.ws.send(JSON.stringify(msg)); }
function ask(op, body = {}) {
  const id = S.nextId++;
  return new Promise((resolve, reject) => { S.pending.set(id, { resolve, reject }); send({ ...body, op, req: id }); });
}
function join() {
  const msg = { op: "join" };
  if (S.token) msg.token = S.token;
  else if (params.get("view")) { msg.view = params.get("view"); msg.key = params.get("key") || ""; }
  if (S.mode === "replay") {
    msg.t = S.replay.t || +(params.get("t") || 0);
    msg.speed = S.replay.speed;
    msg.play = S.replay.playing;
  }
  send(msg);
}

function receive(msg) {
  switch (msg.type) {
    case "hello":
      S.mode = msg.mode;
      if (S.mode === "replay") {
        $("replay").classList.remove("hidden");
        S.replay.duration = msg.duration;
        if (params.get("t") != null) S.replay.t = +params.get("t") || 0;
        if (params.get("speed")) S.replay.speed = +params.get("speed") || 1;
        S.replay.playing = params.get("play") === "1";
        $("speed").value = String(S.replay.speed);
      }
      S.offered = msg.views || [];
      join();
      break;
    case "state": {
      S.view = msg.view || S.view;
      if (msg.live === false) { S.replay.t = msg.t; S.replay.at = perf(); S.replay.duration = msg.duration; }
      const t = matchNow();
      model.load(msg.state, msg.live === false ? msg.t : t);
      for (const [topic, d, te] of msg.after || []) model.apply(topic, d, te, false);
      if (renderer.camera.fitted) renderer.fit();
      S.stats.states++; S.stats.lastState = perf();
      viewLabel(); hud(true); refreshInfo();
      break;
    }
    case "ev": {
      if (msg.t != null) { S.replay.t = msg.t; S.replay.at = perf(); }
      const t = matchNow();
      for (const [topic, d, te] of msg.e) model.apply(topic, d, te ?? t);
      S.stats.evs += msg.e.length;
      break;
    }
    case "clock":
      Object.assign(S.replay, { t: msg.t, at: perf(), playing: msg.playing, speed: msg.speed, duration: msg.duration });
      $("btn-play").textContent = msg.playing ? "❚❚" : "▶";
      $("speed").value = String(msg.speed);
      break;
    case "reply": {
      const p = S.pending.get(msg.req);
      if (p) { S.pending.delete(msg.req); msg.ok ? p.resolve(msg.body) : p.reject(new Error(msg.error.message)); }
      break;
    }
    case "error":
      if (msg.op !== "join") status(msg.message, 6);
      else if (S.token) {  // a refused token: back to the public view
        S.token = ""; sessionStorage.removeItem("robo_comp.token");
        $("token-error").textContent = msg.message;
        if (!$("token-dialog").open) $("token-dialog").showModal();
        join();
      } else if (params.get("view")) {  // a view this server does not offer
        params.delete("view"); history.replaceState(null, "", "#" + params);
        status(msg.message, 8); join();
      } else {  // the core is not there yet: try again
        status(msg.message);
        setTimeout(join, 2000);
      }
      break;
  }
}

let statusTimer = null;
function status(text, seconds = 0) {
  $("status").textContent = text;
  $("status").classList.toggle("hidden", !text);
  clearTimeout(statusTimer);
  if (text && seconds) statusTimer = setTimeout(() => status(""), seconds * 1000);
}

function viewLabel() {
  const v = S.view, l = $("view-label");
  l.textContent = v.kind === "private" ? `${v.name} (private)` : "public";
  l.classList.toggle("private", v.kind === "private");
  $("arena-name").textContent = model.arena ? model.arena.name : "";
}

// ------------------------------------------------------------------ HUD: clock, scoreboard, messages
function hud(force = false) {
  const t = matchNow();
  const [el, rem] = model.clock(t);
  $("phase").textContent = model.match.phase || (S.mode === "replay" ? "replay" : "live");
  $("elapsed").textContent = fmt(!model.match.phase && S.mode === "replay" ? t : el);  // no phases: the recording's time
  $("remaining").textContent = rem != null ? `(${fmt(rem)} left)` : "";
  if (S.mode === "replay") {
    $("t-now").textContent = fmt(t); $("t-end").textContent = fmt(S.replay.duration);
    const tl = $("timeline");
    tl.max = String(Math.max(0.1, S.replay.duration));
    if (!S.dragging) tl.value = String(t);
  }
  if (!force && model.version === S.hudVersion) return;
  S.hudVersion = model.version;
  const rows = (model.score.length ? model.score : (model.arena ? model.arena.teams.map(x => ({ team: x.name, score: 0, victims: 0 })) : []));
  $("score-table").tBodies[0].innerHTML = rows.map((r, i) => {
    const c = model.colour(r.team);
    return `<tr class="${r.disqualified ? "dq" : ""}"><td>${r.rank ?? i + 1}</td><td><span class="swatch" data-colour="${esc(c)}"></span>${esc(r.team)}</td><td class="num">${esc(fmtNum(r.score))}</td><td class="num">${esc(r.victims ?? 0)}</td></tr>`;
  }).join("");
  // colours set through the DOM: the page's Content-Security-Policy allows no inline style attributes
  for (const s of $("score-table").querySelectorAll(".swatch")) s.style.background = s.dataset.colour;
  $("messages").innerHTML = model.messages.filter(x => t - x.t < 12 || S.mode === "replay" && Math.abs(t - x.t) < 12)
    .map(x => `<div class="${esc(x.level)}">${esc(x.text)}</div>`).join("");
}
const fmtNum = v => typeof v === "number" ? (Number.isInteger(v) ? v : v.toFixed(1)) : (v ?? "");
const esc = v => String(v ?? "").replace(/[&<>"']/g, c => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]);

// ------------------------------------------------------------------ info box: a robot's monitor data, a find's evidence
function showInfo(sel) {
  S.info = sel;
  renderer.selected = sel && sel.robot != null ? sel.robot : null;
  renderer.selectedThing = sel && sel.thing ? sel.thing : null;
  $("info").classList.toggle("hidden", !sel);
  if (!sel) { S.follow = null; return; }
  refreshInfo(true);
}
let infoBusy = false;
async function refreshInfo(fresh = false) {
  const sel = S.info;
  if (!sel || (infoBusy && !fresh)) return;
  infoBusy = true;
  try {
    if (sel.robot != null) await robotInfo(sel.robot, fresh);
    else await thingInfo(sel.thing, fresh);
  } finally { infoBusy = false; }
}
function fields(obj) {
  $("info-fields").innerHTML = Object.entries(obj).filter(([, v]) => v !== undefined && v !== null && v !== "")
    .map(([k, v]) => `<dt>${esc(k)}</dt><dd>${esc(typeof v === "object" ? JSON.stringify(v) : v)}</dd>`).join("");
}
async function robotInfo(tag, fresh) {
  const r = model.robots.get(tag);
  $("info-title").textContent = `Robot ${tag}`;
  $("btn-follow").classList.remove("hidden");
  $("btn-follow").textContent = S.follow === tag ? "Stop following" : "Follow";
  if (fresh) $("info-pictures").innerHTML = "";
  const base = r ? { team: r.team, status: r.status, x: r.x.toFixed(2), y: r.y.toFixed(2), heading: `${Math.round(r.h)}°`,
                     moving: r.moving ? "yes" : "no", task: r.task || "–" } : {};
  if (S.mode === "replay") { fields(base); return; }
  try {
    const m = await ask("monitor", { tag });
    if (!S.info || S.info.robot !== tag) return;
    const task = m.task && typeof m.task === "object" ? `${m.task.name}#${m.task.task_id} ${JSON.stringify(m.task.args ?? "")}` : (m.task || "–");
    const out = { ...base, task, queue: m.queue, sensors: m.sensors, "last report": m.last_report,
                  done: Array.isArray(m.done) ? m.done.slice(-3).map(d => `${d.name}: ${d.ok ? "ok" : "failed"} ${d.status || ""}`).join("; ") : undefined,
                  note: m.note };
    fields(out);
  } catch (e) { fields({ ...base, refused: e.message }); }
}
async function thingInfo(key, fresh) {
  const th = model.things.get(key);
  $("btn-follow").classList.add("hidden");
  if (!th) { $("info-title").textContent = "gone"; fields({}); return; }
  $("info-title").textContent = `${th.kind[0].toUpperCase()}${th.kind.slice(1)} ${th.id}`;
  const info = { ...th.info };
  for (const k of ["id", "x", "y", "team"]) delete info[k];
  fields({ team: th.team, state: th.state, at: `${th.x}, ${th.y}`, ...info,
           evidence: th.info.evidence ?? (S.view.kind === "public" ? "private to the team (enter its token)" : undefined) });
  if (!fresh) return;
  const pics = th.kind === "picture" ? [th.id] : (Array.isArray(th.info.evidence) ? th.info.evidence : []);
  const box = $("info-pictures");
  box.innerHTML = "";
  for (const pid of pics.slice(0, 4)) {
    try {
      const p = await ask("picture", { id: pid });
      const img = new Image(); img.src = p.png; img.alt = `picture ${pid}`; img.dataset.pid = pid;
      box.appendChild(img);
    } catch (e) {
      const d = document.createElement("p"); d.className = "error"; d.textContent = `picture ${pid}: ${e.message}`;
      box.appendChild(d);
    }
  }
}
$("info-close").onclick = () => showInfo(null);
$("btn-follow").onclick = () => {
  const tag = S.info && S.info.robot;
  S.follow = S.follow === tag ? null : tag;
  $("btn-follow").textContent = S.follow != null ? "Stop following" : "Follow";
  if (S.follow != null) renderer.camera.fitted = false;
};
setInterval(() => refreshInfo(false), 1000);

// ------------------------------------------------------------------ input: zoom, pan, pinch, click
const canvas = $("map");
const pointers = new Map();
let down = null, pinch = null;
canvas.addEventListener("pointerdown", e => {
  canvas.setPointerCapture(e.pointerId);
  pointers.set(e.pointerId, [e.offsetX, e.offsetY]);
  if (pointers.size === 1) down = { x: e.offsetX, y: e.offsetY, moved: 0 };
  else if (pointers.size === 2) { const [a, b] = [...pointers.values()]; pinch = Math.hypot(a[0] - b[0], a[1] - b[1]); down = null; }
});
canvas.addEventListener("pointermove", e => {
  const p = pointers.get(e.pointerId);
  if (!p) return;
  const dx = e.offsetX - p[0], dy = e.offsetY - p[1];
  pointers.set(e.pointerId, [e.offsetX, e.offsetY]);
  if (pointers.size === 2 && pinch) {
    const [a, b] = [...pointers.values()];
    const d = Math.hypot(a[0] - b[0], a[1] - b[1]);
    renderer.camera.zoomAt((a[0] + b[0]) / 2, (a[1] + b[1]) / 2, d / pinch);
    pinch = d;
  } else if (down) {
    down.moved += Math.abs(dx) + Math.abs(dy);
    if (down.moved > 4) { renderer.camera.pan(dx, dy); S.follow = null; }
  }
});
function pointerEnd(e) {
  pointers.delete(e.pointerId);
  if (pointers.size < 2) pinch = null;
  if (down && down.moved <= 4 && e.type === "pointerup") {
    const hit = renderer.hit(e.offsetX, e.offsetY, perf());
    showInfo(hit);
  }
  down = null;
}
canvas.addEventListener("pointerup", pointerEnd);
canvas.addEventListener("pointercancel", pointerEnd);
canvas.addEventListener("wheel", e => {
  e.preventDefault();
  renderer.camera.zoomAt(e.offsetX, e.offsetY, Math.exp(-e.deltaY * 0.0015));
}, { passive: false });
window.addEventListener("keydown", e => {
  if (e.target.tagName === "INPUT") return;
  if (e.key === "f" || e.key === "0") { renderer.fit(); S.follow = null; }
  else if (e.key === "+" || e.key === "=") renderer.camera.zoomAt(renderer.w / 2, renderer.h / 2, 1.25);
  else if (e.key === "-") renderer.camera.zoomAt(renderer.w / 2, renderer.h / 2, 0.8);
  else if (e.key === "Escape") showInfo(null);
  else if (e.key === " " && S.mode === "replay") { e.preventDefault(); togglePlay(); }
});
$("btn-fit").onclick = () => { renderer.fit(); S.follow = null; };
$("btn-score").onclick = () => $("score").classList.toggle("folded");

// ------------------------------------------------------------------ views: the team token
$("btn-token").onclick = () => {
  $("token-error").textContent = "";
  $("views").innerHTML = (S.offered || []).map(v => `<button type="button" data-view="${esc(v)}">${esc(v)}</button>`).join(" ");
  for (const b of $("views").querySelectorAll("button")) b.onclick = () => {
    S.token = ""; params.set("view", b.dataset.view); history.replaceState(null, "", "#" + params); join(); $("token-dialog").close();
  };
  $("token-dialog").showModal();
};
$("token-form").addEventListener("submit", () => {
  S.token = $("token-input").value.trim();
  $("token-input").value = "";
  if (S.token) sessionStorage.setItem("robo_comp.token", S.token);
  join();
});
$("btn-public").onclick = () => {
  S.token = ""; sessionStorage.removeItem("robo_comp.token"); params.delete("view");
  history.replaceState(null, "", "#" + params); join(); $("token-dialog").close();
};
$("btn-cancel").onclick = () => $("token-dialog").close();

// ------------------------------------------------------------------ replay controls
function togglePlay() { send({ op: S.replay.playing ? "pause" : "play" }); }
$("btn-play").onclick = togglePlay;
$("speed").onchange = e => send({ op: "speed", value: +e.target.value });
let seekTimer = null;
$("timeline").addEventListener("input", e => {
  S.dragging = true;
  $("t-now").textContent = fmt(+e.target.value);
  clearTimeout(seekTimer);
  seekTimer = setTimeout(() => send({ op: "seek", t: +e.target.value }), 60);
});
$("timeline").addEventListener("change", e => { S.dragging = false; clearTimeout(seekTimer); send({ op: "seek", t: +e.target.value }); });
$("btn-link").onclick = async () => {
  const p = new URLSearchParams({ t: String(Math.floor(matchNow())), speed: String(S.replay.speed) });
  if (S.replay.playing) p.set("play", "1");
  const url = `${location.origin}${location.pathname}#${p}`;
  history.replaceState(null, "", "#" + p);
  try { await navigator.clipboard.writeText(url); status("link copied", 2); } catch { status(url, 8); }
};
window.addEventListener("hashchange", () => {
  const p = new URLSearchParams(location.hash.slice(1));
  if (S.mode === "replay" && p.get("t") != null) send({ op: "seek", t: +p.get("t") || 0 });
});

// ------------------------------------------------------------------ the frame loop
function frame() {
  const t = perf(), st = S.stats;
  st.frames++;
  if (st.last) { st.gaps.push(t - st.last); if (st.gaps.length > 2000) st.gaps.shift(); }
  st.last = t;
  renderer.resize();
  if (S.follow != null) {
    const r = model.robots.get(S.follow);
    if (r) { const [x, y] = r.pose(t); renderer.camera.centreOn(x, y, renderer.w, renderer.h); }
  }
  if (renderer.needsDraw(t)) {
    const t0 = performance.now();
    renderer.draw(t);
    const took = performance.now() - t0;
    st.drawMs += took;
    st.draws.push(took); if (st.draws.length > 2000) st.draws.shift();
    st.drawn++;
  }
  if (t - S.lastHud > 0.25) { S.lastHud = t; hud(); }
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);
connect();
