// The trend: a capture of every cycle the server streams for the chosen channels (binary
// frames, docs/web.md § "Protocol"), drawn with uPlot (YT) or on a plain canvas (XY).
// A gap (ticks the server could not deliver) is a break in the line and is counted; an
// instruction bit change is a marker on the time axis; a trigger (a level crossed, a bit's
// edge) freezes pre + 1 + post rows around the trigger row; two cursors give Δ; CSV export
// writes the whole capture or the visible range, one row per tick, full float64 precision.

import { Capture } from "./capture.js";

const MAGIC = 0x4d535452; // 'MSTR'
const HEADER_BYTES = 24; // u32 magic, u16 version, u16 nchan, u32 layout, nrows, gaps, reserved
const MAX_CHANNELS = 16;
const MAX_ROWS = 120000; // two minutes at 1 kHz; the oldest rows go first
const MAX_MARKERS = 2000;
const COLORS = [
  "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
  "#bcbd22", "#17becf", "#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd",
];
const $ = (id) => document.getElementById(id);

export class Trend {
  constructor(view, send) {
    this.view = view;
    this.send = send;
    this.channels = []; // asked for
    this.layout = null; // {id, channels} in effect
    this.capture = new Capture([]);
    this.frozen = null; // the triggered capture, shown instead of the live one
    this.follow = true;
    this.range = null; // [min, max] ticks when not following
    this.gaps = 0;
    this.gapTicks = 0;
    this.frames = 0;
    this.ignored = 0; // frames of a layout no longer in effect
    this.markers = [];
    this.cursorA = null;
    this.cursorB = null;
    this.trigger = { state: "idle" };
    this.bitNames = new Set();
    this.periodUs = 0;
    this.renders = 0;
    this.drawn = []; // [newest tick drawn, Date.now()] per render, the latest 5000
    this.arrived = []; // [newest tick of a frame, Date.now()] per frame, the latest 5000
    this.plot = null;
    this.plotted = null; // the data last given to uPlot
    this.pending = false;
    this.wire();
    view.capture = () => this.capture;
    view.rows = () => this.capture.rows();
    view.csv = (which) => this.csvText(which);
  }

  setModel(model) {
    const ctl = model.controller || {};
    this.periodUs = Number(ctl.period_us) || 0;
    this.bitNames = new Set();
    for (const ins of model.instructions || []) for (const b of ins.bits || []) {
      this.bitNames.add(b.includes(".") ? b : `${ins.name}.${b}`);
    }
  }

  // -- channels and layout -------------------------------------------------------------
  setChannels(channels) {
    this.channels = channels.slice(0, MAX_CHANNELS);
    this.showChips();
    this.send(this.channels);
  }

  addChannel(name) {
    name = name.trim();
    if (!name) return;
    const known = (this.view.model && this.view.model.channels) || [];
    if (known.length && !known.includes(name)) {
      this.say(`${name}: not a channel of this controller`);
      return;
    }
    if (this.channels.includes(name)) return;
    if (this.channels.length >= MAX_CHANNELS) {
      this.say(`at most ${MAX_CHANNELS} channels`);
      return;
    }
    this.setChannels([...this.channels, name]);
  }

  removeChannel(name) {
    this.setChannels(this.channels.filter((c) => c !== name));
  }

  showChips() {
    const box = $("channels");
    box.textContent = "";
    this.channels.forEach((name, i) => {
      const chip = document.createElement("span");
      chip.className = "chip";
      chip.style.borderColor = COLORS[i % COLORS.length];
      chip.textContent = name;
      const x = document.createElement("button");
      x.type = "button";
      x.textContent = "×";
      x.title = `remove ${name}`;
      x.addEventListener("click", () => this.removeChannel(name));
      chip.appendChild(x);
      box.appendChild(chip);
    });
    $("channel-count").textContent = `${this.channels.length}/${MAX_CHANNELS}`;
  }

  onLayout(msg) {
    this.layout = { id: msg.id, channels: msg.channels.slice() };
    this.capture = new Capture(this.layout.channels);
    this.frozen = null;
    this.trigger = { state: "idle" };
    this.gaps = 0;
    this.gapTicks = 0;
    this.markers = [];
    this.cursorA = this.cursorB = null;
    this.follow = true;
    this.range = null;
    this.fillSelects();
    this.makePlot();
    this.showCounts();
    this.showTrigger();
  }

