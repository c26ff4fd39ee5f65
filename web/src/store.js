// What the page knows: the latest outputs of every vessel, short histories,
// and the alarms. Fed by the server-sent events; read by the panels.
// Every event only updates data and sets dirty flags: drawing happens once a
// frame at most (main.js), so a burst of events costs a burst of JSON.parse
// and nothing more. Forecasts of vessels that are not followed are kept as
// text and parsed only when needed.

import { epochS, originOf } from './geo.js';

/** Track and fault points kept per vessel (10 min at 2 per second). */
export const SERIES_LEN = 1200;
/** Message time between two kept points, s. */
export const SERIES_STEP_S = 0.5;
export const ALARMS_KEPT = 200;

function pushPoint(series, p) {
  const last = series[series.length - 1];
  if (last) {
    if (p[0] < last[0] - 1) series.length = 0; // time went back: a new run
    else if (p[0] - last[0] < SERIES_STEP_S) return;
  }
  series.push(p);
  if (series.length > SERIES_LEN) series.splice(0, series.length - SERIES_LEN);
}

export class Vessel {
  constructor(id) {
    this.id = id;
    this.state = null;
    this.fault = null;
    this.stats = null;
    this.finding = null;
    this.gnss = null;
    this.actuators = null;
    this.predictionText = null;
    this._prediction = null;
    this._predictionOf = null;
    this.frame = null; // the twin's local frame (origin), from the state
    this.track = []; // [t, north, east, sigmaN, sigmaE]
    this.faults = []; // [t, portLoss, portSigma, stbdLoss, stbdSigma]
    this.fixes = []; // [t, lat, lon]
    this.heardMs = 0;
    this.historyLoaded = false;
  }

  /** Whether the latest forecast belongs to the latest state: a forecast
   *  starts at the fix it was made from, published every
   *  `prediction_interval_s` of message time; one from long before (or
   *  after: a replay that started over) is not drawn. */
  forecastCurrent(info) {
    const p = this.prediction;
    if (!p || !this.state) return false;
    const gap = epochS(this.state.time) - epochS(p.start);
    const limit = Math.max(5, 5 * (info?.prediction_interval_s ?? 1));
    return gap >= -1 && gap <= limit;
  }

  /** The latest forecast, parsed on first use. */
  get prediction() {
    if (this.predictionText !== this._predictionOf) {
      try {
        this._prediction = JSON.parse(this.predictionText);
      } catch {
        this._prediction = null;
      }
      this._predictionOf = this.predictionText;
    }
    return this._prediction;
  }
}

export class Store {
  constructor() {
    this.vessels = new Map();
    this.alarms = [];
    this.info = null;
    this.followed = null;
    this.dirty = new Set();
    this.skipped = 0;
    this.events = 0;
    this.onFirstVessel = null;
  }

  vessel(id) {
    let v = this.vessels.get(id);
    if (!v) {
      v = new Vessel(id);
      this.vessels.set(id, v);
      this.dirty.add('list');
      if (this.onFirstVessel && this.vessels.size === 1) this.onFirstVessel(id);
    }
    v.heardMs = performance.now();
    return v;
  }

  mark(v, ...what) {
    this.dirty.add('list');
    this.dirty.add('map');
    if (v.id === this.followed) for (const w of what) this.dirty.add(w);
  }

  /** One server-sent event. */
  ingest(kind, text) {
    this.events++;
    if (kind === 'prediction') {
      // The vessel id is near the start: avoid parsing 15 kB for nothing.
      const m = /^\{"vessel":"([A-Za-z0-9_-]+)"/.exec(text);
      const id = m ? m[1] : JSON.parse(text).vessel;
      const v = this.vessel(id);
      v.predictionText = text;
      this.mark(v, 'forecast', 'pgm');
      return;
    }
    let msg;
    try {
      msg = JSON.parse(text);
    } catch {
      return;
    }
    switch (kind) {
      case 'hello':
        this.info = msg;
        this.dirty.add('all');
        return;
      case 'lagged':
        this.skipped += msg.skipped || 0;
        return;
      case 'alarm':
        this.alarms.push(msg);
        if (this.alarms.length > ALARMS_KEPT) this.alarms.shift();
        this.dirty.add('alarms');
        return;
      default:
        break;
    }
    if (typeof msg.vessel !== 'string') return;
    const v = this.vessel(msg.vessel);
    switch (kind) {
      case 'state': {
        v.state = msg;
        v.frame = originOf(msg.lat_deg, msg.lon_deg, msg.north_m, msg.east_m);
        pushPoint(v.track, [epochS(msg.time), msg.north_m, msg.east_m, msg.sigma.north_m, msg.sigma.east_m]);
        this.mark(v, 'state', 'pgm', 'view3d');
        break;
      }
      case 'fault': {
        v.fault = msg;
        const p = msg.thrusters.port;
        const s = msg.thrusters.starboard;
        pushPoint(v.faults, [epochS(msg.time), p.loss ?? NaN, p.sigma ?? NaN, s.loss ?? NaN, s.sigma ?? NaN]);
        this.mark(v, 'gauges', 'chart', 'pgm', 'view3d');
        break;
      }
      case 'gnss':
        v.gnss = msg;
        pushPoint(v.fixes, [epochS(msg.time), msg.lat_deg, msg.lon_deg]);
        this.mark(v, 'state', 'pgm');
        break;
      case 'actuators':
        v.actuators = msg;
        this.mark(v, 'pgm', 'view3d');
        break;
      case 'stats':
        v.stats = msg;
        this.mark(v, 'pgm');
        break;
      case 'finding':
        v.finding = msg;
        this.mark(v, 'findings', 'pgm');
        break;
      default:
        break;
    }
  }

  /** Merges `GET /api/history/{vessel}` in front of what live events gave. */
  mergeHistory(v, h) {
    const older = (series, first) => series.filter((p) => first === undefined || p[0] < first - 1e-6);
    const track = (h.track || []).map((p) => p.map((x) => (x === null ? NaN : x)));
    const faults = (h.faults || []).map((p) => p.map((x) => (x === null ? NaN : x)));
    const [lat0, lon0] = h.origin || [0, 0];
    const fixes = (h.fixes || []).map((p) => [p[0], lat0 + p[1], lon0 + p[2]]);
    v.track = older(track, v.track[0]?.[0]).concat(v.track).slice(-SERIES_LEN);
    v.faults = older(faults, v.faults[0]?.[0]).concat(v.faults).slice(-SERIES_LEN);
    v.fixes = older(fixes, v.fixes[0]?.[0]).concat(v.fixes).slice(-SERIES_LEN);
    v.historyLoaded = true;
    this.dirty.add('all');
  }
}
