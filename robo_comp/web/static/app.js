// The page: a WebSocket to the gateway, the model, the canvas and the controls.
// Hash parameters: #t=SECONDS (replay position), speed=S, play=1, view=NAME&key=K (a view the server
// offers, with the key from the link the gateway printed).
import { Model } from "./model.js";
import { Renderer, VICTIM_FOUND, VICTIM_MISSED } from "./view.js";

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
window.robo = { model, renderer, S, showInfo: sel => showInfo(sel) };  // for tests and the console

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
        if (params.get("speed")) S.replay.speed = +params.get("speed") || 1;
        if (params.get("t") != null) { S.replay.t = +params.get("t") || 0; S.replay.playing = params.get("play") === "1"; }
        else { S.replay.t = msg.start || 0; S.replay.playing = params.get("play") !== "0"; }  // opens where the match starts, playing
        $("speed").value = String(S.replay.speed);
      }
      S.offered = msg.views || [];
      join();
      break;
    case "state": {
      S.view = msg.view || S.view;
      if (msg.live === false) { S.replay.t = msg.t; S.replay.at = perf(); S.replay.duration = msg.duration; }
      const t = matchNow();
      model.load(msg.state, msg.live === false ? msg.t : t, msg.live !== false);
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
      for (const it of msg.s || []) model.storyItem(it);
      if (msg.k) { model.story.scores.push(msg.k); model.story.version++; }
      if (msg.v) { model.story.victims = msg.v; model.story.version++; }
      break;
    }
    case "story":
      model.setStory(msg.story);
      hud(true);
      break;
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

// ------------------------------------------------------------------ HUD: clock, scoreboard, story
// One match clock everywhere: the header, the replay bar's two ends and every ticker line show
// the core's match clock (the recording's time only where the match has no phases).
function clockText(t) {
  const [el] = model.clock(t);
  return fmt(!model.match.phase && S.mode === "replay" ? t : el);
}
// The story's timeline now: the replay's position, or the live gateway's clock.
function storyNow() {
  if (S.mode === "replay") return matchNow();
  const st = model.story;
  return st.now != null ? st.now + (perf() - st.heard) : Infinity;
}
function hud(force = false) {
  const t = matchNow();
  const [, rem] = model.clock(t);
  const phase = model.match.phase;
  $("phase").textContent = phase || (S.mode === "replay" ? "replay" : "live");
  $("elapsed").textContent = clockText(t);
  $("remaining").textContent = rem != null && phase !== "finished" ? `(${fmt(rem)} left)` : "";
  if (S.mode === "replay") {
    $("t-now").textContent = clockText(t);
    $("t-now").title = `match clock (recording ${fmt(t)})`;
    const end = model.story.endClock;
    $("t-end").textContent = end != null ? fmt(end) : fmt(S.replay.duration);
    const tl = $("timeline");
    tl.max = String(Math.max(0.1, S.replay.duration));
    if (!S.dragging) tl.value = String(t);
    if (S.markersFor !== `${model.story.version}|${S.replay.duration}`) markers();
  }
  story(force);
  if (!force && model.version === S.hudVersion) return;
  S.hudVersion = model.version;
  banner();
  legend();
  debugPanel();
  const rows = (model.score.length ? model.score : (model.arena ? model.arena.teams.map(x => ({ team: x.name, score: 0, victims: 0 })) : []));
  $("score-table").tBodies[0].innerHTML = rows.map((r, i) => {
    const c = model.colour(r.team);
    return `<tr class="${r.disqualified ? "dq" : ""}"><td>${r.rank ?? i + 1}</td><td><span class="swatch" data-colour="${esc(c)}"></span>${esc(r.team)}</td><td class="num">${esc(fmtNum(r.score))}</td><td class="num">${esc(r.victims ?? 0)}</td></tr>`;
  }).join("");
  // colours set through the DOM: the page's Content-Security-Policy allows no inline style attributes
  paint($("score-table"));
  // referee broadcasts and penalties are in the ticker: the message bar keeps the rest (storage faults, refusals)
  $("messages").innerHTML = model.messages.filter(x => x.level !== "broadcast" && !/^(penalty|disqualified) /.test(x.text))
    .filter(x => t - x.t < 12 || S.mode === "replay" && Math.abs(t - x.t) < 12)
    .map(x => `<div class="${esc(x.level)}">${esc(x.text)}</div>`).join("");
}
// ------------------------------------------------------------------ the story: ticker, markers, chart, banner, legend
const KIND_COLOUR = { find: "#28be46", penalty: "#ff5646", bump: "#ff9f1a", lost: "#ffd200", phase: "#ffb020",
                      broadcast: "#7ab8ff", disqualified: "#ff2d55", score: "#c0c0d0" };