  fillSelects() {
    const chans = this.layout ? this.layout.channels : [];
    for (const id of ["xy-x", "xy-y", "trig-channel"]) {
      const sel = $(id);
      const old = sel.value;
      sel.textContent = "";
      for (const c of chans) {
        const opt = document.createElement("option");
        opt.value = opt.textContent = c;
        sel.appendChild(opt);
      }
      if (chans.includes(old)) sel.value = old;
    }
    if (chans.length > 1 && $("xy-y").value === $("xy-x").value) $("xy-y").value = chans[1];
  }

  // -- frames ----------------------------------------------------------------------------
  onFrame(buf) {
    const dv = new DataView(buf);
    if (buf.byteLength < HEADER_BYTES || dv.getUint32(0, true) !== MAGIC) return;
    if (dv.getUint16(4, true) !== 1) return;
    const nchan = dv.getUint16(6, true);
    const layoutId = dv.getUint32(8, true);
    const nrows = dv.getUint32(12, true);
    const gapsBefore = dv.getUint32(16, true);
    const rowBytes = 8 + 8 * nchan;
    if (!this.layout || layoutId !== this.layout.id || nchan !== this.layout.channels.length) {
      this.ignored += 1;
      return;
    }
    if (buf.byteLength < HEADER_BYTES + nrows * rowBytes) return;
    this.frames += 1;
    const cap = this.capture;
    const values = new Array(nchan);
    let off = HEADER_BYTES;
    for (let r = 0; r < nrows; r++) {
      const tick = Number(dv.getBigUint64(off, true));
      for (let c = 0; c < nchan; c++) values[c] = dv.getFloat64(off + 8 + 8 * c, true);
      off += rowBytes;
      const last = cap.length ? cap.ticks[cap.length - 1] : null;
      if (last !== null && tick <= last) {
        // the clock went back (a snapshot restored): a new capture
        this.say(`tick went back from ${last} to ${tick}: capture restarted`);
        this.capture = new Capture(this.layout.channels);
        this.trigger = this.trigger.state === "idle" ? this.trigger : { ...this.trigger, state: "armed", hit: undefined, hitTick: undefined };
        this.onFrameRow(this.capture, tick, values, 0);
        continue;
      }
      let missing = last === null ? 0 : tick - last - 1;
      if (r === 0 && last !== null) missing = Math.max(missing, gapsBefore);
      if (missing > 0) {
        this.gaps += 1;
        this.gapTicks += missing;
      }
      this.onFrameRow(cap, tick, values, missing);
    }
    if (nrows) {
      this.arrived.push([this.capture.ticks[this.capture.length - 1], Date.now()]);
      if (this.arrived.length > 5000) this.arrived.splice(0, 1000);
    }
    if (this.capture.length > MAX_ROWS) {
      const n = this.capture.length - MAX_ROWS + Math.floor(MAX_ROWS / 10);
      this.capture.dropFront(n);
      if (this.trigger.hit !== undefined) this.trigger.hit -= n;
    }
    // a held view (zoomed, panned, stopped, a trigger's capture) is not redrawn per frame
    if (this.follow && !this.frozen) this.schedule();
    else this.showCounts();
  }

  onFrameRow(cap, tick, values, missing) {
    const prevIdx = cap.length - 1;
    cap.push(tick, values, missing);
    // exact bit-change markers for trended instruction bits
    if (prevIdx >= 0) {
      for (let c = 0; c < cap.channels.length; c++) {
        const name = cap.channels[c];
        if (!this.bitNames.has(name)) continue;
        const before = cap.cols[c][prevIdx];
        if (Boolean(before) !== Boolean(values[c])) this.marker(tick, name, Boolean(values[c]), true);
      }
    }
    this.checkTrigger(cap, missing);
  }

  // -- markers ---------------------------------------------------------------------------
  /** A bit change at ``tick``; from a status message (``exact`` false) or a trend row. */
  marker(tick, tag, on, exact = false) {
    if (!exact && this.layout && this.layout.channels.includes(tag)) return; // drawn exactly
    this.markers.push({ tick, tag, on, exact });
    if (this.markers.length > MAX_MARKERS) this.markers.splice(0, MAX_MARKERS / 10);
    this.schedule();
  }

