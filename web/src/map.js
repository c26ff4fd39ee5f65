// The map: a plain 2D plot in the followed vessel's local frame (north up,
// metres), over Web Mercator tiles when twind's settings name a tile server
// (tiles.js; none by default). Draws the estimated track with its current 2-sigma
// ellipse, the measured fixes, the forecast with its band, and every other
// vessel as a marker with a short trail (placed by latitude/longitude in the
// followed vessel's frame).

import { el, set, text } from './svg.js';
import { toLocal, epochS } from './geo.js';
import { TileLayers } from './tiles.js';

/** Half-width of the forecast band, in position sigmas. */
export const BAND_K = 2;
/** The first seconds of the forecast, whose band is drawn darker. */
export const NEAR_S = 20;

const BOAT = 'M 0 -1.6 L 0.9 1.1 L 0 0.6 L -0.9 1.1 Z';

export class MapView {
  /** `tileBox`, `credit`: the elements for the background tiles and their
   *  attribution. */
  constructor(svg, store, tileBox, credit) {
    this.svg = svg;
    this.store = store;
    this.tiles = new TileLayers(tileBox, credit);
    this.view = null; // {cx, cy, span} in metres: centre east, centre north, width
    this.auto = 'follow'; // 'follow' | 'fleet' | null (the user moved it)
    el('defs', {}, svg);
    this.grid = el('g', { class: 'grid' }, svg);
    this.world = el('g', { class: 'world' }, svg);
    this.trails = el('path', { class: 'trails', 'data-testid': 'fleet-trails' }, this.world);
    this.others = el('g', { class: 'others' }, this.world);
    this.band = el('path', { class: 'band', 'data-testid': 'prediction-band', 'data-points': '0' }, this.world);
    this.nearBand = el('path', { class: 'band near' }, this.world);
    this.forecast = el('path', { class: 'forecast', 'data-testid': 'prediction-line' }, this.world);
    this.ticks = el('path', { class: 'forecast-ticks' }, this.world);
    this.fixes = el('path', { class: 'fixes', 'data-testid': 'measured-fixes', 'data-points': '0' }, this.world);
    this.track = el('path', { class: 'track', 'data-testid': 'estimated-track', 'data-points': '0' }, this.world);
    this.ellipse = el('ellipse', { class: 'ellipse' }, this.world);
    this.boat = el('path', { class: 'boat', d: BOAT }, this.world);
    this.label = el('text', { class: 'boat-label' }, this.world);
    this.markers = new Map();
    this.scaleText = el('text', { class: 'scale-text', x: 12, y: 20 }, svg);
    this.bindInput();
  }

  bindInput() {
    const svg = this.svg;
    svg.addEventListener(
      'wheel',
      (e) => {
        if (!this.view) return;
        e.preventDefault();
        const k = Math.exp(e.deltaY * 0.0015);
        const p = this.toWorld(e.offsetX, e.offsetY);
        this.view.cx = p.e + (this.view.cx - p.e) * k;
        this.view.cy = p.n + (this.view.cy - p.n) * k;
        this.view.span = Math.min(1e6, Math.max(5, this.view.span * k));
        this.auto = null;
        this.store.dirty.add('map');
      },
      { passive: false },
    );
    let drag = null;
    svg.addEventListener('pointerdown', (e) => {
      if (!this.view) return;
      drag = { x: e.clientX, y: e.clientY, cx: this.view.cx, cy: this.view.cy };
      svg.setPointerCapture(e.pointerId);
    });
    svg.addEventListener('pointermove', (e) => {
      if (!drag) return;
      const m = this.view.span / svg.clientWidth;
      this.view.cx = drag.cx - (e.clientX - drag.x) * m;
      this.view.cy = drag.cy + (e.clientY - drag.y) * m;
      this.auto = null;
      this.store.dirty.add('map');
    });
    svg.addEventListener('pointerup', () => {
      drag = null;
    });
  }

  toWorld(px, py) {
    const w = this.svg.clientWidth;
    const h = this.svg.clientHeight;
    const m = this.view.span / w;
    return { e: this.view.cx + (px - w / 2) * m, n: this.view.cy - (py - h / 2) * m };
  }

  /** Where every vessel is, in the followed vessel's frame. */
  positions(frame) {
    const out = [];
    for (const v of this.store.vessels.values()) {
      if (!v.state) continue;
      const p = frame ? toLocal(frame, v.state.lat_deg, v.state.lon_deg) : { n: v.state.north_m, e: v.state.east_m };
      out.push({ v, p });
    }
    return out;
  }

  fit(points) {
    let minE = Infinity;
    let maxE = -Infinity;
    let minN = Infinity;
    let maxN = -Infinity;
    for (const [e, n] of points) {
      if (!Number.isFinite(e) || !Number.isFinite(n)) continue;
      minE = Math.min(minE, e);
      maxE = Math.max(maxE, e);
      minN = Math.min(minN, n);
      maxN = Math.max(maxN, n);
    }
    if (!Number.isFinite(minE)) return;
    const w = this.svg.clientWidth || 1;
    const h = this.svg.clientHeight || 1;
    const span = Math.max(40, (maxE - minE) * 1.15, (maxN - minN) * 1.15 * (w / h));
    this.view = { cx: (minE + maxE) / 2, cy: (minN + maxN) / 2, span };
  }

