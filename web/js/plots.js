// Small line plots on a 2D canvas (no library): several series over a shared x (time in s), optional log scale,
// dashed reference series, and a cursor. Long series are reduced to their min/max per pixel column.

export class LinePlot {
  constructor(canvas, { title, yLabel = '', log = false, series }) {
    this.canvas = canvas;
    this.title = title;
    this.yLabel = yLabel;
    this.log = log;
    this.series = series; // [{ label, color, dashed?, width? }]
  }

  // x: Float64Array/Array of times; ys: one array per series (null/NaN: gap); cursor: x of a vertical line or null.
  draw(x, ys, cursor = null) {
    const c = this.canvas;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(50, Math.round(c.clientWidth * dpr));
    const h = Math.max(50, Math.round(c.clientHeight * dpr));
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    const g = c.getContext('2d');
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    const W = w / dpr, H = h / dpr;
    g.clearRect(0, 0, W, H);
    g.font = '11px system-ui, sans-serif';
    const left = 44, right = 8, top = 18, bottom = 18;
    const pw = W - left - right, ph = H - top - bottom;

    const n = x.length;
    let x0 = n ? x[0] : 0, x1 = n ? x[n - 1] : 1;
    if (x1 <= x0) x1 = x0 + 1;
    const tf = (v) => (this.log ? (v > 0 ? Math.log10(v) : NaN) : v);
    let y0 = Infinity, y1 = -Infinity;
    for (const y of ys) {
      if (!y) continue;
      for (let i = 0; i < y.length; ++i) {
        const v = tf(y[i]);
        if (v === null || !Number.isFinite(v)) continue;
        if (v < y0) y0 = v;
        if (v > y1) y1 = v;
      }
    }
    if (!Number.isFinite(y0)) { y0 = this.log ? -1 : 0; y1 = this.log ? 1 : 1; }
    if (!this.log) y0 = Math.min(0, y0);
    if (y1 - y0 < 1e-9) y1 = y0 + 1;
    const pad = 0.05 * (y1 - y0);
    y1 += pad;
    if (this.log) y0 -= pad;
    const X = (v) => left + ((v - x0) / (x1 - x0)) * pw;
    const Y = (v) => top + (1 - (tf(v) - y0) / (y1 - y0)) * ph;

    // Frame, ticks, labels.
    g.strokeStyle = '#31353b';
    g.lineWidth = 1;
    g.strokeRect(left + 0.5, top + 0.5, pw, ph);
    g.fillStyle = '#8b9097';
    g.textBaseline = 'middle';
    g.textAlign = 'right';
    for (let k = 0; k <= 4; ++k) {
      const v = y0 + ((y1 - y0) * k) / 4;
      const yy = top + (1 - k / 4) * ph;
      const label = this.log ? fmt(Math.pow(10, v)) : fmt(v);
      g.fillText(label, left - 4, yy);
      g.strokeStyle = '#25282d';
      g.beginPath(); g.moveTo(left + 1, yy + 0.5); g.lineTo(left + pw, yy + 0.5); g.stroke();
    }
    g.textAlign = 'center';
    g.textBaseline = 'top';
    g.fillText(`${fmt(x0)} s`, left + 14, top + ph + 3);
    g.fillText(`${fmt(x1)} s`, left + pw - 14, top + ph + 3);
    g.textAlign = 'left';
    g.textBaseline = 'top';
    g.fillStyle = '#d8dadd';
    g.fillText(this.title + (this.log ? ' (log)' : ''), left, 2);

    // Legend.
    let lx = left + g.measureText(this.title + (this.log ? ' (log)' : '')).width + 14;
    for (const s of this.series) {
      if (s.legend === false) continue;
      g.fillStyle = s.color;
      g.fillRect(lx, 6, 10, 3);
      g.fillStyle = '#8b9097';
      g.fillText(s.label, lx + 13, 2);
      lx += 13 + g.measureText(s.label).width + 10;
    }

    // Series, reduced to min/max per pixel column.
    g.save();
    g.beginPath(); g.rect(left, top, pw, ph); g.clip();
    this.series.forEach((s, k) => {
      const y = ys[k];
      if (!y || !n) return;
      g.strokeStyle = s.color;
      g.lineWidth = s.width || 1.2;
      g.setLineDash(s.dashed ? [4, 3] : []);
      g.beginPath();
      let pen = false, col = -1, lo = 0, hi = 0, last = 0;
      const flush = () => {
        if (col < 0) return;
        if (!pen) { g.moveTo(col, lo); pen = true; } else g.lineTo(col, lo);
        if (hi !== lo) g.lineTo(col, hi);
        g.lineTo(col, last);
      };
      for (let i = 0; i < n; ++i) {
        const v = y[i];
        const yy = v === null || v === undefined ? NaN : Y(v);
        if (!Number.isFinite(yy)) { flush(); col = -1; pen = false; continue; }
        const cx = Math.round(X(x[i]));
        if (cx !== col) { flush(); col = cx; lo = hi = last = yy; }
        else { lo = Math.min(lo, yy); hi = Math.max(hi, yy); last = yy; }
      }
      flush();
      g.stroke();
    });
    g.setLineDash([]);
    if (cursor !== null && Number.isFinite(cursor)) {
      g.strokeStyle = '#ffffff80';
      g.beginPath(); g.moveTo(X(cursor) + 0.5, top); g.lineTo(X(cursor) + 0.5, top + ph); g.stroke();
    }
    g.restore();
  }
}

function fmt(v) {
  const a = Math.abs(v);
  if (a !== 0 && (a < 0.01 || a >= 1e5)) return v.toExponential(1);
  if (a >= 100) return v.toFixed(0);
  if (a >= 10) return v.toFixed(1);
  return v.toFixed(2);
}
