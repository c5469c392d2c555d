// The page's picture of the match: loaded from a `state` message, then changed by events.
// It mirrors robo_comp/wall/model.py (the gateway's model) topic by topic; unknown topics are
// ignored, so the page keeps working when the core learns new events.

export const TRAIL_LEN = 40;
export const MESSAGE_SECONDS = 12;

const now = () => performance.now() / 1000;

export class Robot {
  constructor(tag, team) {
    this.tag = tag; this.team = team;
    this.x = 0; this.y = 0; this.h = 0;          // where the feed last put it
    this.fx = 0; this.fy = 0; this.fh = 0;       // where the drawing starts from (interpolation)
    this.t0 = 0; this.dur = 0; this.last = 0;
    this.status = "connected"; this.moving = false; this.task = null;
    this.trail = [];
  }
  // Drawn position at animation time `t`: glides from the old pose to the new one in about the
  // time between two updates, so 10 updates a second look like smooth motion.
  pose(t) {
    if (this.dur <= 0 || t >= this.t0 + this.dur) return [this.x, this.y, this.h];
    const k = Math.max(0, (t - this.t0) / this.dur);
    let dh = ((this.h - this.fh + 540) % 360) - 180;
    return [this.fx + (this.x - this.fx) * k, this.fy + (this.y - this.fy) * k, this.fh + dh * k];
  }
  moveTo(x, y, h, animate) {
    const t = now();
    if (animate && this.last > 0) {
      const [cx, cy, ch] = this.pose(t);
      this.fx = cx; this.fy = cy; this.fh = ch;
      this.dur = Math.min(1.0, Math.max(0.05, t - this.last));
      this.t0 = t;
    } else {
      this.dur = 0;
    }
    this.last = t;
    const tr = this.trail;
    if (!tr.length || Math.abs(tr[tr.length - 2] - x) + Math.abs(tr[tr.length - 1] - y) >= 0.5) {
      tr.push(x, y);
      if (tr.length > TRAIL_LEN * 2) tr.splice(0, 2);
    }
    this.x = x; this.y = y; this.h = h;
  }
}

export function findState(f) {
  if (f.state) return f.state;
  const v = f.verdict || {};
  if (v.valid) return "confirmed";
  if (v.duplicate) return "duplicate";
  return f.verdict ? "rejected" : "reported";
}

export class Model {
  constructor() { this.reset(); }

  reset() {
    this.arena = null;
    this.robots = new Map();
    this.things = new Map();
    this.score = [];
    this.match = { phase: "", elapsed: 0, remaining: null, heard: 0 };
    this.messages = [];
    this.version = 0;
    this.events = 0;
    this.animUntil = 0;  // robots glide until then (the page draws every frame until then)
    this.legend = null;
    this.debug = new Map();  // tag -> the robot's newest frame of debug drawing (team views; robo_comp/protocol/drawing.py)
    if (!this.story) this.setStory(null);
  }

  // The story (ticker lines, timeline markers, score samples, revealed victims): from a
  // `state` (live) or a `story` message (a replay's whole story, sent once per view).
  setStory(st) {
    this.story = { items: [], byId: new Map(), scores: [], victims: [], endClock: null, version: (this.story?.version || 0) + 1 };
    if (!st) return;
    for (const it of st.items || []) this.storyItem(it);
    this.story.scores = st.scores || [];
    this.story.victims = st.victims || [];
    this.story.endClock = st.end_clock ?? null;
  }
  // One ticker item, new or changed (a score line folded into it, a repeated bump).
  storyItem(it) {
    const st = this.story, old = st.byId.get(it.id);
    if (old) Object.assign(old, it);
    else { st.byId.set(it.id, it); st.items.push(it); if (st.items.length > 5000) st.byId.delete(st.items.shift().id); }
    st.version++;
  }

  // A find's colour by state: the legend's (the server's, the wall's), the same in every view.
  findColour(state) {
    const f = (this.legend && this.legend.finds) || {};
    return f[state] || f.reported || "#fac828";
  }

  colour(team) {
    const t = this.arena && this.arena.teams.find(t => t.name === team);
    return (t && t.colour) || "#808080";
  }

  // A `state` message's body; `t` is the match-clock time it was true at. `keepTrails`: a live
  // state (a view switch, a resync) keeps the longer trail the page already drew; a replay's
  // seek takes the state's trails (they are of that moment).
  load(s, t, keepTrails = false) {
    const keepArena = this.arena && s.arena && this.arena.map === s.arena.map ? this.arena : null;
    const version = this.version;
    const old = this.robots;
    this.reset();
    this.version = version;  // never goes back: the page redraws on every change of it
    this.arena = keepArena || s.arena;
    this.legend = s.legend || null;
    if (s.story) { this.setStory(s.story); this.story.now = s.now; this.story.heard = performance.now() / 1000; }
    for (const [tag, team, x, y, h, status, moving, task, trail] of s.robots || []) {
      const r = this.robot(tag, team);
      const was = old.get(tag);
      if (keepTrails && was && was.trail.length > (trail || []).length) r.trail = was.trail;
      else if (trail && trail.length) r.trail = trail.slice(-TRAIL_LEN * 2);
      r.moveTo(x, y, h, false);
      r.status = status; r.moving = !!moving; r.task = task || null;
    }
    for (const th of s.things || []) this.things.set(`${th.kind}:${th.id}`, th);
    for (const [tag, frame] of s.debug || []) this.debug.set(tag, frame);
    this.score = s.score || [];
    const m = s.match || {};
    this.match = { phase: m.phase || "", elapsed: m.elapsed || 0, remaining: m.remaining ?? null, heard: t };
    this.messages = (s.messages || []).map(x => ({ ...x, t }));
    this.version++;
  }

