// Browser end-to-end test (c): the chart's background tiles. twind's
// settings name a tile server that this test runs itself on 127.0.0.1
// (plain PNGs made here; nothing leaves the machine): the page asks for the
// tiles around the followed vessel, with the z/x/y that the slippy-map
// formulas (computed here, not by the page) give for its latitude and
// longitude, draws them under the track, and shows the attribution. The
// tile-less default (no request beyond twind) is checked by demo.test.js.
// Screenshot: $WEB_ARTIFACTS/tiles.png.

import { test } from 'node:test';
import assert from 'node:assert/strict';
import { createServer } from 'node:http';
import { writeFileSync, mkdtempSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { deflateSync, inflateSync, crc32 } from 'node:zlib';
import { startTwind, launch, waitFor, ARTIFACTS } from './helpers.js';

const ATTRIBUTION = 'Test tiles © the twin web tests';
/** `[web] tile_max_zoom` in the test's settings. */
const MAX_ZOOM = 18;
/** The base tiles' colour, and the page's background under them. */
const BASE_RGB = [0, 200, 0];
const BACKGROUND_RGB = [0x0a, 0x15, 0x24];
/** The page draws the base tiles at this opacity (style.css). */
const BASE_OPACITY = 0.55;

/** A PNG chunk: length, type, data, CRC of type and data. */
function chunk(type, data) {
  const head = Buffer.alloc(8);
  head.writeUInt32BE(data.length, 0);
  head.write(type, 4, 'latin1');
  const crc = Buffer.alloc(4);
  crc.writeUInt32BE(crc32(Buffer.concat([head.subarray(4), data])), 0);
  return Buffer.concat([head, data, crc]);
}

/** A 256×256 PNG of one RGBA colour. */
function solidPng([r, g, b, a]) {
  const size = 256;
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(size, 0);
  ihdr.writeUInt32BE(size, 4);
  ihdr.set([8, 6, 0, 0, 0], 8); // 8 bits, RGBA, deflate, no filter, no interlace
  const row = Buffer.alloc(1 + 4 * size);
  for (let i = 0; i < size; i++) row.set([r, g, b, a], 1 + 4 * i);
  const raw = Buffer.concat(Array.from({ length: size }, () => row));
  const signature = Buffer.from([137, 80, 78, 71, 13, 10, 26, 10]);
  return Buffer.concat([signature, chunk('IHDR', ihdr), chunk('IDAT', deflateSync(raw)), chunk('IEND', Buffer.alloc(0))]);
}

/** The colour of a 1×1 PNG (a screenshot of one pixel): with one pixel every
 *  PNG filter leaves the bytes as they are. */
function pixelOf(png) {
  let at = 8;
  const idat = [];
  while (at < png.length) {
    const len = png.readUInt32BE(at);
    const type = png.toString('latin1', at + 4, at + 8);
    if (type === 'IDAT') idat.push(png.subarray(at + 8, at + 8 + len));
    at += 12 + len;
  }
  const raw = inflateSync(Buffer.concat(idat));
  return [raw[1], raw[2], raw[3]];
}

/** Serves `/base/{z}/{x}/{y}.png` (opaque) and `/sea/...` (transparent) on
 *  127.0.0.1, and records what was asked. */
async function startTileServer() {
  const base = solidPng([...BASE_RGB, 255]);
  const sea = solidPng([0, 0, 0, 0]);
  const requests = [];
  const server = createServer((req, res) => {
    const m = /^\/(base|sea)\/(\d+)\/(\d+)\/(\d+)\.png$/.exec(req.url);
    requests.push({ url: req.url, referer: req.headers.referer ?? null });
    if (!m) {
      res.writeHead(404).end();
      return;
    }
    res.writeHead(200, { 'content-type': 'image/png', 'cache-control': 'no-store' });
    res.end(m[1] === 'base' ? base : sea);
  });
  await new Promise((res) => server.listen(0, '127.0.0.1', res));
  return { server, requests, origin: `http://127.0.0.1:${server.address().port}` };
}

/** The slippy-map tile of a latitude/longitude at zoom z. */
function slippyTile(latDeg, lonDeg, z) {
  const n = 2 ** z;
  const lat = (latDeg * Math.PI) / 180;
  return {
    x: Math.floor(((lonDeg + 180) / 360) * n),
    y: Math.floor(((1 - Math.asinh(Math.tan(lat)) / Math.PI) / 2) * n),
  };
}

/** The base and overlay tiles drawn under the boat once both are loaded
 *  at a zoom level `zoomOk` accepts, with the vessel's latest position. */
async function tileUnderBoat(page, zoomOk) {
  let last = null;
  return waitFor(
    async () => {
      const found = await page.evaluate(() => {
        const st = window.__twin.store.vessels.get('otter-sim')?.state;
        const boat = document.querySelector('#map .boat')?.getBoundingClientRect();
        if (!st || !boat || !boat.width) return null;
        const [bx, by] = [boat.x + boat.width / 2, boat.y + boat.height / 2];
        const under = (layer) =>
          [...document.querySelectorAll(`[data-testid=map-tile][data-layer=${layer}]`)]
            .filter((img) => {
              const r = img.getBoundingClientRect();
              return r.left <= bx && bx < r.right && r.top <= by && by < r.bottom;
            })
            .map((img) => {
              const r = img.getBoundingClientRect();
              return { ...img.dataset, naturalWidth: img.naturalWidth, width: r.width, height: r.height, src: img.src };
            });
        const [base, overlay] = [under('base'), under('overlay')];
        if (base.length !== 1 || overlay.length !== 1 || base[0].state !== 'loaded' || overlay[0].state !== 'loaded') return null;
        return { lat: st.lat_deg, lon: st.lon_deg, base: base[0], overlay: overlay[0], zoom: Number(document.querySelector('[data-testid=map-tiles]').dataset.zoom), boat: { x: bx, y: by } };
      });
      // The page's zoom and the tile's agree, and the tile is the one
      // holding the vessel (the boat is drawn from the latest state a
      // moment after it arrives: asked again if it just crossed a tile edge).
      last = found ?? last;
      if (!found || !zoomOk(found.zoom) || Number(found.base.z) !== found.zoom) return false;
      const want = slippyTile(found.lat, found.lon, found.zoom);
      return Number(found.base.x) === want.x && Number(found.base.y) === want.y ? found : false;
    },
    { what: 'the loaded tile holding the vessel under the boat' },
  ).catch((e) => {
    const want = last && slippyTile(last.lat, last.lon, last.zoom);
    throw new Error(`${e.message}; last seen under the boat: ${JSON.stringify(last)}, the vessel's tile: ${JSON.stringify(want)}`);
  });
}

/** The tile found under the boat: the one the slippy-map formulas give,
 *  from the test's server, decoded, its overlay the same z/x/y. */
function checkTile(found, origin) {
  const z = found.zoom;
  const want = slippyTile(found.lat, found.lon, z);
  assert.deepEqual([Number(found.base.x), Number(found.base.y)], [want.x, want.y], `tile under the boat at ${found.lat}, ${found.lon}, z ${z}`);
  assert.deepEqual([found.overlay.z, found.overlay.x, found.overlay.y], [found.base.z, found.base.x, found.base.y]);
  assert.equal(found.base.src, `${origin}/base/${z}/${want.x}/${want.y}.png`);
  assert.equal(found.base.naturalWidth, 256, 'the PNG was decoded (the page policy lets the tile server in)');
  assert.ok(Math.abs(found.base.width - found.base.height) / found.base.width < 0.6, `tile ${found.base.width}×${found.base.height} px`);
}

test('tiles: a configured tile server is asked for the z/x/y around the vessel; drawn under the track, attributed', { timeout: 180_000 }, async () => {
  const tiles = await startTileServer();
  const dir = mkdtempSync(join(tmpdir(), 'twind-tiles-'));
  const settings = join(dir, 'twind.toml');
  writeFileSync(
    settings,
    ['[web]', `tile_url = "${tiles.origin}/base/{z}/{x}/{y}.png"`, `tile_overlay_url = "${tiles.origin}/sea/{z}/{x}/{y}.png"`, `tile_attribution = "${ATTRIBUTION}"`, `tile_max_zoom = ${MAX_ZOOM}`, ''].join('\n'),
  );
  const twind = await startTwind(['--settings', settings, '--demo', '--demo-loop', '--demo-rate', '2', '--web-listen', '127.0.0.1:0']);
  const browser = await launch();
  try {
    const page = await browser.newPage({ viewport: { width: 1600, height: 1000 } });
    const errors = [];
    page.on('pageerror', (e) => errors.push(e.message));
    await page.goto(`${twind.url}#vessel=otter-sim&3d=off`);
    await waitFor(async () => (await page.textContent('[data-testid=followed-vessel]')) === 'otter-sim', { what: 'following otter-sim' });

    // The attribution is on the chart, visible.
    const credit = page.locator('[data-testid=map-attribution]');
    await credit.waitFor({ state: 'visible' });
    assert.equal(await credit.textContent(), ATTRIBUTION);
    const creditBox = await credit.boundingBox();
    const mapBox = await page.locator('[data-testid=map]').boundingBox();
    assert.ok(creditBox.width > 50 && creditBox.y + creditBox.height <= mapBox.y + mapBox.height + 1, `attribution at ${JSON.stringify(creditBox)}, map ${JSON.stringify(mapBox)}`);

    // Close in (the view starts a few tens of metres wide) the configured
    // most detailed zoom is used, its tiles enlarged.
    let found = await tileUnderBoat(page, (zoom) => zoom === MAX_ZOOM);
    checkTile(found, tiles.origin);
    assert.ok(found.base.width >= 256 / Math.SQRT2, `tile drawn ${found.base.width} px wide at z ${found.zoom}`);
    // Zoomed out with the wheel over the vessel, the page picks the zoom
    // whose tiles are nearest 256 px: drawn 256 px wide give or take a
    // factor sqrt(2).
    const boat = found.boat;
    await page.mouse.move(boat.x, boat.y);
    for (let i = 0; i < 4; i++) await page.mouse.wheel(0, 600);
    found = await tileUnderBoat(page, (zoom) => zoom < MAX_ZOOM - 1);
    checkTile(found, tiles.origin);
    assert.ok(found.base.width > 256 / Math.SQRT2 - 1 && found.base.width < 256 * Math.SQRT2 + 1, `tile drawn ${found.base.width} px wide at z ${found.zoom}`);
    const z = found.zoom;
    const want = slippyTile(found.lat, found.lon, z);
    // The tiles cover the whole chart, corners included, each layer once.
    const uncovered = await page.evaluate(() => {
      const m = document.querySelector('[data-testid=map]').getBoundingClientRect();
      const points = [
        [m.left + 1, m.top + 1],
        [m.right - 1, m.top + 1],
        [m.left + 1, m.bottom - 1],
        [m.right - 1, m.bottom - 1],
        [(m.left + m.right) / 2, (m.top + m.bottom) / 2],
      ];
      const out = [];
      for (const layer of ['base', 'overlay']) {
        const rects = [...document.querySelectorAll(`[data-testid=map-tile][data-layer=${layer}]`)].map((img) => img.getBoundingClientRect());
        for (const [x, y] of points) {
          const n = rects.filter((r) => r.left <= x && x < r.right && r.top <= y && y < r.bottom).length;
          if (n !== 1) out.push({ layer, x, y, tiles: n });
        }
      }
      return out;
    });
    assert.deepEqual(uncovered, [], 'chart points not under exactly one tile per layer');

    // The server was asked for exactly that tile, base and overlay, with the
    // page's origin as referrer.
    const asked = tiles.requests.map((r) => r.url);
    assert.ok(asked.includes(`/base/${z}/${want.x}/${want.y}.png`), asked.join(' '));
    assert.ok(asked.includes(`/sea/${z}/${want.x}/${want.y}.png`), asked.join(' '));
    const pageOrigin = new URL(twind.url).origin;
    for (const r of tiles.requests) assert.equal(r.referer, `${pageOrigin}/`, `referrer of ${r.url}`);

    // Drawn under the track: the chart's pixels away from the vessel are
    // the base colour at the page's opacity over its background (the
    // overlay is transparent); the SVG above is clear there.
    const blend = BASE_RGB.map((c, i) => Math.round(BASE_OPACITY * c + (1 - BASE_OPACITY) * BACKGROUND_RGB[i]));
    const samples = [];
    for (const [fx, fy] of [
      [0.15, 0.25],
      [0.85, 0.25],
      [0.15, 0.75],
      [0.85, 0.75],
      [0.5, 0.1],
    ]) {
      const x = Math.round(mapBox.x + fx * mapBox.width) + 0.5;
      const y = Math.round(mapBox.y + fy * mapBox.height) + 0.5;
      const png = await page.screenshot({ clip: { x: x - 0.5, y: y - 0.5, width: 1, height: 1 } });
      samples.push(pixelOf(png));
    }
    const near = samples.filter((p) => p.every((c, i) => Math.abs(c - blend[i]) <= 12));
    // A grid line or another vessel's trail may cross a sample.
    assert.ok(near.length >= 3, `chart pixels ${JSON.stringify(samples)}, tiles blended ${JSON.stringify(blend)}`);

    // The attribution stays visible, and every tile request went to the
    // configured server.
    assert.ok(await credit.isVisible());
    assert.ok(tiles.requests.length >= 2);
    assert.deepEqual(errors, [], 'no script errors on the page');
    await page.screenshot({ path: join(ARTIFACTS, 'tiles.png') });
    console.log(`tiles: z ${z}, tile ${want.x}/${want.y} under the boat at ${found.lat.toFixed(5)}, ${found.lon.toFixed(5)}; ${tiles.requests.length} tile requests`);
  } finally {
    await browser.close();
    await twind.stop();
    tiles.server.close();
  }
  const { code, signal } = await twind.exited;
  assert.equal(code, 0, `twind exited with ${code ?? signal}`);
});
