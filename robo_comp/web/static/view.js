// The canvas: the map image scaled up, trails, finds and robots, drawn for a camera that can
// zoom, pan, fit the window and follow a robot. Robots are drawn in one path per team colour,
// so a thousand robots cost a handful of canvas calls.

const BG = "#0c0c10";
export const VICTIM_FOUND = "#28be46", VICTIM_MISSED = "#ff3b30";

export class Camera {
  constructor() { this.scale = 10; this.ox = 0; this.oy = 0; this.fitted = true; }
  toScreen(x, y) { return [this.ox + x * this.scale, this.oy + y * this.scale]; }
  toWorld(sx, sy) { return [(sx - this.ox) / this.scale, (sy - this.oy) / this.scale]; }
  fit(w, h, aw, ah) {
    this.scale = Math.max(0.05, Math.min(w / aw, h / ah) * 0.96);
    this.ox = (w - aw * this.scale) / 2; this.oy = (h - ah * this.scale) / 2;
    this.fitted = true;
  }
  zoomAt(sx, sy, f) {
    const s = Math.min(400, Math.max(0.05, this.scale * f));
    const [wx, wy] = this.toWorld(sx, sy);
    this.scale = s; this.ox = sx - wx * s; this.oy = sy - wy * s;
    this.fitted = false;
  }
  pan(dx, dy) { this.ox += dx; this.oy += dy; this.fitted = false; }
  centreOn(x, y, w, h) { this.ox = w / 2 - (x + 0.5) * this.scale; this.oy = h / 2 - (y + 0.5) * this.scale; }
}

