// The twin as the seed's probabilistic graphical model (thesis section
// 2.2.2, after Kapteyn, Pretorius and Willcox 2021) for one time step t:
// the physical state S_t (hidden), the observations O_t (measured), the
// digital state D_t (estimated, with its uncertainty), the quantities of
// interest Q_t (inferred and predicted) and the control U_t, with the
// previous step's D_{t-1} and U_{t-1} feeding in. Every node shows the
// live values of the followed vessel.

import { el, text, f1, f2, pct } from './svg.js';
import { toDeg } from './geo.js';

const W = 1000;
const H = 330;
const LINE = 15;

// x, y, w, h; kind picks the colour; lines are filled in by render().
const NODES = {
  u0: { x: 8, y: 250, w: 150, h: 66, kind: 'past', title: 'U', sub: 't−1', caption: 'control', lines: 2 },
  d0: { x: 430, y: 250, w: 170, h: 66, kind: 'past', title: 'D', sub: 't−1', caption: 'digital state', lines: 2 },
  s: { x: 8, y: 12, w: 178, h: 204, kind: 'hidden', title: 'S', sub: 't', caption: 'physical state · hidden', lines: 9 },
  o: { x: 204, y: 12, w: 196, h: 204, kind: 'measured', title: 'O', sub: 't', caption: 'observations · measured', lines: 9 },
  d: { x: 418, y: 12, w: 196, h: 204, kind: 'estimated', title: 'D', sub: 't', caption: 'digital state · estimated ±1σ', lines: 9 },
  q: { x: 632, y: 12, w: 196, h: 204, kind: 'predicted', title: 'Q', sub: 't', caption: 'quantities of interest', lines: 9 },
  u: { x: 846, y: 12, w: 146, h: 204, kind: 'control', title: 'U', sub: 't', caption: 'control', lines: 9 },
};

// The edges (arrows) of the graph.
const EDGES = [
  'M 83 250 L 83 217', // U(t-1) -> S: actuation
  'M 186 110 L 203 110', // S -> O: sensing
  'M 400 110 L 417 110', // O -> D: assimilation
  'M 515 250 L 515 217', // D(t-1) -> D: the model's prediction
  'M 158 290 L 400 290 Q 410 290 410 280 L 410 235 Q 410 226 440 220 L 450 217', // U(t-1) -> D: known input
  'M 614 110 L 631 110', // D -> Q: inference
  'M 828 110 L 845 110', // Q -> U: decision
  'M 919 217 L 919 300 L 610 300', // U -> t+1
];

export class PgmView {
  constructor(svg, store) {
    this.svg = svg;
    this.store = store;
    svg.setAttribute('viewBox', `0 0 ${W} ${H}`);
    svg.setAttribute('preserveAspectRatio', 'xMidYMid meet');
    const defs = el('defs', {}, svg);
    const m = el('marker', { id: 'arrow', viewBox: '0 0 10 10', refX: 9, refY: 5, markerWidth: 7, markerHeight: 7, orient: 'auto-start-reverse' }, defs);
    el('path', { d: 'M0 0 L10 5 L0 10 z', class: 'arrow-head' }, m);
    for (const d of EDGES) el('path', { d, class: 'edge', 'marker-end': 'url(#arrow)' }, svg);
    const label = (x, y, t) => {
      el('text', { x, y, class: 'edge-label' }, svg).textContent = t;
    };
    label(612, 316, 'to S and D at t+1');
    label(168, 284, 'known input (shaft speeds)');
    label(521, 240, 'model: predict');
    label(88, 240, 'actuation');
    this.nodes = {};
    for (const [id, n] of Object.entries(NODES)) {
      const g = el('g', { class: `node ${n.kind}`, 'data-testid': `pgm-${id}`, transform: `translate(${n.x} ${n.y})` }, svg);
      el('rect', { width: n.w, height: n.h, rx: 8 }, g);
      const t = el('text', { x: 10, y: 20, class: 'node-title' }, g);
      t.textContent = n.title;
      el('tspan', { 'baseline-shift': 'sub', 'font-size': '10' }, t).textContent = n.sub;
      el('text', { x: n.sub.length > 1 ? 52 : 38, y: 19, class: 'node-caption' }, g).textContent = n.caption;
      const lines = [];
      for (let i = 0; i < n.lines; i++) lines.push(el('text', { x: 10, y: 38 + i * LINE, class: 'node-line' }, g));
      this.nodes[id] = lines;
    }
    // Legend.
    const lg = el('g', { transform: `translate(640 236)`, class: 'pgm-legend' }, svg);
    [
      ['hidden', 'hidden: not seen directly'],
      ['measured', 'measured'],
      ['estimated', 'estimated (±1σ)'],
      ['predicted', 'inferred / predicted (±2σ)'],
    ].forEach(([k, label], i) => {
      const g = el('g', { class: `node ${k}`, transform: `translate(${(i % 2) * 175} ${Math.floor(i / 2) * 20})` }, lg);
      el('rect', { width: 14, height: 12, rx: 3 }, g);
      el('text', { x: 20, y: 10, class: 'node-line' }, g).textContent = label;
    });
  }

  fill(id, lines) {
    const slots = this.nodes[id];
    for (let i = 0; i < slots.length; i++) text(slots[i], lines[i] ?? '');
  }