  // -- trigger ---------------------------------------------------------------------------
  arm() {
    if (!this.layout) return;
    const channel = $("trig-channel").value;
    const c = this.layout.channels.indexOf(channel);
    if (c < 0) {
      this.say("choose a trend channel to trigger on");
      return;
    }
    this.trigger = {
      state: "armed",
      channel,
      column: c,
      slope: $("trig-slope").value,
      level: Number($("trig-level").value),
      pre: Math.max(0, Math.floor(Number($("trig-pre").value) || 0)),
      post: Math.max(0, Math.floor(Number($("trig-post").value) || 0)),
    };
    this.frozen = null;
    this.showTrigger();
    this.schedule();
  }

  checkTrigger(cap, missing) {
    const t = this.trigger;
    const i = cap.length - 1;
    if (t.state === "armed" && i >= 1 && missing === 0) {
      const a = cap.cols[t.column][i - 1];
      const b = cap.cols[t.column][i];
      const up = a < t.level && b >= t.level;
      const down = a > t.level && b <= t.level;
      if ((t.slope !== "falling" && up) || (t.slope !== "rising" && down)) {
        t.state = "filling";
        t.hit = i;
        t.hitTick = cap.ticks[i];
        this.showTrigger();
      }
    }
    if (t.state === "filling" && i - t.hit >= t.post) {
      t.state = "triggered";
      this.frozen = cap.slice(t.hit - t.pre, t.hit + t.post + 1);
      t.rows = this.frozen.rows();
      this.follow = false;
      this.range = [this.frozen.ticks[0], this.frozen.ticks[this.frozen.length - 1]];
      this.showTrigger();
      this.schedule();
    }
  }

  showTrigger() {
    const t = this.trigger;
    let text = t.state;
    if (t.state === "armed") text = `armed: ${t.channel} ${t.slope} through ${t.level}`;
    if (t.state === "filling") text = `triggered at tick ${t.hitTick}, filling ${t.post} post`;
    if (t.state === "triggered") {
      text = `captured ${this.frozen.length} rows around tick ${t.hitTick}`;
    }
    $("trig-state").textContent = text;
    $("trig-state").dataset.state = t.state;
    this.view.trigger = t;
  }

  // -- drawing ---------------------------------------------------------------------------
  source() {
    return this.frozen || this.capture;
  }

  schedule() {
    if (this.pending) return;
    this.pending = true;
    requestAnimationFrame(() => {
      this.pending = false;
      this.render();
    });
  }

  windowRows() {
    return Math.max(10, Math.floor(Number($("window-rows").value) || 2000));
  }

  makePlot() {
    const box = $("chart");
    if (this.plot) this.plot.destroy();
    box.textContent = "";
    const chans = this.layout ? this.layout.channels : [];
    const series = [{ label: "tick" }];
    let hasBits = false;
    chans.forEach((name, i) => {
      const bit = this.bitNames.has(name);
      hasBits = hasBits || bit;
      series.push({
        label: name,
        stroke: COLORS[i % COLORS.length],
        width: 1.5,
        scale: bit ? "bit" : "y",
        spanGaps: false,
        points: { show: false },
      });
    });
    const axes = [{ label: "tick" }, { scale: "y" }];
    if (hasBits) axes.push({ scale: "bit", side: 1, grid: { show: false } });
    const opts = {
      width: Math.max(400, box.clientWidth || 900),
      height: 320,
      series,
      axes,
      scales: { x: { time: false }, bit: { range: [-0.1, 1.2] } },
      cursor: { drag: { x: true, y: false, setScale: false } },
      legend: { live: true },
      hooks: {
        setSelect: [(u) => this.onSelect(u)],
        draw: [(u) => this.decorate(u)],
        ready: [(u) => this.wirePlot(u)],
      },
    };
    this.plot = new window.uPlot(opts, [[], ...chans.map(() => [])], box);
  }