const TICKER_LINES = 40;
function visibleItems(now) {
  const items = model.story.items;
  let hi = items.length;
  if (S.mode === "replay") { let lo = 0; while (lo < hi) { const mid = (lo + hi) >> 1; if (items[mid].t <= now + 1e-6) lo = mid + 1; else hi = mid; } }
  return items.slice(Math.max(0, hi - TICKER_LINES), hi).reverse();
}
function itemColour(it) {
  if (it.kind === "find") return model.findColour(it.state);
  return it.team ? model.colour(it.team) : KIND_COLOUR[it.kind] || "#c0c0d0";
}
function story(force) {
  const now = storyNow(), st = model.story;
  const shown = visibleItems(now);
  const key = `${st.version}|${shown.length ? shown[0].id : 0}|${shown.length}`;
  if (force || key !== S.tickerKey) {
    S.tickerKey = key;
    $("ticker").innerHTML = shown.map(it => {
      const pts = it.points ? `<span class="pts ${it.points < 0 ? "neg" : "pos"}">${it.points > 0 ? "+" : "−"}${esc(fmtNum(Math.abs(it.points)))}</span>` : "<span></span>";
      return `<li class="k-${esc(it.kind)}${S.mode === "replay" ? " seekable" : ""}" data-t="${it.t}" title="${esc(it.kind)}">` +
        `<span class="tt">${esc(fmt(it.c ?? it.t))}</span><span class="tx"><span class="swatch" data-colour="${esc(itemColour(it))}"></span>${esc(it.text)}</span>${pts}</li>`;
    }).join("");
    paint($("ticker"));
  }
  chart(now);
}
$("ticker").addEventListener("click", e => {
  const li = e.target.closest("li");
  if (li && S.mode === "replay") seek(+li.dataset.t);
});
function seek(t) { send({ op: "seek", t: Math.max(0, t) }); }
function markers() {
  const st = model.story, d = Math.max(0.1, S.replay.duration);
  S.markersFor = `${st.version}|${S.replay.duration}`;
  const box = $("markers");
  box.innerHTML = "";
  for (const it of st.items) {
    if (it.kind === "score") continue;
    const b = document.createElement("button");
    b.type = "button";
    b.className = `mk k-${it.kind}`;
    b.style.left = `${Math.min(100, 100 * it.t / d)}%`;  // (CSSOM, which the page's CSP allows)
    b.style.background = itemColour(it);
    b.title = `${fmt(it.c ?? it.t)} ${it.text}`;
    b.setAttribute("aria-label", b.title);
    b.onclick = () => seek(it.t);
    box.appendChild(b);
  }
}
// The score over time: one line per team, up to now (a replay never shows the future).
function chart(now) {
  const cv = $("chart"), st = model.story;
  const dpr = window.devicePixelRatio || 1, w = cv.clientWidth, h = cv.clientHeight;
  if (!w || !h) return;
  const samples = st.scores;
  const key = `${st.version}|${samples.length}|${w}|${h}|${S.mode === "replay" ? Math.floor(now * 4) : 0}`;
  if (key === S.chartKey) return;
  S.chartKey = key;
  if (cv.width !== Math.round(w * dpr)) { cv.width = Math.round(w * dpr); cv.height = Math.round(h * dpr); }
  const ctx = cv.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  ctx.clearRect(0, 0, w, h);
  const upto = samples.filter(s => s[0] <= now + 1e-6);
  const end = S.mode === "replay" ? Math.max(0.1, S.replay.duration) : Math.max(1, samples.length ? samples[samples.length - 1][0] : 1, Number.isFinite(now) ? now : 0);
  const start = S.mode === "replay" ? 0 : (samples.length ? samples[0][0] : 0);
  let lo = 0, hi = 0;
  for (const [, , b] of upto) for (const v of Object.values(b)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (hi - lo < 1) hi = lo + 1;
  const X = t => 4 + (w - 8) * (t - start) / Math.max(0.1, end - start), Y = v => h - 14 - (h - 22) * (v - lo) / (hi - lo);
  ctx.strokeStyle = "#3a3c4c"; ctx.lineWidth = 1;
  ctx.beginPath(); ctx.moveTo(4, Y(0) + 0.5); ctx.lineTo(w - 4, Y(0) + 0.5); ctx.stroke();
  ctx.fillStyle = "#a0a2b0"; ctx.font = "10px system-ui, sans-serif"; ctx.textBaseline = "top";
  ctx.fillText(`${fmtNum(hi)}`, 4, 2); ctx.textBaseline = "bottom"; ctx.fillText(`${fmtNum(lo)}`, 4, h - 1);
  ctx.textAlign = "right"; ctx.fillText("score over time", w - 4, h - 1); ctx.textAlign = "left";
  const teams = new Set(); for (const [, , b] of upto) for (const k of Object.keys(b)) teams.add(k);
  for (const team of teams) {
    ctx.strokeStyle = model.colour(team); ctx.lineWidth = 2; ctx.beginPath();
    let prev = 0, first = true;
    for (const [t, , b] of upto) {
      const v = b[team] ?? prev;
      if (first) { ctx.moveTo(X(start), Y(0)); first = false; }
      ctx.lineTo(X(t), Y(prev)); ctx.lineTo(X(t), Y(v)); prev = v;
    }
    if (Number.isFinite(now)) ctx.lineTo(X(Math.min(end, now)), Y(prev));
    ctx.stroke();
  }
  if (S.mode === "replay") { ctx.strokeStyle = "#ffb020"; ctx.beginPath(); ctx.moveTo(X(now) + 0.5, 0); ctx.lineTo(X(now) + 0.5, h - 12); ctx.stroke(); }
}
// The winner banner when the match is over (the victims are revealed on the map then).
function banner() {
  const done = model.match.phase === "finished";
  $("banner").classList.toggle("hidden", !done);
  if (!done) return;
  const rows = [...model.score].filter(r => !r.disqualified).sort((a, b) => (a.rank ?? 99) - (b.rank ?? 99));
  let title = "Match over";
  if (rows.length && (rows.length < 2 || rows[0].score !== rows[1].score || rows[0].victims !== rows[1].victims)) title = `${rows[0].team} wins`;
  else if (rows.length >= 2) title = "A draw";
  const vs = model.story.victims;
  const found = vs.filter(v => (v.found_by || []).length).length;
  $("banner-title").textContent = title;
  $("banner-title").style.color = rows.length ? model.colour(rows[0].team) : "";
  $("banner-detail").textContent = rows.map(r => `${r.team} ${fmtNum(r.score)}`).join(" · ") +
    (vs.length ? ` — ${found} of ${vs.length} victims found (shown on the map)` : "");
}
// What the symbols and colours mean, in the colours the map uses.
function legend() {
  const L = model.legend, a = model.arena;
  const key = JSON.stringify([L, a && a.teams]);
  if (key === S.legendKey) return;
  S.legendKey = key;
  // [symbol class, colour, text]; colours go on through the DOM (the page's CSP allows no inline styles)
  const li = (sym, colour, text) => `<li><span class="sym ${sym}" data-colour="${esc(colour)}"></span>${esc(text)}</li>`;
  const out = [];
  for (const t of (a && a.teams) || []) out.push(li("dot", model.colour(t.name), `robot of ${t.name} (line: heading)`));
  if (L) {
    out.push(li("ring", L.lost, "lost robot"));
    out.push(li("dot", "#5a5a64", "robot that left"));
    for (const [state, c] of Object.entries(L.finds)) out.push(li("diamond", c, `find, ${state}`));
    out.push(li("square", "#7ab8ff", "picture taken"));
    out.push(li("triangle", "#c77dff", "video filmed"));
    out.push(li("dot", L.discovery, "discovery (team view)"));
    out.push(li("cross", VICTIM_FOUND, "victim found (at the end)"));
    out.push(li("cross", VICTIM_MISSED, "victim missed (at the end)"));
    out.push(li("square", L.wall, "wall"));
    out.push(li("square", L.costly, "costly cell (near a wall)"));
    for (const t of (a && a.teams) || []) if (t.start) out.push(li("square faint", model.colour(t.name), `start zone of ${t.name}`));
    for (const [kind, c] of Object.entries(L.zones)) out.push(li("square", c, `zone: ${kind}`));
  }
  $("legend-list").innerHTML = out.join("");
  paint($("legend-list"));
}

// The debug drawing toggles: all, and one per team whose robots drew something (team views,
// and a replay whose match shows it to everyone). A robot's own switch is in its info box.
function debugPanel() {
  const D = renderer.debug, teams = new Set();
  for (const tag of model.debug.keys()) { const r = model.robots.get(tag); teams.add(r ? r.team : null); }
  const names = [...teams].filter(t => t != null).sort();
  const key = JSON.stringify([names, D.on, [...D.offTeams].sort(), D.offRobots.size]);
  if (key === S.debugKey) return;
  S.debugKey = key;
  $("debug-panel").classList.toggle("hidden", !names.length && !S.debugSeen);
  if (names.length) S.debugSeen = true;
  const box = (id, on, text, colour) => `<label class="debug-row"><input type="checkbox" data-debug="${esc(id)}" ${on ? "checked" : ""}>` +
    (colour ? `<span class="swatch" data-colour="${esc(colour)}"></span>` : "") + `${esc(text)}</label>`;
  const off = D.offRobots.size ? ` (${D.offRobots.size} robot${D.offRobots.size > 1 ? "s" : ""} hidden)` : "";
  $("debug-list").innerHTML = box("*", D.on, `all${off}`) + names.map(t => box(t, !D.offTeams.has(t), t, model.colour(t))).join("");
  paint($("debug-list"));
  for (const el of $("debug-list").querySelectorAll("input")) el.onchange = () => {
    const id = el.dataset.debug;
    if (id === "*") { D.on = el.checked; if (D.on) D.offRobots.clear(); }
    else if (el.checked) D.offTeams.delete(id); else D.offTeams.add(id);
    D.version++; debugPanel();
  };
}
function toggleRobotDebug(tag) {
  const D = renderer.debug;
  if (D.offRobots.has(tag)) D.offRobots.delete(tag); else D.offRobots.add(tag);
  D.version++; debugPanel();
  $("btn-debug").textContent = D.offRobots.has(tag) ? "Show its drawing" : "Hide its drawing";
}

// Colours from data-colour attributes (a ring or a cross takes it as its border).
function paint(root) {
  for (const el of root.querySelectorAll("[data-colour]")) {
    if (el.classList.contains("ring") || el.classList.contains("cross")) el.style.borderColor = el.dataset.colour;
    else el.style.background = el.dataset.colour;
  }
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
  $("btn-debug").classList.toggle("hidden", !model.debug.has(tag) && !renderer.debug.offRobots.has(tag));
  $("btn-debug").textContent = renderer.debug.offRobots.has(tag) ? "Show its drawing" : "Hide its drawing";
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
  $("btn-debug").classList.add("hidden");
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
  if (th.kind === "video") await showVideo(box, th.id);
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
// A video's film in the info box (the core decides who may see it: the team that filmed it, the referee).
async function showVideo(box, vid) {
  try {
    const v = await ask("video", { id: vid });
    const el = document.createElement("video");
    el.src = v.webm; el.controls = true; el.autoplay = true; el.loop = true; el.muted = true;
    el.setAttribute("aria-label", `video ${vid}`); el.dataset.vid = vid;
    box.appendChild(el);
  } catch (e) {
    const d = document.createElement("p"); d.className = "error"; d.textContent = `video ${vid}: ${e.message}`;
    box.appendChild(d);
  }
}
$("info-close").onclick = () => showInfo(null);
$("btn-debug").onclick = () => { if (S.info && S.info.robot != null) toggleRobotDebug(S.info.robot); };
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
  else if (e.key === "d" || e.key === "D") { const D = renderer.debug; D.on = !D.on; D.version++; debugPanel(); }
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
  else if (model.story.version !== S.storyVersion) { S.storyVersion = model.story.version; story(false); }
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);
connect();