export class Renderer {
  constructor(canvas, model) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d", { alpha: false });
    this.model = model;
    this.camera = new Camera();
    this.img = null; this.imgSrc = "";
    this.selected = null;     // robot tag
    this.selectedThing = null; // thing key
    this.trails = true;
    // debug drawing: on for all, and the teams and robots switched off (the page's toggles)
    this.debug = { on: true, offTeams: new Set(), offRobots: new Set(), version: 0 };
    this.w = 0; this.h = 0; this.dpr = 1;
    this.dirty = true;   // something not in the model changed (the map image came, a selection)
    this.drawnKey = "";
  }

  // Whether a frame at time `t` would differ from the last one drawn: the model changed, the
  // camera moved, a selection changed or robots are still gliding. An idle page draws nothing.
  needsDraw(t) {
    const c = this.camera;
    const key = `${this.model.version}|${c.scale}|${c.ox}|${c.oy}|${this.w}|${this.h}|${this.selected}|${this.selectedThing}|${this.debug.version}`;
    if (this.dirty || key !== this.drawnKey || t <= this.model.animUntil + 0.05) {
      this.dirty = false; this.drawnKey = key;
      return true;
    }
    return false;
  }

  resize() {
    const dpr = window.devicePixelRatio || 1;
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
    if (w === this.w && h === this.h && dpr === this.dpr) return false;
    this.w = w; this.h = h; this.dpr = dpr;
    this.canvas.width = Math.max(1, Math.round(w * dpr));
    this.canvas.height = Math.max(1, Math.round(h * dpr));
    if (this.camera.fitted) this.fit();
    return true;
  }

  fit() {
    const a = this.model.arena;
    if (a) this.camera.fit(this.w, this.h, a.width, a.height);
  }

  mapImage() {
    const a = this.model.arena;
    if (!a || !a.map) return null;
    if (this.imgSrc !== a.map) {
      this.imgSrc = a.map;
      this.img = new Image();
      this.img.src = a.map;
    }
    if (!this.img.complete) { this.img.onload = () => { this.dirty = true; }; return null; }
    return this.img;
  }

  // Draw one frame at animation time `t` (seconds, performance clock).
  draw(t) {
    const ctx = this.ctx, m = this.model, cam = this.camera, s = cam.scale;
    ctx.setTransform(this.dpr, 0, 0, this.dpr, 0, 0);
    ctx.fillStyle = BG;
    ctx.fillRect(0, 0, this.w, this.h);
    const a = m.arena;
    if (!a) return;
    const img = this.mapImage();
    ctx.imageSmoothingEnabled = false;
    if (img) ctx.drawImage(img, cam.ox, cam.oy, a.width * s, a.height * s);
    if (s >= 14) this.grid(a);
    // known objects
    ctx.fillStyle = "#785432";
    for (const o of a.objects || []) {
      const [x, y] = cam.toScreen(+o.x + 0.2, +o.y + 0.2);
      ctx.fillRect(x, y, Math.max(2, 0.6 * s), Math.max(2, 0.6 * s));
    }
    const robots = [...m.robots.values()];
    if (this.trails) this.drawTrails(robots);
    this.drawThings();
    if (m.match.phase === "finished" && m.story.victims.length) this.drawVictims(m.story.victims);
    this.drawRobots(robots, t);
    if (this.debug.on && m.debug.size) this.drawDebug();
  }

  // Team code's debug drawing (robot.draw_dot/line/text): each shown robot's newest frame, over
  // everything else, thin so the match stays readable. Shapes are map cells; a dot sits in its cell's centre.
  drawDebug() {
    const ctx = this.ctx, cam = this.camera, s = cam.scale, m = this.model, D = this.debug;
    const X = x => cam.ox + (x + 0.5) * s, Y = y => cam.oy + (y + 0.5) * s;
    const r = Math.max(2.5, s * 0.18);
    ctx.lineWidth = Math.max(1.5, s * 0.08);
    ctx.font = `600 ${Math.round(Math.max(10, Math.min(14, s * 0.6)))}px system-ui, sans-serif`;
    ctx.textAlign = "left"; ctx.textBaseline = "middle";
    this.debugShown = 0;
    for (const [tag, frame] of m.debug) {
      const rb = m.robots.get(tag);
      if (D.offRobots.has(tag) || (rb && D.offTeams.has(rb.team))) continue;
      for (const sh of frame) {
        const col = sh[sh.length - 1];
        if (sh[0] === "d") {
          ctx.fillStyle = col; ctx.beginPath(); ctx.arc(X(+sh[1]), Y(+sh[2]), r, 0, Math.PI * 2); ctx.fill();
        } else if (sh[0] === "l") {
          ctx.strokeStyle = col; ctx.beginPath(); ctx.moveTo(X(+sh[1]), Y(+sh[2])); ctx.lineTo(X(+sh[3]), Y(+sh[4])); ctx.stroke();
        } else if (sh[0] === "t") {
          const text = String(sh[3]), x = X(+sh[1]), y = Y(+sh[2]);
          ctx.fillStyle = "rgba(12,12,16,0.7)"; ctx.fillRect(x - 2, y - 8, ctx.measureText(text).width + 4, 16);
          ctx.fillStyle = col; ctx.fillText(text, x, y);
        }
        this.debugShown++;
      }
    }
  }

  // The hidden victims, revealed when the match is over: a ring and a cross, green when a team
  // found the victim, red when no one did, with its id.
  drawVictims(victims) {
    const ctx = this.ctx, cam = this.camera, s = cam.scale;
    const r = Math.max(6, s * 0.5);
    ctx.lineWidth = Math.max(2, r * 0.28);
    ctx.font = `700 ${Math.round(Math.max(10, Math.min(14, r)))}px system-ui, sans-serif`;
    ctx.textAlign = "left"; ctx.textBaseline = "middle";
    for (const v of victims) {
      const cx = cam.ox + (+v.x + 0.5) * s, cy = cam.oy + (+v.y + 0.5) * s;
      const col = (v.found_by || []).length ? VICTIM_FOUND : VICTIM_MISSED;
      ctx.beginPath(); ctx.arc(cx, cy, r, 0, Math.PI * 2);
      ctx.moveTo(cx - r * 0.6, cy); ctx.lineTo(cx + r * 0.6, cy); ctx.moveTo(cx, cy - r * 0.6); ctx.lineTo(cx, cy + r * 0.6);
      ctx.strokeStyle = "#ffffff"; ctx.lineWidth = Math.max(4, r * 0.45); ctx.stroke();
      ctx.strokeStyle = col; ctx.lineWidth = Math.max(2, r * 0.28); ctx.stroke();
      const label = String(v.id);
      const w = ctx.measureText(label).width;
      ctx.fillStyle = "rgba(12,12,16,0.8)"; ctx.fillRect(cx + r + 2, cy - 8, w + 6, 16);
      ctx.fillStyle = col; ctx.fillText(label, cx + r + 5, cy);
    }
  }

  grid(a) {
    const ctx = this.ctx, cam = this.camera, s = cam.scale;
    ctx.strokeStyle = "rgba(0,0,0,0.08)";
    ctx.lineWidth = 1;
    ctx.beginPath();
    const x0 = Math.max(0, Math.floor(-cam.ox / s)), x1 = Math.min(a.width, Math.ceil((this.w - cam.ox) / s));
    const y0 = Math.max(0, Math.floor(-cam.oy / s)), y1 = Math.min(a.height, Math.ceil((this.h - cam.oy) / s));
    for (let x = x0; x <= x1; x++) { const sx = Math.round(cam.ox + x * s) + 0.5; ctx.moveTo(sx, cam.oy + y0 * s); ctx.lineTo(sx, cam.oy + y1 * s); }
    for (let y = y0; y <= y1; y++) { const sy = Math.round(cam.oy + y * s) + 0.5; ctx.moveTo(cam.ox + x0 * s, sy); ctx.lineTo(cam.ox + x1 * s, sy); }
    ctx.stroke();
  }

  drawTrails(robots) {
    const ctx = this.ctx, cam = this.camera, s = cam.scale;
    const byTeam = new Map();
    for (const r of robots) {
      if (r.trail.length < 4 || r.status === "left") continue;
      if (!byTeam.has(r.team)) byTeam.set(r.team, []);
      byTeam.get(r.team).push(r);
    }
    ctx.lineWidth = Math.max(1, s * 0.12);
    ctx.globalAlpha = 0.35;
    for (const [team, rs] of byTeam) {
      ctx.strokeStyle = this.model.colour(team);
      ctx.beginPath();
      for (const r of rs) {
        const tr = r.trail;
        ctx.moveTo(cam.ox + (tr[0] + 0.5) * s, cam.oy + (tr[1] + 0.5) * s);
        for (let i = 2; i < tr.length; i += 2) ctx.lineTo(cam.ox + (tr[i] + 0.5) * s, cam.oy + (tr[i + 1] + 0.5) * s);
      }
      ctx.stroke();
    }
    ctx.globalAlpha = 1;
  }

  drawThings() {
    const ctx = this.ctx, cam = this.camera, s = cam.scale;
    const r = Math.max(5, s * 0.45);
    for (const [key, th] of this.model.things) {
      const cx = cam.ox + (th.x + 0.5) * s, cy = cam.oy + (th.y + 0.5) * s;
      if (cx < -20 || cy < -20 || cx > this.w + 20 || cy > this.h + 20) continue;
      ctx.beginPath();
      if (th.kind === "find") {
        ctx.moveTo(cx, cy - r); ctx.lineTo(cx + r, cy); ctx.lineTo(cx, cy + r); ctx.lineTo(cx - r, cy); ctx.closePath();
        ctx.fillStyle = this.model.findColour(th.state);
      } else if (th.kind === "picture") {
        const q = r * 0.6;
        ctx.rect(cx - q, cy - q * 0.75, 2 * q, 1.5 * q);
        ctx.fillStyle = "#7ab8ff";
      } else if (th.kind === "video") {
        videoMark(ctx, cx, cy, r);
      } else {
        ctx.arc(cx, cy, r * 0.7, 0, Math.PI * 2);
        ctx.fillStyle = "#ff8c00";
      }
      ctx.fill();
      ctx.lineWidth = key === this.selectedThing ? 3 : 1.2;
      ctx.strokeStyle = key === this.selectedThing ? "#ffffff" : "#141418";
      ctx.stroke();
    }
  }

  drawRobots(robots, t) {
    const ctx = this.ctx, cam = this.camera, s = cam.scale, m = this.model;
    const rad = Math.max(3, s * 0.42);
    const groups = new Map();
    const lost = [], gone = [], dq = [];
    const poses = new Map();
    const W = this.w + rad, H = this.h + rad;
    for (const r of robots) {
      const [x, y, h] = r.pose(t);
      const cx = cam.ox + (x + 0.5) * s, cy = cam.oy + (y + 0.5) * s;
      if (cx < -rad || cy < -rad || cx > W || cy > H) continue;
      poses.set(r.tag, [cx, cy, h]);
      const key = r.status === "left" ? "#5a5a64" : r.team;
      if (!groups.has(key)) groups.set(key, []);
      groups.get(key).push(r);
      if (r.status === "lost") lost.push(r);
      else if (r.status === "left") gone.push(r);
      else if (r.status === "disqualified") dq.push(r);
    }
    // bodies, one path per colour
    for (const [key, rs] of groups) {
      ctx.fillStyle = key === "#5a5a64" ? key : m.colour(key);
      ctx.beginPath();
      for (const r of rs) {
        const [cx, cy] = poses.get(r.tag);
        ctx.moveTo(cx + rad, cy);
        ctx.arc(cx, cy, rad, 0, Math.PI * 2);
      }
      ctx.fill();
      if (rad >= 5) { ctx.lineWidth = 1; ctx.strokeStyle = "#141418"; ctx.stroke(); }
    }
    // headings, one path
    ctx.beginPath();
    for (const [, [cx, cy, h]] of poses) {
      const a = h * Math.PI / 180;
      ctx.moveTo(cx, cy);
      ctx.lineTo(cx + Math.cos(a) * rad * 1.25, cy + Math.sin(a) * rad * 1.25);
    }
    ctx.lineWidth = Math.max(1.5, rad * 0.3);
    ctx.strokeStyle = "#ffffff";
    ctx.stroke();
    // lost robots: a yellow ring and a question mark
    if (lost.length) {
      ctx.beginPath();
      for (const r of lost) { const [cx, cy] = poses.get(r.tag); ctx.moveTo(cx + rad * 1.6, cy); ctx.arc(cx, cy, rad * 1.6, 0, Math.PI * 2); }
      ctx.lineWidth = Math.max(2, rad * 0.35);
      ctx.strokeStyle = "#ffd200";
      ctx.setLineDash([4, 3]);
      ctx.stroke();
      ctx.setLineDash([]);
      if (rad >= 6) {
        ctx.fillStyle = "#ffd200"; ctx.font = `bold ${Math.round(rad * 1.4)}px system-ui, sans-serif`;
        ctx.textAlign = "center"; ctx.textBaseline = "bottom";
        for (const r of lost) { const [cx, cy] = poses.get(r.tag); ctx.fillText("?", cx + rad * 1.6, cy - rad); }
      }
    }
    if (dq.length) {
      ctx.beginPath();
      for (const r of dq) { const [cx, cy] = poses.get(r.tag); ctx.moveTo(cx - rad, cy - rad); ctx.lineTo(cx + rad, cy + rad); ctx.moveTo(cx + rad, cy - rad); ctx.lineTo(cx - rad, cy + rad); }
      ctx.lineWidth = Math.max(2, rad * 0.4); ctx.strokeStyle = "#141414"; ctx.stroke();
    }
    // tags when there is room, each where it overlaps no other tag (below, above, right, left)
    if (rad >= 6 && poses.size <= 300) this.drawLabels(poses, rad);
    if (this.selected != null && poses.has(this.selected)) {
      const [cx, cy] = poses.get(this.selected);
      ctx.beginPath(); ctx.arc(cx, cy, rad + 4, 0, Math.PI * 2);
      ctx.lineWidth = 3; ctx.strokeStyle = "#ffffff"; ctx.stroke();
    }
  }

  // Robot tags on a dark box, placed greedily: the first of four places beside the robot that
  // overlaps no tag already placed and no robot; a tag with no free place is left out.
  drawLabels(poses, rad) {
    const ctx = this.ctx;
    const fs = Math.round(Math.max(10, Math.min(13, rad * 0.9)));
    ctx.font = `600 ${fs}px system-ui, sans-serif`;
    ctx.textAlign = "left"; ctx.textBaseline = "middle";
    const placed = [], bodies = [];
    for (const [, [cx, cy]] of poses) bodies.push([cx - rad, cy - rad, cx + rad, cy + rad]);
    const hits = (b, list) => list.some(o => b[0] < o[2] && b[2] > o[0] && b[1] < o[3] && b[3] > o[1]);
    const boxes = [];
    // the selected robot and robots nearer the top-left first, so the layout is stable
    const order = [...poses.entries()].sort((a, b) => (a[0] === this.selected ? -1 : b[0] === this.selected ? 1 : a[1][1] - b[1][1] || a[1][0] - b[1][0]));
    for (const [tag, [cx, cy]] of order) {
      const text = String(tag), w = ctx.measureText(text).width + 6, h = fs + 4;
      const spots = [[cx - w / 2, cy + rad + 2], [cx - w / 2, cy - rad - 2 - h], [cx + rad + 3, cy - h / 2], [cx - rad - 3 - w, cy - h / 2]];
      for (const [x, y] of spots) {
        const b = [x, y, x + w, y + h];
        if (hits(b, placed)) continue;
        const own = [cx - rad, cy - rad, cx + rad, cy + rad];
        if (hits(b, bodies.filter(o => o[0] !== own[0] || o[1] !== own[1]))) continue;
        placed.push(b); boxes.push([text, x, y, w, h]);
        break;
      }
    }
    ctx.fillStyle = "rgba(12,12,16,0.72)";
    for (const [, x, y, w, h] of boxes) ctx.fillRect(x, y, w, h);
    ctx.fillStyle = "#ffffff";
    for (const [text, x, y, , h] of boxes) ctx.fillText(text, x + 3, y + h / 2 + 0.5);
    this.labels = boxes.map(([text, x, y, w, h]) => ({ text, x, y, w, h }));
  }

  // What is under screen point (sx, sy): {robot: tag} or {thing: key} or null.
  hit(sx, sy, t) {
    const cam = this.camera, s = cam.scale;
    const reach = Math.max(12, s * 0.6);
    let best = null, bd = reach * reach;
    for (const r of this.model.robots.values()) {
      const [x, y] = r.pose(t);
      const dx = cam.ox + (x + 0.5) * s - sx, dy = cam.oy + (y + 0.5) * s - sy, d = dx * dx + dy * dy;
      if (d < bd) { bd = d; best = { robot: r.tag }; }
    }
    if (best) return best;
    for (const [key, th] of [...this.model.things].reverse()) {  // the newest first: it is drawn on top
      const dx = cam.ox + (th.x + 0.5) * s - sx, dy = cam.oy + (th.y + 0.5) * s - sy, d = dx * dx + dy * dy;
      if (d < bd) { bd = d; best = { thing: key }; }
    }
    return best;
  }
}

// A video filmed (examineArea): a play triangle, in the colour of the page's legend.
function videoMark(ctx, cx, cy, r) {
  const q = r * 0.75;
  ctx.moveTo(cx - q * 0.6, cy - q); ctx.lineTo(cx + q, cy); ctx.lineTo(cx - q * 0.6, cy + q); ctx.closePath();
  ctx.fillStyle = "#c77dff";
}