  render() {
    const src = this.source();
    const xyMode = $("view-mode").value === "xy";
    let from = 0;
    let to = src.length;
    if (this.follow && !this.frozen) {
      from = Math.max(0, to - this.windowRows());
    } else if (this.range) {
      from = Math.max(0, src.index(this.range[0]) - 1);
      to = Math.min(src.length, src.index(this.range[1] + 1) + 1);
    }
    if (xyMode) this.drawXY(src, from, to);
    else if (this.plot) {
      // at most ~4 points per pixel: beyond that uPlot slows and nothing more shows
      const data = src.plotData(from, to, 4 * Math.max(400, this.plot.width));
      this.plotted = data;
      this.plot.setData(data, false);
      const x = data[0];
      if (x.length) {
        const min = this.follow && !this.frozen ? x[0] : this.range[0];
        const max = this.follow && !this.frozen ? x[x.length - 1] : this.range[1];
        this.plot.setScale("x", { min, max: max > min ? max : min + 1 });
      } else {
        this.plot.redraw();
      }
    }
    this.renders += 1;
    if (src.length) {
      this.drawn.push([src.ticks[src.length - 1], Date.now()]);
      if (this.drawn.length > 5000) this.drawn.splice(0, 1000);
    }
    this.showCounts();
    this.showCursors();
  }

  visibleRange() {
    if (this.plot && $("view-mode").value === "yt") {
      const s = this.plot.scales.x;
      if (s.min !== null && s.min !== undefined) return [s.min, s.max];
    }
    const src = this.source();
    if (!src.length) return [0, 0];
    if (this.range) return this.range;
    const from = Math.max(0, src.length - this.windowRows());
    return [src.ticks[from], src.ticks[src.length - 1]];
  }

  decorate(u) {
    const ctx = u.ctx;
    const { left, top, width, height } = u.bbox;
    const xMin = u.scales.x.min;
    const xMax = u.scales.x.max;
    const inView = (t) => t >= xMin && t <= xMax;
    const px = (t) => u.valToPos(t, "x", true);
    ctx.save();
    ctx.beginPath();
    ctx.rect(left, top, width, height);
    ctx.clip();
    const dpr = window.devicePixelRatio || 1;
    ctx.font = `${10 * dpr}px sans-serif`;
    // gaps: a shaded band between the rows around the missing ticks
    const src = this.source();
    ctx.fillStyle = "rgba(214, 39, 40, 0.18)";
    for (const [i] of src.gapAt) {
      if (i <= 0) continue;
      const a = src.ticks[i - 1];
      const b = src.ticks[i];
      if (b < xMin || a > xMax) continue;
      ctx.fillRect(px(a), top, Math.max(2, px(b) - px(a)), height);
    }
    // instruction bit changes (labels at one pixel stacked, not overprinted)
    const stacked = new Map();
    for (const m of this.markers) {
      if (!inView(m.tick)) continue;
      const x = px(m.tick);
      const row = stacked.get(Math.round(x)) || 0;
      stacked.set(Math.round(x), row + 1);
      ctx.strokeStyle = m.on ? "rgba(44, 160, 44, 0.8)" : "rgba(127, 127, 127, 0.8)";
      ctx.setLineDash(m.exact ? [] : [3 * dpr, 3 * dpr]);
      ctx.beginPath();
      ctx.moveTo(x, top);
      ctx.lineTo(x, top + height);
      ctx.stroke();
      ctx.fillStyle = ctx.strokeStyle;
      ctx.fillText(`${m.tag}${m.on ? "↑" : "↓"}`, x + 2 * dpr, top + (12 + 11 * row) * dpr);
    }
    ctx.setLineDash([]);
    // the trigger row
    const t = this.trigger;
    if (t.hitTick !== undefined && inView(t.hitTick)) {
      ctx.strokeStyle = "#ff7f0e";
      ctx.lineWidth = 2 * dpr;
      ctx.beginPath();
      ctx.moveTo(px(t.hitTick), top);
      ctx.lineTo(px(t.hitTick), top + height);
      ctx.stroke();
    }
    // the two cursors
    for (const [name, tick] of [["A", this.cursorA], ["B", this.cursorB]]) {
      if (tick === null || !inView(tick)) continue;
      ctx.strokeStyle = name === "A" ? "#000" : "#9467bd";
      ctx.lineWidth = 1 * dpr;
      ctx.beginPath();
      ctx.moveTo(px(tick), top);
      ctx.lineTo(px(tick), top + height);
      ctx.stroke();
      ctx.fillStyle = ctx.strokeStyle;
      ctx.fillText(name, px(tick) + 2 * dpr, top + height - 4 * dpr);
    }
    ctx.restore();
  }