  render() {
    const v = this.store.vessels.get(this.store.followed);
    const s = v?.state;
    const f = v?.fault;
    const g = v?.gnss;
    const a = v?.actuators;
    const kinetic = f?.model === 'kinetic';
    const rpm = a?.rpm;
    this.fill('s', [
      'true position, velocity,',
      'heading and yaw rate;',
      'true propeller effectiveness',
      '(1 − loss) port and starboard;',
      'water current, wind, waves.',
      '',
      'Not observed directly: the',
      'twin knows it only through',
      'O and infers it as D.',
    ]);
    const fix = g
      ? [
          `GNSS ${g.lat_deg.toFixed(6)}°, ${g.lon_deg.toFixed(6)}°`,
          `SOG ${f2(g.sog_mps)} m/s · COG ${f1(toDeg(g.cog_rad))}°`,
          g.heading_rad != null ? `heading ${f1(toDeg(g.heading_rad))}° (compass)` : 'no heading sensor',
          g.hdop != null ? `HDOP ${f1(g.hdop)} · at ${g.time.slice(11, 22)}` : `at ${g.time.slice(11, 22)}`,
        ]
      : ['(JSON inputs only; none seen yet)'];
    this.fill('o', [
      ...fix,
      rpm ? `shaft speeds P ${rpm.port.toFixed(0)} · S ${rpm.starboard.toFixed(0)} rpm` : a?.thrust_n ? `thrust P ${f1(a.thrust_n.port)} · S ${f1(a.thrust_n.starboard)} N` : 'no propeller data',
      s ? `innovation NIS ${f2(s.nis)} (${s.nis_dof} dof)` : '',
      v?.stats ? `accepted ${Object.values(v.stats.accepted).reduce((x, y) => x + y, 0)} · rejected ${Object.values(v.stats.rejected).reduce((x, y) => x + y, 0)}` : '',
    ]);
    const c = s?.current;
    this.fill(
      'd',
      s
        ? [
            `north ${f1(s.north_m)} ± ${f2(s.sigma.north_m)} m`,
            `east ${f1(s.east_m)} ± ${f2(s.sigma.east_m)} m`,
            `SOG ${f2(s.sog_mps)} ± ${f2(s.sigma.sog_mps)} m/s`,
            `course ${f1(toDeg(s.cog_rad))} ± ${f1((s.sigma.cog_rad * 180) / Math.PI)}°`,
            s.heading_rad != null ? `heading ${f1(toDeg(s.heading_rad))}°` : 'heading: not estimated',
            kinetic ? `port loss ${pct(f.thrusters.port.loss)} ± ${pct(f.thrusters.port.sigma)} %` : f ? `input faults a ${f2(f.seed_input_faults[0])}, r ${f2(f.seed_input_faults[1])}` : '',
            kinetic ? `stbd loss ${pct(f.thrusters.starboard.loss)} ± ${pct(f.thrusters.starboard.sigma)} %` : '',
            c ? `current ${f2(c.speed_mps)} m/s → ${c.toward_deg.toFixed(0)}°` : 'current: not estimated',
            `${s.model === 'kinetic' ? 'extended twin (kinetic)' : "seed's method (kinematic)"}${s.stale ? ' · STALE' : ''}`,
          ]
        : ['waiting for twin/state'],
    );
    const current = v?.forecastCurrent(this.store.info);
    const pred = current ? v.prediction : null;
    const end = pred?.points?.[pred.points.length - 1];
    const st = (side) => {
      const t = f?.thrusters?.[side];
      return t ? `${t.status.replace('_', ' ').toUpperCase()}${t.onset ? ` since ${t.onset.slice(11, 19)}` : ''}` : '–';
    };
    this.fill('q', [
      'thruster health',
      ` port: ${st('port')}`,
      ` stbd: ${st('starboard')}`,
      f?.effectiveness_ratio ? `effectiveness ratio ${f.effectiveness_ratio.value.toFixed(3)}` : kinetic ? '' : 'thrust loss: not observable',
      end ? `forecast +${pred.horizon_s.toFixed(0)} s:` : v?.prediction ? `forecast: stale (from ${v.prediction.start.slice(11, 19)})` : 'forecast: waiting',
      end ? ` N ${f1(end.north_m)} E ${f1(end.east_m)} m` : '',
      end ? ` ± ${f1(2 * end.position_sigma_m)} m (2σ)` : '',
      end ? ` SOG ${f2(end.sog_mps)} m/s` : '',
      `alarms ${this.store.alarms.filter((x) => x.vessel === v?.id).length}${v?.finding ? ` · findings: ${(v.finding.findings || []).map((x) => x.cause).join(', ') || 'none'}` : ''}`,
    ]);
    this.fill('u', [
      rpm ? `port ${rpm.port.toFixed(0)} rpm` : 'no propeller data',
      rpm ? `stbd ${rpm.starboard.toFixed(0)} rpm` : '',
      rpm ? '(measured shaft speeds,' : '',
      rpm ? ' the twin\'s known input)' : '',
      '',
      'A fault-tolerant controller',
      'subscribes to twin/fault',
      'and re-allocates thrust.',
      '',
    ]);
    this.fill('u0', ['shaft speeds at t−1', 'drive S and D']);
    this.fill('d0', ['estimate and covariance', 'at the previous fix']);
  }
}
