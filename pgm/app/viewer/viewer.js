"use strict";
(function () {
  const DATA = JSON.parse(document.getElementById("pgm-data").textContent);
  const IMAGES = JSON.parse(document.getElementById("pgm-images").textContent);
  const meta = DATA.meta, frames = DATA.frames, layers = DATA.layers;
  const W = (meta.image_size || [640, 480])[0], H = (meta.image_size || [640, 480])[1];
  // drawn at about 900 px whatever the frame size: thumbnails stretch, overlays stay crisp
  const scale = Math.min(3, 900 / Math.max(W, H));
  const canvas = document.getElementById("canvas"), ctx = canvas.getContext("2d");
  canvas.width = Math.round(W * scale); canvas.height = Math.round(H * scale);
  // image coordinates -> canvas: (x - x0) * k; the whole frame, or zoomed on a layer
  let view = {x0: 0, y0: 0, k: scale};
  const X = x => (x - view.x0) * view.k, Y = y => (y - view.y0) * view.k;
  const zoomBox = document.getElementById("zoom");
  const slider = document.getElementById("slider");
  slider.max = String(frames.length - 1);
  const NS = "http://www.w3.org/2000/svg";
  const PALETTE = ["#e6194b", "#3cb44b", "#ffe119", "#4363d8", "#f58231", "#911eb4",
                   "#46f0f0", "#f032e6", "#bcf60c", "#fabebe", "#008080", "#e6beff"];
  const VIRIDIS = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
  const visible = {};
  layers.forEach(l => { visible[l.id] = true; });
  let active = (layers.find(l => l.kind === "message") ||
                layers.find(l => ["particles", "set", "replicas"].includes(l.kind)) ||
                layers[0] || {}).id;
  let current = 0;
  const cache = {};

  document.getElementById("title").textContent =
    (meta.model || "model") + " \u00b7 " + frames.length + " recorded frames";
  if (DATA.run && DATA.run.complete === false)
    document.getElementById("status").textContent =
      "run not complete: " + (DATA.run.stopped || "");

  function viridis(t) {
    t = Math.max(0, Math.min(1, t)) * (VIRIDIS.length - 1);
    const i = Math.min(VIRIDIS.length - 2, Math.floor(t)), f = t - i;
    const c = VIRIDIS[i].map((v, k) => Math.round(v + f * (VIRIDIS[i + 1][k] - v)));
    return "rgb(" + c.join(",") + ")";
  }
  function idColour(id) { return PALETTE[Math.abs(id) % PALETTE.length]; }
  function fmt(v, d) { return (v === null || v === undefined) ? "n/a" :
                        Number(v).toFixed(d === undefined ? 2 : d); }
  function layerById(id) { return layers.find(l => l.id === id); }

  // -- drawing on the image ------------------------------------------------------------
  function cloud(x, w, colour, alpha, opts) {
    if (!x || !x.length) return;
    const wmax = Math.max.apply(null, w.map(v => v || 0)) || 1;
    const order = w.map((v, i) => i).sort((a, b) => (w[a] || 0) - (w[b] || 0));
    for (const i of order) {
      if (x[i][0] === null || x[i][1] === null) continue;
      const t = Math.sqrt((w[i] || 0) / wmax), px = X(x[i][0]), py = Y(x[i][1]);
      const r = 1.5 + 5 * t;
      ctx.globalAlpha = alpha * (0.45 + 0.55 * t);
      if (opts && opts.cross) {
        ctx.strokeStyle = colour; ctx.lineWidth = 1.5;
        ctx.beginPath(); ctx.moveTo(px - r, py - r); ctx.lineTo(px + r, py + r);
        ctx.moveTo(px - r, py + r); ctx.lineTo(px + r, py - r); ctx.stroke();
      } else {
        ctx.fillStyle = (opts && opts.fill) || viridis(t);
        ctx.strokeStyle = colour; ctx.lineWidth = 1;
        ctx.beginPath(); ctx.arc(px, py, r, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
      }
    }
    ctx.globalAlpha = 1;
  }
  function box(b, colour, alpha, dashed, label) {
    if (!b || b.some(v => v === null)) return;
    ctx.globalAlpha = alpha; ctx.strokeStyle = colour; ctx.lineWidth = dashed ? 1 : 2;
    ctx.setLineDash(dashed ? [4, 3] : []);
    ctx.strokeRect(X(b[0]), Y(b[1]), b[2] * view.k, b[3] * view.k);
    ctx.setLineDash([]);
    if (label) {
      ctx.fillStyle = colour; ctx.font = "bold 12px sans-serif";
      ctx.fillText(label, X(b[0]) + 2, Math.max(11, Y(b[1]) - 3));
    }
    ctx.globalAlpha = 1;
  }
  function plus(x, y, colour, size) {
    ctx.strokeStyle = "#fff"; ctx.lineWidth = 4;
    ctx.beginPath(); ctx.moveTo(x - size, y); ctx.lineTo(x + size, y);
    ctx.moveTo(x, y - size); ctx.lineTo(x, y + size); ctx.stroke();
    ctx.strokeStyle = colour; ctx.lineWidth = 2; ctx.stroke();
  }
  function partBox(est, v) {
    const info = meta.variables[v] || {};
    if (!info.box || !est) return null;
    const c = info.box.map(k => est[k]);
    return [c[0] - c[2] / 2, c[1] - c[3] / 2, c[2], c[3]];
  }
  function drawLayer(l, rec, alpha) {
    if (l.kind === "particles") {
      const d = (rec.variables || {})[l.name];
      if (d && l.image) cloud(d.x, d.w, l.colour, alpha);
    } else if (l.kind === "message") {
      const m = (rec.messages || []).find(m => m.src === l.src && m.dst === l.dst &&
                                               (m.factor || null) === (l.factor || null));
      if (m && l.image) cloud(m.x, m.w, l.colour, alpha, {cross: true});
    } else if (l.kind === "set") {
      const s = (rec.sets || {})[l.name];
      if (!s) return;
      cloud(s.x, s.w, l.colour, alpha);
      ctx.globalAlpha = alpha;
      for (const e of s.extracted || []) plus(X(e[0]), Y(e[1]), l.colour, 7);
      for (const t of s.tracks || []) {
        if (t.x === null || t.y === null) continue;
        ctx.strokeStyle = idColour(t.id); ctx.lineWidth = 2;
        ctx.setLineDash(t.coasting ? [3, 3] : []);
        ctx.beginPath(); ctx.arc(X(t.x), Y(t.y), 11, 0, 2 * Math.PI); ctx.stroke();
        ctx.setLineDash([]);
        ctx.fillStyle = idColour(t.id); ctx.font = "bold 11px sans-serif";
        ctx.fillText(String(t.id), X(t.x) + 12, Y(t.y) - 8);
      }
      ctx.globalAlpha = 1;
    } else if (l.kind === "replicas") {
      for (const r of (rec.replicas || {})[l.name] || []) {
        const c = r.id ? idColour(r.id) : "#bbbbbb";
        if (l.image) cloud(r.x, r.w, c, alpha);
      }
    } else if (l.kind === "measurements") {
      for (const m of rec.measurements || []) box(m, "#c8c8c8", alpha, true);
    } else if (l.kind === "estimates") {
      for (const [v, d] of Object.entries(rec.variables || {})) {
        const lv = layerById("particles:" + v);
        box(partBox(d.estimate, v), lv ? lv.colour : l.colour, alpha, true);
      }
    } else if (l.kind === "targets") {
      const t = rec.targets;
      if (!t) return;
      t.boxes.forEach((b, i) => box(b, idColour(t.ids[i]), alpha, false, String(t.ids[i])));
    }
  }
  function layerPoints(l, rec) {
    if (!l || !l.image) return [];
    if (l.kind === "particles") return ((rec.variables || {})[l.name] || {}).x || [];
    if (l.kind === "set") return ((rec.sets || {})[l.name] || {}).x || [];
    if (l.kind === "message") {
      const m = (rec.messages || []).find(m => m.src === l.src && m.dst === l.dst);
      return m ? m.x : [];
    }
    if (l.kind === "replicas")
      return [].concat(...((rec.replicas || {})[l.name] || []).map(r => r.x));
    const t = rec.targets;
    return t ? [].concat(...t.boxes.map(b => [[b[0], b[1]], [b[0] + b[2], b[1] + b[3]]])) : [];
  }
  function zoomed(rec) {
    // around the active layer's points and the reported targets (else every layer's
    // points), with the frame's aspect ratio
    let pts = layerPoints(layerById(active), rec).filter(p => p[0] !== null && p[1] !== null);
    if (pts.length) pts = pts.concat(layerPoints(layerById("targets"), rec));
    else for (const l of layers) pts = pts.concat(layerPoints(l, rec));
    pts = pts.filter(p => p[0] !== null && p[1] !== null);
    if (!pts.length) return {x0: 0, y0: 0, k: scale};
    const xs = pts.map(p => p[0]), ys = pts.map(p => p[1]);
    const cx = (Math.min(...xs) + Math.max(...xs)) / 2, cy = (Math.min(...ys) + Math.max(...ys)) / 2;
    let vw = Math.max(1.6 * (Math.max(...xs) - Math.min(...xs)), 40, W / 8);
    let vh = Math.max(1.6 * (Math.max(...ys) - Math.min(...ys)), 40 * H / W, H / 8);
    if (vw / vh > W / H) vh = vw * H / W; else vw = vh * W / H;
    vw = Math.min(vw, W); vh = Math.min(vh, H);
    const x0 = Math.max(0, Math.min(W - vw, cx - vw / 2));
    const y0 = Math.max(0, Math.min(H - vh, cy - vh / 2));
    return {x0: x0, y0: y0, k: canvas.width / vw};
  }
  function drawLatent(rec) {
    const lat = document.getElementById("latent");
    const l = layerById(active);
    if (!l || l.image !== false || !["particles", "replicas"].includes(l.kind)) {
      lat.style.display = "none"; return;
    }
    let pts = [], ws = [];
    if (l.kind === "particles" && rec.variables && rec.variables[l.name]) {
      pts = rec.variables[l.name].x; ws = rec.variables[l.name].w;
    } else if (l.kind === "replicas") {
      for (const r of (rec.replicas || {})[l.name] || []) { pts = pts.concat(r.x); ws = ws.concat(r.w); }
    }
    lat.style.display = "block";
    const c = lat.getContext("2d");
    c.clearRect(0, 0, lat.width, lat.height);
    c.fillStyle = "#333"; c.font = "11px sans-serif";
    c.fillText(l.name + " (not an image position: its first two state columns)", 6, 13);
    if (!pts.length) return;
    const xs = pts.map(p => p[0]), ys = pts.map(p => p[1]);
    const x0 = Math.min(...xs), x1 = Math.max(...xs) + 1e-9, y0 = Math.min(...ys),
          y1 = Math.max(...ys) + 1e-9, wmax = Math.max(...ws) || 1;
    pts.forEach((p, i) => {
      const t = Math.sqrt((ws[i] || 0) / wmax);
      c.fillStyle = viridis(t);
      c.beginPath();
      c.arc(10 + (p[0] - x0) / (x1 - x0) * (lat.width - 20),
            lat.height - 10 - (p[1] - y0) / (y1 - y0) * (lat.height - 30), 1.5 + 4 * t, 0,
            2 * Math.PI);
      c.fill();
    });
  }

  // -- the factor graph ----------------------------------------------------------------
  function highlight(rec) {
    const l = layerById(active);
    const names = new Set();
    if (l) {
      (rec.t === 0 ? l.factors_first : l.factors).forEach(n => names.add(n));
      (l.variables || []).forEach(n => names.add(n));
    }
    document.querySelectorAll("#graph-svg g[data-node]").forEach(g => {
      g.classList.toggle("active", names.has(g.getAttribute("data-node")));
    });
  }
  document.querySelectorAll("#graph-svg g[data-node]").forEach(g => {
    g.addEventListener("click", () => {
      const name = g.getAttribute("data-node");
      const isFactor = g.classList.contains("factor");
      const pick = isFactor ?
        (layers.find(l => l.kind === "message" && l.factor === name) ||
         layers.find(l => l.kind === "vb" && l.name === name) ||
         layers.find(l => (l.factors || []).includes(name) ||
                          (l.factors_first || []).includes(name))) :
        (layers.find(l => ["particles", "set", "replicas"].includes(l.kind) && l.name === name) ||
         layers.find(l => (l.variables || []).includes(name)));
      if (pick) setActive(pick.id);
    });
  });

  // -- layers list and info --------------------------------------------------------------
  const list = document.getElementById("layers");
  for (const l of layers) {
    const li = document.createElement("li");
    li.dataset.layer = l.id;
    const cb = document.createElement("input");
    cb.type = "checkbox"; cb.checked = true; cb.title = "show on the image";
    cb.addEventListener("click", ev => { ev.stopPropagation(); visible[l.id] = cb.checked;
                                          render(); });
    const sw = document.createElement("span");
    sw.className = "swatch"; sw.style.background = l.colour;
    const tx = document.createElement("span");
    tx.textContent = l.label;
    li.append(cb, sw, tx);
    li.addEventListener("click", () => setActive(l.id));
    list.appendChild(li);
  }
  function setActive(id) { active = id; render(); }

  function infoText(l, rec) {
    if (!l) return "";
    const out = [l.label];
    const facs = rec.t === 0 ? l.factors_first : l.factors;
    if (facs && facs.length) out.push("active factors: " + facs.join(", "));
    const N = (meta.num_particles || {})[l.name];
    if (l.kind === "particles") {
      const d = (rec.variables || {})[l.name];
      if (d) {
        out.push(d.n + " particles" + (N && d.n !== N ? " (" + N + " own + message particles)" : "")
                 + ", " + d.x.length + " shown holding " + fmt(100 * (d.shown_mass || 0), 1)
                 + "% of the weight");
        out.push("ESS " + fmt(d.ess, 1) + (N ? " of " + N : "") +
                 (d.resampled ? ", resampled" : ", not resampled"));
        if (d.own_mass !== null && d.own_mass !== undefined)
          out.push("own mass after fusion " + fmt(d.own_mass, 3));
        if (d.log_evidence !== null && d.log_evidence !== undefined)
          out.push("log evidence increment " + fmt(d.log_evidence, 3));
        if (d.estimate) out.push("estimate [" + d.estimate.map(v => fmt(v, 1)).join(", ") + "]");
      }
    } else if (l.kind === "message") {
      const m = (rec.messages || []).find(m => m.src === l.src && m.dst === l.dst);
      if (m) out.push(m.n + " message particles, " + m.x.length + " shown");
    } else if (l.kind === "set") {
      const s = (rec.sets || {})[l.name];
      if (s) {
        out.push("expected number of targets " + fmt(s.mass, 2) + ", " + s.n + " particles ("
                 + s.x.length + " shown)" + (s.resampled_to ? ", resampled to " + s.resampled_to : ""));
        out.push((s.extracted || []).length + " extracted, " + (s.tracks || []).length + " tracks");
      }
    } else if (l.kind === "replicas") {
      const rs = (rec.replicas || {})[l.name] || [];
      out.push(rs.length + " replicas");
      for (const r of rs)
        out.push("  id " + (r.id || "-") + (r.reported ? "" : " (not reported)") + ": ESS " +
                 fmt(r.ess, 1) + (r.resampled ? ", resampled" : "") + ", existence " +
                 fmt(r.existence, 2));
      if (rec.plate) out.push("births " + rec.plate.births + ", deaths " +
                              (rec.plate.deaths.join(", ") || "none"));
    } else if (l.kind === "vb") {
      const v = (rec.vb || {})[l.name];
      if (v) {
        out.push(v.iterations + " iterations; ELBO " + v.elbo.map(e => fmt(e, 2)).join(" \u2192 "));
        out.push("\u03c3\u0302 = " + v.sigma.map(s => fmt(s, 3)).join(", ") +
                 "  (noise: " + v.noise + ")");
      } else out.push("no VB update this frame");
    } else if (l.kind === "targets" && rec.targets) {
      out.push(rec.targets.ids.length + " reported " + (rec.targets.text || ""));
    } else if (l.kind === "measurements") {
      out.push((rec.measurements || []).length + " measurements");
    }
    if (rec.dropped) out.push("this frame was withheld from the tracker (predicted through)");
    return out.join("\n");
  }

  // -- charts --------------------------------------------------------------------------
  function el(tag, attrs, parent) {
    const e = document.createElementNS(NS, tag);
    for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
    if (parent) parent.appendChild(e);
    return e;
  }
  function chart(id, series, opts) {
    const svg = document.getElementById(id);
    while (svg.firstChild) svg.removeChild(svg.firstChild);
    const w = svg.clientWidth || 420, h = svg.clientHeight || 120;
    svg.setAttribute("viewBox", "0 0 " + w + " " + h);
    const pts = [].concat(...series.map(s => s.points)).filter(p => p[1] !== null);
    if (!pts.length) { el("text", {x: 8, y: 16}, svg).textContent = opts.empty || "no data"; return; }
    let x0 = Math.min(...pts.map(p => p[0])), x1 = Math.max(...pts.map(p => p[0]));
    let y0 = opts.y0 !== undefined ? opts.y0 : Math.min(...pts.map(p => p[1]));
    let y1 = opts.y1 !== undefined ? opts.y1 : Math.max(...pts.map(p => p[1]));
    if (x1 === x0) { x0 -= 1; x1 += 1; }
    if (y1 === y0) { y0 -= 1; y1 += 1; }
    const L = 44, R = 8, T = 8, B = 18;
    const sx = x => L + (x - x0) / (x1 - x0) * (w - L - R);
    const sy = y => h - B - (y - y0) / (y1 - y0) * (h - T - B);
    el("line", {x1: L, y1: h - B, x2: w - R, y2: h - B, stroke: "#999"}, svg);
    el("line", {x1: L, y1: T, x2: L, y2: h - B, stroke: "#999"}, svg);
    el("text", {x: L - 3, y: T + 8, "text-anchor": "end"}, svg).textContent = fmt(y1, opts.yd);
    el("text", {x: L - 3, y: h - B, "text-anchor": "end"}, svg).textContent = fmt(y0, opts.yd);
    el("text", {x: L, y: h - 5}, svg).textContent = (opts.xlabel || "") + " " + fmt(x0, 0);
    el("text", {x: w - R, y: h - 5, "text-anchor": "end"}, svg).textContent = fmt(x1, 0);
    if (opts.vline !== undefined)
      el("line", {x1: sx(opts.vline), y1: T, x2: sx(opts.vline), y2: h - B, stroke: "#ff9800",
                  "stroke-width": 2}, svg);
    let ly = T + 9;
    for (const s of series) {
      const p = s.points.filter(q => q[1] !== null);
      if (!p.length) continue;
      el("polyline", {points: p.map(q => sx(q[0]).toFixed(1) + "," + sy(q[1]).toFixed(1)).join(" "),
                      fill: "none", stroke: s.colour, "stroke-width": 1.6}, svg);
      if (s.dots)
        for (const q of p) el("circle", {cx: sx(q[0]), cy: sy(q[1]), r: 2.5, fill: s.colour}, svg);
      const t = el("text", {x: w - R - 2, y: ly, "text-anchor": "end", fill: s.colour}, svg);
      t.textContent = s.name; ly += 10;
    }
    for (const m of opts.marks || [])
      el("path", {d: "M" + sx(m[0]) + "," + (h - B) + " l-3,6 l6,0 z", fill: "#e53935"}, svg);
  }
  function drawCharts(rec) {
    const fx = frames.map(f => f.frame);
    const ess = [], marks = [];
    for (const l of layers) {
      if (l.kind !== "particles" && l.kind !== "replicas") continue;
      const N = (meta.num_particles || {})[l.name] || 1;
      const pts = frames.map(f => {
        if (l.kind === "particles") {
          const d = (f.variables || {})[l.name];
          if (d && d.resampled) marks.push([f.frame]);
          return [f.frame, d && d.ess !== null ? d.ess / N : null];
        }
        const rs = ((f.replicas || {})[l.name] || []).filter(r => r.ess !== null);
        if (rs.some(r => r.resampled)) marks.push([f.frame]);
        return [f.frame, rs.length ? rs.reduce((a, r) => a + r.ess, 0) / rs.length / N : null];
      });
      ess.push({name: l.name + (l.kind === "replicas" ? " (mean over replicas)" : ""),
                colour: l.colour, points: pts});
    }
    document.getElementById("panel-ess").style.display = ess.length ? "" : "none";
    if (ess.length) chart("chart-ess", ess, {y0: 0, y1: 1, vline: rec.frame, marks: marks,
                                             xlabel: "frame", yd: 1});
    const vbNames = layers.filter(l => l.kind === "vb").map(l => l.name);
    document.getElementById("panel-elbo").style.display = vbNames.length ? "" : "none";
    document.getElementById("panel-sigma").style.display = vbNames.length ? "" : "none";
    if (vbNames.length) {
      chart("chart-elbo", vbNames.map((n, k) => ({
        name: n, colour: ["#7b2cbf", "#1f77b4", "#d62728"][k % 3], dots: true,
        points: (((rec.vb || {})[n] || {}).elbo || []).map((e, i) => [i + 1, e])})),
        {xlabel: "iteration", empty: "no VB update in this frame"});
      const sig = [];
      vbNames.forEach(n => {
        const dims = Math.max(0, ...frames.map(f => (((f.vb || {})[n] || {}).sigma || []).length));
        for (let k = 0; k < dims; k++)
          sig.push({name: "\u03c3\u0302" + (dims > 1 ? "[" + k + "]" : ""),
                    colour: ["#7b2cbf", "#e377c2", "#17becf"][k % 3],
                    points: frames.map(f => [f.frame,
                                             (((f.vb || {})[n] || {}).sigma || [])[k] ?? null])});
      });
      chart("chart-sigma", sig, {vline: rec.frame, xlabel: "frame"});
    }
    const sets = layers.filter(l => l.kind === "set");
    const hasTargets = frames.some(f => f.targets);
    const multi = sets.length || frames.some(f => f.replicas);
    document.getElementById("panel-count").style.display = multi ? "" : "none";
    if (multi) {
      const ser = [];
      for (const l of sets) {
        ser.push({name: "expected", colour: "#d62728",
                  points: frames.map(f => [f.frame, ((f.sets || {})[l.name] || {}).mass ?? null])});
        ser.push({name: "extracted", colour: "#2ca02c",
                  points: frames.map(f => [f.frame,
                                           (((f.sets || {})[l.name] || {}).extracted || []).length])});
      }
      if (hasTargets) ser.push({name: "reported", colour: "#1f77b4",
                                points: frames.map(f => [f.frame,
                                                         f.targets ? f.targets.ids.length : null])});
      chart("chart-count", ser, {y0: 0, vline: rec.frame, xlabel: "frame", yd: 1});
    }
    void fx;
  }

  // -- the video -----------------------------------------------------------------------
  const video = document.getElementById("video");
  const fps = meta.fps || 25;
  function syncVideo(rec) {
    if (!video || !video.paused || video.readyState < 1) return;
    const t = (rec.t + 0.5) / fps;
    if (Math.abs(video.currentTime - t) > 0.5 / fps) {
      try { video.currentTime = Math.min(t, (video.duration || t)); } catch (e) { /* not seekable */ }
    }
  }
  if (video) video.addEventListener("loadedmetadata", () => syncVideo(frames[current]));

  // -- one frame ------------------------------------------------------------------------
  function image(i) {
    if (!IMAGES[i]) return Promise.resolve(null);
    if (!cache[i]) {
      const img = new Image();
      cache[i] = new Promise(res => { img.onload = () => res(img); img.onerror = () => res(null); });
      img.src = IMAGES[i];
    }
    return cache[i];
  }
  function render() {
    const i = current, rec = frames[i];
    document.getElementById("frame-counter").textContent = String(rec.frame);
    document.getElementById("position").textContent = (i + 1) + " of " + frames.length;
    slider.value = String(i);
    document.querySelectorAll("#layers li").forEach(li =>
      li.classList.toggle("active", li.dataset.layer === active));
    highlight(rec);
    document.getElementById("info").textContent = infoText(layerById(active), rec);
    drawCharts(rec);
    drawLatent(rec);
    syncVideo(rec);
    image(i).then(img => {
      if (i !== current) return;
      view = zoomBox && zoomBox.checked ? zoomed(rec) : {x0: 0, y0: 0, k: scale};
      ctx.fillStyle = "#000"; ctx.fillRect(0, 0, canvas.width, canvas.height);
      if (img) {
        const f = img.naturalWidth / W, vw = canvas.width / view.k, vh = canvas.height / view.k;
        ctx.drawImage(img, view.x0 * f, view.y0 * f, vw * f, vh * f, 0, 0, canvas.width,
                      canvas.height);
      }
      for (const l of layers) {
        if (l.id === active || !visible[l.id]) continue;
        drawLayer(l, rec, 0.35);
      }
      const a = layerById(active);
      if (a && visible[a.id]) drawLayer(a, rec, 1);
      if (rec.dropped) {
        ctx.fillStyle = "rgba(0,0,0,.6)"; ctx.fillRect(0, 0, canvas.width, 22);
        ctx.fillStyle = "#ffd54f"; ctx.font = "bold 13px sans-serif";
        ctx.fillText("frame withheld from the tracker", 8, 16);
      }
      document.body.dataset.shown = String(i);
    });
  }
  function go(i) {
    current = Math.max(0, Math.min(frames.length - 1, i));
    render();
  }
  document.getElementById("prev").addEventListener("click", () => go(current - 1));
  document.getElementById("next").addEventListener("click", () => go(current + 1));
  slider.addEventListener("input", () => go(parseInt(slider.value, 10)));
  if (zoomBox) zoomBox.addEventListener("change", () => render());
  document.addEventListener("keydown", ev => {
    if (ev.target === slider) return;  // the slider moves itself and fires "input"
    if (ev.key === "ArrowRight") { go(current + 1); ev.preventDefault(); }
    else if (ev.key === "ArrowLeft") { go(current - 1); ev.preventDefault(); }
    else if (ev.key === "Home") { go(0); ev.preventDefault(); }
    else if (ev.key === "End") { go(frames.length - 1); ev.preventDefault(); }
  });
  window.pgmView = {go: go, get current() { return current; }, frames: frames.length,
                    setActive: setActive};
  go(0);
})();