  drawXY(src, from, to) {
    const canvas = $("xy");
    const ctx = canvas.getContext("2d");
    const cx = src.channels.indexOf($("xy-x").value);
    const cy = src.channels.indexOf($("xy-y").value);
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    if (cx < 0 || cy < 0 || to <= from) return;
    const xs = src.cols[cx];
    const ys = src.cols[cy];
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    for (let i = from; i < to; i++) {
      x0 = Math.min(x0, xs[i]); x1 = Math.max(x1, xs[i]);
      y0 = Math.min(y0, ys[i]); y1 = Math.max(y1, ys[i]);
    }
    if (x1 === x0) { x0 -= 1; x1 += 1; }
    if (y1 === y0) { y0 -= 1; y1 += 1; }
    const pad = 40;
    const w = canvas.width - 2 * pad;
    const h = canvas.height - 2 * pad;
    const X = (v) => pad + ((v - x0) / (x1 - x0)) * w;
    const Y = (v) => pad + h - ((v - y0) / (y1 - y0)) * h;
    ctx.strokeStyle = "#ccc";
    ctx.strokeRect(pad, pad, w, h);
    ctx.fillStyle = "#333";
    ctx.font = "11px sans-serif";
    ctx.fillText(`${src.channels[cx]}  [${x0.toPrecision(5)} … ${x1.toPrecision(5)}]`, pad, canvas.height - 8);
    ctx.fillText(`${src.channels[cy]}  [${y0.toPrecision(5)} … ${y1.toPrecision(5)}]`, pad, 14);
    ctx.strokeStyle = COLORS[1];
    ctx.beginPath();
    for (let i = from; i < to; i++) {
      if (i === from || src.gapAt.has(i)) ctx.moveTo(X(xs[i]), Y(ys[i]));
      else ctx.lineTo(X(xs[i]), Y(ys[i]));
    }
    ctx.stroke();
  }

  // -- zoom, pan, cursors ----------------------------------------------------------------
  onSelect(u) {
    if (u.select.width < 3) return;
    const min = u.posToVal(u.select.left, "x");
    const max = u.posToVal(u.select.left + u.select.width, "x");
    u.setSelect({ left: 0, top: 0, width: 0, height: 0 }, false);
    this.zoom(min, max);
  }

  zoom(min, max) {
    this.follow = false;
    this.range = [min, max];
    this.schedule();
  }

  pan(direction) {
    const [min, max] = this.visibleRange();
    const step = ((max - min) / 2) * direction;
    this.zoom(min + step, max + step);
  }

  followLive() {
    this.frozen = null;
    if (this.trigger.state === "triggered") this.trigger = { state: "idle" };
    this.follow = true;
    this.range = null;
    this.showTrigger();
    this.schedule();
  }

  wirePlot(u) {
    u.over.addEventListener("click", (ev) => {
      if (u.cursor.left === undefined || u.cursor.left < 0) return;
      const src = this.source();
      if (!src.length) return;
      const x = u.posToVal(u.cursor.left, "x");
      let i = Math.min(src.length - 1, src.index(x));
      if (i > 0 && Math.abs(src.ticks[i - 1] - x) < Math.abs(src.ticks[i] - x)) i -= 1;
      this.setCursor(ev.shiftKey ? "B" : "A", src.ticks[i]);
    });
    u.over.addEventListener("wheel", (ev) => {
      ev.preventDefault();
      const [min, max] = this.visibleRange();
      const at = u.posToVal(u.cursor.left ?? 0, "x");
      const k = ev.deltaY > 0 ? 1.25 : 0.8;
      this.zoom(at - (at - min) * k, at + (max - at) * k);
    }, { passive: false });
  }

  /** Place cursor "A" or "B" on ``tick`` (also a test hook: msView.setCursor). */
  setCursor(which, tick) {
    if (which === "A") this.cursorA = tick;
    else this.cursorB = tick;
    this.schedule();
  }

  valueAt(src, c, tick) {
    const i = src.index(tick);
    return i < src.length && src.ticks[i] === tick ? src.cols[c][i] : null;
  }