  render() {
    const store = this.store;
    const v = store.vessels.get(store.followed);
    const frame = v?.frame ?? null;
    const all = this.positions(frame);
    const pred = v?.forecastCurrent(store.info) ? v.prediction : null;
    set(this.band, 'data-stale', v?.prediction && !pred ? 'yes' : 'no');
    const horizonS = 120;
    if (this.auto === 'follow' && v?.state) {
      const last = v.track[v.track.length - 1]?.[0] ?? 0;
      const pts = v.track.filter((p) => p[0] > last - horizonS).map((p) => [p[2], p[1]]);
      pts.push([v.state.east_m, v.state.north_m]);
      if (pred) for (const q of pred.points) pts.push([q.east_m, q.north_m]);
      this.fit(pts);
    } else if (this.auto === 'fleet' || !this.view) {
      this.fit(all.map(({ p }) => [p.e, p.n]));
    }
    if (!this.view) {
      this.tiles.render(store.info?.tiles, null, null, 0, 0);
      return;
    }
    const w = this.svg.clientWidth || 1;
    const h = this.svg.clientHeight || 1;
    const s = w / this.view.span; // px per metre
    this.tiles.render(store.info?.tiles, frame, this.view, w, h);
    // World (east, north) -> screen: x = (e - cx) s + w/2, y = -(n - cy) s + h/2.
    set(this.world, 'transform', `translate(${(w / 2 - this.view.cx * s).toFixed(2)} ${(h / 2 + this.view.cy * s).toFixed(2)}) scale(${s.toFixed(5)} ${(-s).toFixed(5)})`);
    this.drawGrid(w, h, s);
    const px = 1 / s; // one screen pixel in metres

    // Other vessels.
    const seen = new Set();
    let trails = '';
    for (const { v: o, p } of all) {
      seen.add(o.id);
      if (o.id === store.followed) continue;
      let m = this.markers.get(o.id);
      if (!m) {
        m = el('g', { class: 'other', 'data-vessel': o.id }, this.others);
        el('path', { d: BOAT }, m);
        m.addEventListener('click', () => this.onPick?.(o.id));
        this.markers.set(o.id, m);
      }
      const hdg = o.state.heading_rad ?? o.state.cog_rad;
      set(m, 'transform', `translate(${p.e.toFixed(2)} ${p.n.toFixed(2)}) scale(${(5 * px).toFixed(4)}) rotate(${(-(hdg * 180) / Math.PI).toFixed(1)})`);
      set(m, 'data-status', o.fault?.status ?? 'none');
      if (o.frame && o.track.length > 1 && frame) {
        // The last two minutes, shifted into this frame.
        const d = toLocal(frame, o.frame.lat0, o.frame.lon0);
        const tEnd = o.track[o.track.length - 1][0];
        let first = true;
        for (const q of o.track) {
          if (q[0] < tEnd - 120) continue;
          trails += `${first ? 'M' : 'L'}${(q[2] + d.e).toFixed(1)} ${(q[1] + d.n).toFixed(1)}`;
          first = false;
        }
      }
    }
    for (const [id, m] of this.markers) {
      if (!seen.has(id) || id === store.followed) {
        m.remove();
        this.markers.delete(id);
      }
    }
    set(this.trails, 'd', trails || 'M0 0');

    // The followed vessel.
    if (!v?.state) {
      set(this.track, 'd', 'M0 0');
      set(this.band, 'd', 'M0 0');
      set(this.band, 'data-points', 0);
      return;
    }
    let d = '';
    v.track.forEach((q, i) => {
      d += `${i ? 'L' : 'M'}${q[2].toFixed(2)} ${q[1].toFixed(2)}`;
    });
    const st = v.state;
    d += `L${st.east_m.toFixed(2)} ${st.north_m.toFixed(2)}`;
    set(this.track, 'd', d);
    set(this.track, 'data-points', v.track.length + 1);

    let fx = '';
    for (const q of v.fixes) {
      const p = toLocal(v.frame, q[1], q[2]);
      fx += `M${p.e.toFixed(2)} ${p.n.toFixed(2)}h0`;
    }
    set(this.fixes, 'd', fx || 'M0 0');
    set(this.fixes, 'data-points', v.fixes.length);

    // 2-sigma ellipse of the current position (axes north/east).
    set(this.ellipse, 'cx', st.east_m.toFixed(2));
    set(this.ellipse, 'cy', st.north_m.toFixed(2));
    set(this.ellipse, 'rx', Math.max(BAND_K * st.sigma.east_m, px).toFixed(3));
    set(this.ellipse, 'ry', Math.max(BAND_K * st.sigma.north_m, px).toFixed(3));
    const hdg = st.heading_rad ?? st.cog_rad;
    set(this.boat, 'transform', `translate(${st.east_m.toFixed(2)} ${st.north_m.toFixed(2)}) scale(${(7 * px).toFixed(4)}) rotate(${(-(hdg * 180) / Math.PI).toFixed(1)})`);
    set(this.boat, 'data-status', v.fault?.status ?? 'none');
    set(this.label, 'transform', `translate(${(st.east_m + 10 * px).toFixed(2)} ${(st.north_m + 10 * px).toFixed(2)}) scale(${px.toFixed(5)} ${(-px).toFixed(5)})`);
    text(this.label, v.id);

    // Forecast: centre line; the band is the union of the +-BAND_K sigma
    // discs around every point (one path, nonzero fill: overlaps do not
    // darken, and a band wider than the turn's radius stays a true union);
    // dots every 10 s. The first NEAR_S seconds are drawn darker: far ahead
    // the band can be hundreds of metres wide and would hide the rest.
    if (pred && pred.points.length > 1) {
      let line = `M${st.east_m.toFixed(2)} ${st.north_m.toFixed(2)}`;
      let band = '';
      let near = '';
      const t0 = epochS(pred.start);
      for (const q of pred.points) {
        const r = Math.max(BAND_K * q.position_sigma_m, 0.5 * px);
        const x = q.east_m;
        const y = q.north_m;
        const disc = `M${(x - r).toFixed(2)} ${y.toFixed(2)}a${r.toFixed(2)} ${r.toFixed(2)} 0 1 0 ${(2 * r).toFixed(2)} 0a${r.toFixed(2)} ${r.toFixed(2)} 0 1 0 ${(-2 * r).toFixed(2)} 0`;
        band += disc;
        if (epochS(q.time) - t0 <= NEAR_S) near += disc;
        line += `L${x.toFixed(2)} ${y.toFixed(2)}`;
      }
      set(this.nearBand, 'd', near || 'M0 0');
      set(this.band, 'd', band);
      set(this.band, 'data-points', pred.points.length);
      set(this.band, 'data-vessel', v.id);
      set(this.band, 'data-sigma-end', pred.points[pred.points.length - 1].position_sigma_m);
      set(this.forecast, 'd', line);
      let ticks = '';
      const step = pred.step_s || 1;
      const every = Math.max(1, Math.round(10 / step));
      for (let i = every - 1; i < pred.points.length; i += every) {
        const q = pred.points[i];
        ticks += `M${q.east_m.toFixed(2)} ${q.north_m.toFixed(2)}h0`;
      }
      set(this.ticks, 'd', ticks || 'M0 0');
    } else {
      set(this.band, 'd', 'M0 0');
      set(this.nearBand, 'd', 'M0 0');
      set(this.band, 'data-points', 0);
      set(this.band, 'data-vessel', '');
      set(this.forecast, 'd', 'M0 0');
    }
  }