  robot(tag, team) {
    let r = this.robots.get(tag);
    if (!r) { r = new Robot(tag, team ?? null); this.robots.set(tag, r); }
    else if (team != null && r.team == null) r.team = team;
    return r;
  }

  note(text, level, t) {
    this.messages.push({ text, level, t });
    if (this.messages.length > 6) this.messages.shift();
  }

  // The match clock at time `t`: [elapsed, remaining], run on while the match runs.
  clock(t) {
    const m = this.match;
    if (m.phase !== "running") return [m.elapsed, m.remaining];
    const d = Math.max(0, t - m.heard);
    return [m.elapsed + d, m.remaining == null ? null : Math.max(0, m.remaining - d)];
  }

  // One event; `t` is its match-clock time, `animate` whether robots glide to new poses.
  apply(topic, d, t, animate = true) {
    const h = HANDLERS[topic];
    this.events++;
    if (h) { h(this, d || {}, t, animate); this.version++; }
  }

  setMatch(d, t) {
    if (d.phase) this.match.phase = d.phase;
    if (d.elapsed != null) this.match.elapsed = d.elapsed;
    if ("remaining" in d) this.match.remaining = d.remaining;
    this.match.heard = t;
  }

  find(f) {
    const th = { kind: "find", id: f.id, x: +f.x || 0, y: +f.y || 0, team: f.team ?? null, state: findState(f),
                 info: { ...f } };
    delete th.info.verdict;
    if (f.verdict && !("message" in th.info)) th.info.message = f.verdict.reason || "";
    const old = this.things.get(`find:${f.id}`);
    if (old && old.info && old.info.evidence && !th.info.evidence) th.info.evidence = old.info.evidence;
    this.things.set(`find:${f.id}`, th);
  }
}

function status(s) {
  return (m, d) => {
    const r = m.robot(d.tag, d.team);
    r.status = s; r.moving = false;
    if (d.x != null && d.y != null) r.moveTo(+d.x, +d.y, r.h, false);
    if (s === "left") r.task = null;
  };
}

const HANDLERS = {
  "robot.positions": (m, d, t, animate) => {
    const xs = d.x, ys = d.y, hs = d.heading, mv = d.moving, tags = d.tags || [];
    for (let i = 0; i < tags.length; i++) {
      const r = m.robot(tags[i], d.team);
      r.moveTo(+xs[i], +ys[i], +hs[i], animate);
      r.moving = mv ? !!mv[i] : true;
      if (r.t0 + r.dur > m.animUntil) m.animUntil = r.t0 + r.dur;
    }
  },
  "robot.registered": (m, d) => {
    const r = m.robot(d.tag, d.team);
    r.status = "connected";
    r.moveTo(d.x ?? r.x, d.y ?? r.y, d.heading ?? r.h, false);
  },
  "robot.returned": status("connected"),
  "robot.lost": status("lost"),
  "robot.left": status("left"),
  "robot.stopped": (m, d) => {
    const r = m.robot(d.tag, d.team);
    r.moving = false; r.task = null;
    if (d.x != null && d.y != null) r.moveTo(+d.x, +d.y, r.h, true);
    if (r.t0 + r.dur > m.animUntil) m.animUntil = r.t0 + r.dur;
  },
  "disqualified": (m, d, t) => {
    for (const tag of d.tags || []) m.robot(tag).status = "disqualified";
    m.note(`disqualified ${d.team || (d.tags || []).join(", ")}: ${d.reason || ""}`, "error", t);
  },
  "match.phase": (m, d, t) => m.setMatch(d, t),
  "score": (m, d, t) => {
    if (d.teams) m.score = d.teams;
    if (d.phase) m.setMatch(d, t);
  },
  "find.reported": (m, d) => m.find(d),
  "map.discovery": (m, d) => m.things.set(`discovery:${d.id}`, { kind: "discovery", id: d.id, x: +d.x || 0,
    y: +d.y || 0, team: d.team ?? null, state: d.state || "discovered", info: { ...d } }),
  "picture": (m, d) => m.things.set(`picture:${d.id}`, { kind: "picture", id: d.id, x: +d.x || 0, y: +d.y || 0,
    team: d.team ?? null, state: "", info: { ...d } }),
  "video": (m, d) => m.things.set(`video:${d.id}`, { kind: "video", id: d.id, x: +d.x || 0, y: +d.y || 0,
    team: d.team ?? null, state: "", info: { ...d } }),
  "broadcast": (m, d, t) => m.note(String(d.message ?? ""), "broadcast", t),
  "penalty": (m, d, t) => m.note(`penalty ${d.team}: ${d.points} (${d.reason || ""})`, "error", t),
  "task.started": (m, d) => { if (d.tag != null) m.robot(d.tag, d.team).task = d.name || null; },
  "task.done": (m, d) => { const r = m.robots.get(d.tag); if (r) r.task = null; },
  // team code's debug drawing: each robot's new frame replaces its last (an empty one clears it)
  "debug.draw": (m, d) => {
    const tags = d.tags || [], frames = d.frames || [];
    for (let i = 0; i < tags.length; i++) {
      if (frames[i] && frames[i].length) m.debug.set(tags[i], frames[i]); else m.debug.delete(tags[i]);
    }
  },
};