  showCursors() {
    const table = $("cursor-table");
    const src = this.source();
    const a = this.cursorA;
    const b = this.cursorB;
    const out = { a, b, channels: {} };
    table.textContent = "";
    if (a === null && b === null) {
      this.view.cursors = out;
      return;
    }
    const head = document.createElement("tr");
    const dt = a !== null && b !== null ? b - a : null;
    const dms = dt !== null && this.periodUs ? (dt * this.periodUs) / 1000 : null;
    out.dticks = dt;
    out.dms = dms;
    for (const text of ["channel", `A @ ${a ?? "–"}`, `B @ ${b ?? "–"}`,
      `Δ (${dt ?? "–"} ticks${dms !== null ? `, ${dms} ms` : ""})`]) {
      const th = document.createElement("th");
      th.textContent = text;
      head.appendChild(th);
    }
    table.appendChild(head);
    src.channels.forEach((name, c) => {
      const va = a === null ? null : this.valueAt(src, c, a);
      const vb = b === null ? null : this.valueAt(src, c, b);
      const d = va !== null && vb !== null ? vb - va : null;
      out.channels[name] = { a: va, b: vb, delta: d };
      const tr = document.createElement("tr");
      tr.dataset.channel = name;
      for (const v of [name, va, vb, d]) {
        const td = document.createElement("td");
        // nine significant digits on screen; msView.cursors and the CSV keep every bit
        td.textContent =
          v === null ? "–" : typeof v === "number" ? String(Number(v.toPrecision(9))) : v;
        tr.appendChild(td);
      }
      table.appendChild(tr);
    });
    this.view.cursors = out;
  }

  showCounts() {
    $("row-count").textContent = String(this.source().length);
    $("run-stop").textContent = this.follow && !this.frozen ? "Stop" : "Run";
    $("gap-count").textContent = String(this.gaps);
    $("gap-ticks").textContent = String(this.gapTicks);
    this.view.gaps = this.gaps;
    this.view.gapTicks = this.gapTicks;
    this.view.frames = this.frames;
    this.view.renders = this.renders;
    this.view.drawn = this.drawn;
    this.view.plotted = this.plotted;
    this.view.arrived = this.arrived;
    this.view.layout = this.layout;
    this.view.markers = this.markers;
  }

  // -- CSV -------------------------------------------------------------------------------
  csvText(which = "all") {
    const src = this.source();
    if (which !== "visible") return src.csv();
    const [min, max] = this.visibleRange();
    return src.csv(src.index(min), src.index(Math.floor(max) + 1));
  }

  download(which) {
    const blob = new Blob([this.csvText(which)], { type: "text/csv" });
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob);
    a.download = `trend-${which}.csv`;
    document.body.appendChild(a);
    a.click();
    a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 1000);
  }

  say(text) {
    const m = $("message");
    if (m) m.textContent = text;
  }

  wire() {
    $("channel-add").addEventListener("click", () => {
      this.addChannel($("channel-input").value);
      $("channel-input").value = "";
    });
    $("channel-input").addEventListener("keydown", (ev) => {
      if (ev.key === "Enter") $("channel-add").click();
    });
    $("view-mode").addEventListener("change", () => {
      const xy = $("view-mode").value === "xy";
      $("xy").hidden = !xy;
      $("chart").hidden = xy;
      for (const el of document.querySelectorAll(".xy-only")) el.hidden = !xy;
      this.schedule();
    });
    for (const el of document.querySelectorAll(".xy-only")) el.hidden = true;
    $("xy-x").addEventListener("change", () => this.schedule());
    $("xy-y").addEventListener("change", () => this.schedule());
    $("run-stop").addEventListener("click", () => {
      if (this.follow && !this.frozen) this.zoom(...this.visibleRange());
      else this.followLive();
    });
    $("zoom-reset").addEventListener("click", () => this.followLive());
    $("pan-left").addEventListener("click", () => this.pan(-1));
    $("pan-right").addEventListener("click", () => this.pan(1));
    $("clear").addEventListener("click", () => {
      if (this.layout) this.onLayout(this.layout);
    });
    $("trig-arm").addEventListener("click", () => this.arm());
    window.addEventListener("resize", () => {
      const width = $("chart").clientWidth;
      if (this.plot && width) this.plot.setSize({ width: Math.max(400, width), height: 320 });
    });
    $("csv-all").addEventListener("click", () => this.download("all"));
    $("csv-visible").addEventListener("click", () => this.download("visible"));
    this.view.setCursor = (which, tick) => this.setCursor(which, tick);
    this.view.zoom = (min, max) => this.zoom(min, max);
    this.view.trendChannels = (channels) => this.setChannels(channels);
  }
}
