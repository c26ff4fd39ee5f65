// The twin's web page: connects to twind's server-sent events, keeps the
// picture in a Store, and draws the panels once a frame at most (each at its
// own pace), so that many vessels' events never hold up the page.

import './style.css';
import { Store } from './store.js';
import { MapView } from './map.js';
import { Gauges } from './gauges.js';
import { FaultChart } from './chart.js';
import { VesselList, Alarms, Findings } from './panels.js';
import { PgmView } from './pgm.js';
import { View3d } from './view3d.js';
import { text } from './svg.js';

const $ = (id) => document.getElementById(id);
const store = new Store();

// What the page spends, for people (header) and for the browser tests.
const perf = {
  events: 0,
  ingestMs: 0,
  frames: 0,
  renderMs: 0,
  maxRenderMs: 0,
  maxIngestMs: 0,
  followedAt: 0,
};
window.__twin = { store, perf };

const map = new MapView($('map'), store, $('map-tiles'), $('map-attribution'));
const gauges = new Gauges($('gauges'), store);
const chart = new FaultChart($('fault-chart'), store);
const alarms = new Alarms($('alarms'), store);
const findings = new Findings($('findings'), store);
const pgm = new PgmView($('pgm'), store);
// `#3d=off` in the address leaves the 3D view out (slow machines, no WebGL).
const params = new URLSearchParams(location.hash.slice(1));
const view3d = new View3d($('view3d'), $('view3d-caption'), store, params.get('3d') !== 'off');
const list = new VesselList($('vessels'), $('filter'), $('vessel-count'), store, follow);
map.onPick = follow;

async function loadHistory(id) {
  try {
    const r = await fetch(`/api/history/${encodeURIComponent(id)}`);
    if (!r.ok) return;
    const h = await r.json();
    const v = store.vessels.get(id);
    if (v && !v.historyLoaded) store.mergeHistory(v, h);
  } catch {
    // The live events fill in anyway.
  }
}

function follow(id) {
  if (!id || store.followed === id) return;
  store.followed = id;
  perf.followedAt = performance.now();
  text($('followed'), id);
  $('followed').dataset.vessel = id;
  params.set('vessel', id);
  history.replaceState(null, '', `#${params}`);
  map.auto = 'follow';
  store.dirty.add('all');
  const v = store.vessels.get(id);
  if (v && !v.historyLoaded) loadHistory(id);
}

const wanted = params.get('vessel');
store.onFirstVessel = (id) => {
  if (!store.followed && !wanted) follow(id);
};

$('fit').addEventListener('click', () => {
  map.auto = 'follow';
  store.dirty.add('map');
});
$('fleet').addEventListener('click', () => {
  map.auto = 'fleet';
  store.dirty.add('map');
});

// Live events.
const KINDS = ['hello', 'state', 'fault', 'prediction', 'alarm', 'stats', 'finding', 'gnss', 'actuators', 'lagged'];
function connect() {
  const es = new EventSource('/events');
  const conn = $('conn');
  es.onopen = () => {
    text(conn, 'live');
    conn.dataset.state = 'live';
  };
  es.onerror = () => {
    text(conn, 'reconnecting…');
    conn.dataset.state = 'down';
  };
  for (const kind of KINDS) {
    es.addEventListener(kind, (e) => {
      const t0 = performance.now();
      store.ingest(kind, e.data);
      if (wanted && !store.followed && store.vessels.has(wanted)) follow(wanted);
      const dt = performance.now() - t0;
      perf.events++;
      perf.ingestMs += dt;
      if (dt > perf.maxIngestMs) perf.maxIngestMs = dt;
    });
  }
}
connect();

// Drawing: each panel at its own pace, only when its data changed.
const PACE_MS = { list: 250, map: 100, gauges: 150, chart: 250, pgm: 200, alarms: 250, findings: 500, state: 100, forecast: 100 };
const last = {};
function due(now, what) {
  if (!store.dirty.has(what)) return false;
  if (now - (last[what] ?? 0) < (PACE_MS[what] ?? 100)) return false;
  last[what] = now;
  store.dirty.delete(what);
  return true;
}

let rateAt = performance.now();
let rateEvents = 0;
function frame(now) {
  const t0 = performance.now();
  perf.frames++;
  if (store.dirty.delete('all')) for (const k of [...Object.keys(PACE_MS), 'view3d']) store.dirty.add(k);
  if (due(now, 'list')) list.render();
  const mapDue = due(now, 'map');
  const forecastDue = due(now, 'forecast');
  const stateDue = due(now, 'state');
  if (mapDue || forecastDue || stateDue) map.render();
  if (due(now, 'gauges')) gauges.render();
  if (due(now, 'chart')) chart.render();
  if (due(now, 'pgm')) pgm.render();
  if (due(now, 'alarms')) alarms.render();
  if (due(now, 'findings')) findings.render();
  if (store.dirty.has('view3d') && view3d.render(now)) store.dirty.delete('view3d');
  if (now - rateAt >= 1000) {
    const rate = ((perf.events - rateEvents) * 1000) / (now - rateAt);
    rateEvents = perf.events;
    rateAt = now;
    text($('rates'), `${store.vessels.size} vessels · ${rate.toFixed(0)} events/s${store.skipped ? ` · ${store.skipped} skipped (slow page)` : ''}`);
  }
  const dt = performance.now() - t0;
  perf.renderMs += dt;
  if (dt > perf.maxRenderMs) perf.maxRenderMs = dt;
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);
