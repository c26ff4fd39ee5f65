// The chart's optional background: Web Mercator tiles (the z/x/y scheme of
// OpenStreetMap and OpenSeaMap) under the map's track, from the URL
// templates in twind's settings (`[web] tile_url`, `tile_overlay_url`,
// `tile_attribution`, `tile_max_zoom`; the page reads them from the `hello`
// event). Without them nothing is drawn here and nothing is requested: the
// page stays a tile-less plot that works offline.
//
// The map is drawn in the followed vessel's local frame, linear in latitude
// and longitude (geo.js), so each tile's latitude/longitude box is an
// axis-aligned rectangle on screen, placed from its two corners. Within one
// tile Web Mercator's stretch in latitude is far below a pixel at the zoom
// levels used for a vessel's surroundings.

import { toLocal } from './geo.js';

/** Tile size, px. */
export const TILE_PX = 256;
/** The equator's length on Web Mercator's sphere, m. */
const EQUATOR_M = 2 * Math.PI * 6378137;
/** Web Mercator's latitude limit, degrees. */
const MAX_LAT_DEG = 85.0511287798;
/** More tiles than this per layer and the view is not tiled (a bad zoom). */
const MAX_TILES = 400;
const DEG = Math.PI / 180;

/** Tile column holding a longitude at zoom z (not wrapped). */
export function tileX(lonDeg, z) {
  return Math.floor(((lonDeg + 180) / 360) * 2 ** z);
}

/** Tile row holding a latitude at zoom z (clamped to the map). */
export function tileY(latDeg, z) {
  const lat = Math.max(-MAX_LAT_DEG, Math.min(MAX_LAT_DEG, latDeg)) * DEG;
  const y = ((1 - Math.log(Math.tan(lat) + 1 / Math.cos(lat)) / Math.PI) / 2) * 2 ** z;
  return Math.min(2 ** z - 1, Math.max(0, Math.floor(y)));
}

/** The north-west corner of tile (x, y) at zoom z, degrees. */
export function tileCorner(x, y, z) {
  const n = 2 ** z;
  return { lat: Math.atan(Math.sinh(Math.PI * (1 - (2 * y) / n))) / DEG, lon: (x / n) * 360 - 180 };
}

/** The zoom whose tile pixels are closest to `metresPerPx` at `latDeg`. */
export function zoomFor(metresPerPx, latDeg, maxZoom) {
  const z = Math.round(Math.log2((EQUATOR_M * Math.cos(latDeg * DEG)) / (TILE_PX * metresPerPx)));
  return Math.max(0, Math.min(maxZoom, Number.isFinite(z) ? z : 0));
}

/** A template with z, x and y filled in. */
export function tileUrl(template, z, x, y) {
  return template.replaceAll('{z}', z).replaceAll('{x}', x).replaceAll('{y}', y);
}

export class TileLayers {
  /** `box`: the element under the map's SVG; `credit`: the attribution's. */
  constructor(box, credit) {
    this.box = box;
    this.credit = credit;
    this.config = null;
    this.layers = []; // {name, template, div, imgs: Map key -> img}
    this.key = '';
  }

  configure(tiles) {
    if (tiles === this.config) return;
    this.config = tiles;
    this.box.replaceChildren();
    this.layers = [];
    this.key = '';
    const on = Boolean(tiles && (tiles.url || tiles.overlay_url));
    this.box.hidden = !on;
    this.credit.hidden = !on;
    this.credit.textContent = on ? tiles.attribution : '';
    if (!on) return;
    for (const [name, template] of [
      ['base', tiles.url],
      ['overlay', tiles.overlay_url],
    ]) {
      if (!template) continue;
      const div = document.createElement('div');
      div.className = `tile-layer ${name}`;
      div.dataset.layer = name;
      this.box.appendChild(div);
      this.layers.push({ name, template, div, imgs: new Map() });
    }
  }

  /** Draws the tiles for the view: `frame` the followed vessel's, `view`
   *  {cx, cy, span} metres, `w`×`h` px. */
  render(tiles, frame, view, w, h) {
    this.configure(tiles);
    if (!this.layers.length) return;
    if (!frame || !view) {
      for (const l of this.layers) this.place(l, new Map());
      return;
    }
    const s = w / view.span; // px per metre
    const key = `${w}x${h}:${view.cx}:${view.cy}:${view.span}:${frame.lat0}:${frame.lon0}`;
    if (key === this.key) return;
    this.key = key;
    // The view's corners in latitude/longitude (the frame is linear in both).
    const latOf = (n) => frame.lat0 + n / frame.rm / DEG;
    const lonOf = (e) => frame.lon0 + e / frame.rp / DEG;
    const west = lonOf(view.cx - w / 2 / s);
    const east = lonOf(view.cx + w / 2 / s);
    const north = latOf(view.cy + h / 2 / s);
    const south = latOf(view.cy - h / 2 / s);
    const z = zoomFor(1 / s, latOf(view.cy), this.config.max_zoom ?? 19);
    this.box.dataset.zoom = z;
    const [x0, x1, y0, y1] = [tileX(west, z), tileX(east, z), tileY(north, z), tileY(south, z)];
    const wanted = new Map();
    if ((x1 - x0 + 1) * (y1 - y0 + 1) <= MAX_TILES) {
      const n = 2 ** z;
      const screen = (lat, lon) => {
        const p = toLocal(frame, lat, lon);
        return { x: (p.e - view.cx) * s + w / 2, y: -(p.n - view.cy) * s + h / 2 };
      };
      for (let x = x0; x <= x1; x++) {
        for (let y = y0; y <= y1; y++) {
          const nw = tileCorner(x, y, z);
          const se = tileCorner(x + 1, y + 1, z);
          const a = screen(nw.lat, nw.lon);
          const b = screen(se.lat, se.lon);
          // Whole pixels on both edges: no seams between neighbours.
          const box = { left: Math.round(a.x), top: Math.round(a.y), right: Math.round(b.x), bottom: Math.round(b.y) };
          wanted.set(`${z}/${((x % n) + n) % n}/${y}`, box);
        }
      }
    }
    for (const l of this.layers) this.place(l, wanted);
  }

  place(layer, wanted) {
    for (const [k, img] of layer.imgs) {
      if (!wanted.has(k)) {
        img.remove();
        layer.imgs.delete(k);
      }
    }
    for (const [k, box] of wanted) {
      let img = layer.imgs.get(k);
      if (!img) {
        const [z, x, y] = k.split('/');
        img = document.createElement('img');
        img.alt = '';
        img.draggable = false;
        img.decoding = 'async';
        // The page itself sends no referrer; tile servers ask for the
        // page's origin (OpenStreetMap's tile usage policy).
        img.referrerPolicy = 'strict-origin-when-cross-origin';
        Object.assign(img.dataset, { testid: 'map-tile', layer: layer.name, z, x, y, state: 'loading' });
        img.onload = () => {
          img.dataset.state = 'loaded';
        };
        img.onerror = () => {
          img.dataset.state = 'error';
        };
        img.src = tileUrl(layer.template, z, x, y);
        layer.imgs.set(k, img);
        layer.div.appendChild(img);
      }
      const st = img.style;
      st.left = `${box.left}px`;
      st.top = `${box.top}px`;
      st.width = `${box.right - box.left}px`;
      st.height = `${box.bottom - box.top}px`;
    }
  }
}
