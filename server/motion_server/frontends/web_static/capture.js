// One capture of the trend: the rows the server streamed (one per scan cycle), where the
// gaps are, and what is drawn (with breaks, or as a min/max envelope) and exported (CSV).
// No DOM here: trend.js draws it, tests read it through msView.capture().

/** Rows of one capture: ticks, one column per channel, and where gaps precede a row. */
export class Capture {
  constructor(channels) {
    this.channels = channels.slice();
    this.ticks = [];
    this.cols = channels.map(() => []);
    this.gapAt = new Map(); // row index -> ticks missing just before it
  }

  get length() {
    return this.ticks.length;
  }

  push(tick, values, missing) {
    if (missing > 0) this.gapAt.set(this.ticks.length, missing);
    this.ticks.push(tick);
    for (let c = 0; c < this.cols.length; c++) this.cols[c].push(values[c]);
  }

  /** Drop the oldest ``n`` rows (a full capture), shifting the gap indices. */
  dropFront(n) {
    this.ticks.splice(0, n);
    for (const col of this.cols) col.splice(0, n);
    const gaps = new Map();
    for (const [i, m] of this.gapAt) if (i >= n) gaps.set(i - n, m);
    this.gapAt = gaps;
  }

  /** Rows ``[from, to)`` as a new capture (its gaps kept). */
  slice(from, to) {
    const out = new Capture(this.channels);
    from = Math.max(0, from);
    to = Math.min(this.length, to);
    out.ticks = this.ticks.slice(from, to);
    out.cols = this.cols.map((col) => col.slice(from, to));
    for (const [i, m] of this.gapAt) if (i > from && i < to) out.gapAt.set(i - from, m);
    return out;
  }

  /** First row index whose tick is ≥ ``tick``. */
  index(tick) {
    let lo = 0;
    let hi = this.ticks.length;
    while (lo < hi) {
      const mid = (lo + hi) >> 1;
      if (this.ticks[mid] < tick) lo = mid + 1;
      else hi = mid;
    }
    return lo;
  }

  rows(from = 0, to = this.length) {
    const out = [];
    for (let i = from; i < to; i++) out.push([this.ticks[i], ...this.cols.map((c) => c[i])]);
    return out;
  }

  /** uPlot data: x = tick, one array per channel, a null row at every gap (a break).
   * More than ``maxRows`` rows are drawn as an envelope: per bucket of rows, each
   * channel's minimum and maximum in the order they came (so no peak is lost), at the
   * bucket's first and last tick; a bucket holding a gap starts with the break. */
  plotData(from = 0, to = this.length, maxRows = Infinity) {
    if (to - from > maxRows) return this.envelope(from, to, maxRows);
    const x = [];
    const ys = this.cols.map(() => []);
    for (let i = from; i < to; i++) {
      if (i > from && this.gapAt.has(i)) {
        x.push((this.ticks[i - 1] + this.ticks[i]) / 2);
        for (const y of ys) y.push(null);
      }
      x.push(this.ticks[i]);
      for (let c = 0; c < ys.length; c++) ys[c].push(this.cols[c][i]);
    }
    return [x, ...ys];
  }

  envelope(from, to, maxRows) {
    const per = Math.ceil((to - from) / Math.max(1, Math.floor(maxRows / 2)));
    const gaps = [...this.gapAt.keys()].filter((g) => g > from && g < to).sort((a, b) => a - b);
    let g = 0;
    const x = [];
    const ys = this.cols.map(() => []);
    for (let b = from; b < to; b += per) {
      const e = Math.min(to, b + per);
      let broken = false;
      while (g < gaps.length && gaps[g] < e) {
        broken = true;
        g += 1;
      }
      if (broken && x.length) {
        x.push(this.ticks[b] - 0.5);
        for (const y of ys) y.push(null);
      }
      x.push(this.ticks[b]);
      if (e - 1 > b) x.push(this.ticks[e - 1]);
      for (let c = 0; c < ys.length; c++) {
        const col = this.cols[c];
        let lo = b;
        let hi = b;
        for (let i = b + 1; i < e; i++) {
          if (col[i] < col[lo]) lo = i;
          if (col[i] > col[hi]) hi = i;
        }
        if (e - 1 > b) ys[c].push(col[Math.min(lo, hi)], col[Math.max(lo, hi)]);
        else ys[c].push(col[b]);
      }
    }
    return [x, ...ys];
  }

  csv(from = 0, to = this.length) {
    const lines = [["tick", ...this.channels].join(",")];
    for (let i = from; i < to; i++) {
      const row = [String(this.ticks[i])];
      for (const col of this.cols) row.push(String(col[i]));
      lines.push(row.join(","));
    }
    return lines.join("\n") + "\n";
  }
}
