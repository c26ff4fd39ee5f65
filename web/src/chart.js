// Fault estimates over time: each propeller's loss with its +-2 sigma band,
// and the suspect and fault levels.

import { el, set, text, SIDE_COLOUR } from './svg.js';

const W = 420;
const H = 140;
const PAD = { l: 36, r: 8, t: 10, b: 20 };

export class FaultChart {
  constructor(svg, store) {
    this.svg = svg;
    this.store = store;
    svg.setAttribute('viewBox', `0 0 ${W} ${H}`);
    this.axes = el('g', { class: 'axes' }, svg);
    this.levels = el('g', { class: 'levels' }, svg);
    this.series = {};
    for (const side of ['port', 'starboard']) {
      const band = el('path', { class: 'chart-band', fill: SIDE_COLOUR[side] }, svg);
      const line = el('path', { class: 'chart-line', stroke: SIDE_COLOUR[side], 'data-testid': `fault-line-${side}` }, svg);
      this.series[side] = { band, line };
    }
    this.empty = el('text', { x: W / 2, y: H / 2, 'text-anchor': 'middle', class: 'chart-empty' }, svg);
  }

  render() {
    const v = this.store.vessels.get(this.store.followed);
    const data = v?.faults ?? [];
    const info = this.store.info;
    const pts = data.filter((p) => Number.isFinite(p[1]) || Number.isFinite(p[3]));
    const seed = v?.fault?.model === 'seed_method';
    text(this.empty, seed ? 'GNSS only: no thrust-loss estimate' : pts.length ? '' : 'no fault estimates yet');
    if (seed || pts.length < 2) {
      for (const s of Object.values(this.series)) {
        set(s.band, 'd', 'M0 0');
        set(s.line, 'd', 'M0 0');
      }
      return;
    }
    const t0 = pts[0][0];
    const t1 = Math.max(pts[pts.length - 1][0], t0 + 10);
    let ymax = Math.max(0.2, (info?.fault_loss ?? 0.1) * 1.5);
    for (const p of pts) {
      if (Number.isFinite(p[1])) ymax = Math.max(ymax, p[1] + 2 * (p[2] || 0));
      if (Number.isFinite(p[3])) ymax = Math.max(ymax, p[3] + 2 * (p[4] || 0));
    }
    ymax = Math.min(1, Math.ceil(ymax * 10) / 10);
    const x = (t) => PAD.l + ((t - t0) / (t1 - t0)) * (W - PAD.l - PAD.r);
    const y = (l) => H - PAD.b - (Math.max(0, Math.min(ymax, l)) / ymax) * (H - PAD.t - PAD.b);
    const key = `${t0}:${ymax}:${Math.round(t1 - t0)}`;
    if (key !== this.key) {
      this.key = key;
      while (this.axes.firstChild) this.axes.firstChild.remove();
      while (this.levels.firstChild) this.levels.firstChild.remove();
      let d = '';
      for (let l = 0; l <= ymax + 1e-9; l += ymax > 0.5 ? 0.2 : 0.1) {
        d += `M${PAD.l} ${y(l).toFixed(1)}H${W - PAD.r}`;
        el('text', { x: PAD.l - 4, y: (y(l) + 3).toFixed(1), 'text-anchor': 'end', class: 'tick' }, this.axes).textContent = `${Math.round(l * 100)}%`;
      }
      const span = t1 - t0;
      const step = [10, 30, 60, 120, 300, 600].find((s) => span / s <= 6) ?? 1200;
      for (let t = 0; t <= span; t += step) {
        d += `M${x(t0 + t).toFixed(1)} ${PAD.t}V${H - PAD.b}`;
        el('text', { x: x(t0 + t).toFixed(1), y: H - 6, 'text-anchor': 'middle', class: 'tick' }, this.axes).textContent = `${Math.round(t)} s`;
      }
      el('path', { d, class: 'grid-lines' }, this.axes);
      if (info) {
        el('path', { d: `M${PAD.l} ${y(info.suspect_loss).toFixed(1)}H${W - PAD.r}`, class: 'level suspect' }, this.levels);
        el('path', { d: `M${PAD.l} ${y(info.fault_loss).toFixed(1)}H${W - PAD.r}`, class: 'level fault' }, this.levels);
      }
    }
    const draw = (side, li, si) => {
      let line = '';
      const up = [];
      const down = [];
      let n = 0;
      for (const p of pts) {
        if (!Number.isFinite(p[li])) continue;
        const X = x(p[0]).toFixed(1);
        line += `${n++ ? 'L' : 'M'}${X} ${y(p[li]).toFixed(1)}`;
        const s = Number.isFinite(p[si]) ? p[si] : 0;
        up.push(`${X} ${y(p[li] + 2 * s).toFixed(1)}`);
        down.push(`${X} ${y(p[li] - 2 * s).toFixed(1)}`);
      }
      set(this.series[side].line, 'd', line || 'M0 0');
      set(this.series[side].band, 'd', up.length ? `M${up.join('L')}L${down.reverse().join('L')}Z` : 'M0 0');
    };
    draw('port', 1, 2);
    draw('starboard', 3, 4);
  }
}