  drawGrid(w, h, s) {
    const spanM = w / s;
    const raw = spanM / 8;
    const mag = 10 ** Math.floor(Math.log10(raw));
    const step = [1, 2, 5, 10].map((k) => k * mag).find((x) => x >= raw) ?? 10 * mag;
    const key = `${w}x${h}:${this.view.cx.toFixed(1)}:${this.view.cy.toFixed(1)}:${s.toFixed(4)}`;
    if (key === this.gridKey) return;
    this.gridKey = key;
    const g = this.grid;
    while (g.firstChild) g.firstChild.remove();
    const tl = this.toWorld(0, 0);
    const br = this.toWorld(w, h);
    let d = '';
    for (let e = Math.ceil(tl.e / step) * step; e <= br.e; e += step) {
      const x = (e - this.view.cx) * s + w / 2;
      d += `M${x.toFixed(1)} 0V${h}`;
      el('text', { x: (x + 3).toFixed(1), y: h - 6, class: 'grid-label' }, g).textContent = `${Math.round(e)}`;
    }
    for (let n = Math.ceil(br.n / step) * step; n <= tl.n; n += step) {
      const y = -(n - this.view.cy) * s + h / 2;
      d += `M0 ${y.toFixed(1)}H${w}`;
      el('text', { x: 4, y: (y - 3).toFixed(1), class: 'grid-label' }, g).textContent = `${Math.round(n)}`;
    }
    el('path', { d, class: 'grid-lines' }, g).parentNode.insertBefore(g.lastChild, g.firstChild);
    // North arrow.
    const na = el('g', { class: 'north', transform: `translate(${w - 28} 46)` }, g);
    el('path', { d: 'M0 -18 L7 6 L0 1 L-7 6 Z' }, na);
    el('text', { x: 0, y: 20, 'text-anchor': 'middle' }, na).textContent = 'N';
    text(this.scaleText, `grid ${step} m · east → · north ↑ · band ±${BAND_K}σ`);
  }
}

