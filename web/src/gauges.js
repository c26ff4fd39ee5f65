// Per-thruster loss gauges: an arc from 0 to 100 % loss with the estimate,
// its +-2 sigma range, the suspect and fault levels, and the status colour.

import { el, set, text, pct, STATUS_COLOUR } from './svg.js';

const R = 62;
const CX = 80;
const CY = 78;

function polar(frac, r = R) {
  const a = Math.PI * (1 - frac);
  return [CX + r * Math.cos(a), CY - r * Math.sin(a)];
}

function arc(f0, f1, r = R) {
  const a = Math.max(0, Math.min(1, f0));
  const b = Math.max(0, Math.min(1, f1));
  if (b - a < 1e-4) return 'M0 0';
  const [x0, y0] = polar(a, r);
  const [x1, y1] = polar(b, r);
  return `M${x0.toFixed(2)} ${y0.toFixed(2)}A${r} ${r} 0 0 1 ${x1.toFixed(2)} ${y1.toFixed(2)}`;
}

class Gauge {
  constructor(parent, side) {
    this.side = side;
    const box = document.createElement('div');
    box.className = 'gauge';
    box.dataset.testid = `gauge-${side}`;
    parent.appendChild(box);
    const title = document.createElement('div');
    title.className = 'gauge-title';
    title.textContent = side === 'port' ? 'Port propeller' : 'Starboard propeller';
    box.appendChild(title);
    const svg = el('svg', { viewBox: '0 0 160 96', class: 'gauge-svg' }, box);
    el('path', { d: arc(0, 1), class: 'gauge-track' }, svg);
    this.sigma = el('path', { class: 'gauge-sigma' }, svg);
    this.fill = el('path', { class: 'gauge-fill' }, svg);
    this.suspect = el('path', { class: 'gauge-level suspect' }, svg);
    this.faultLevel = el('path', { class: 'gauge-level fault' }, svg);
    this.needle = el('line', { class: 'gauge-needle', x1: CX, y1: CY }, svg);
    for (const [f, t] of [[0, '0'], [0.5, '50'], [1, '100 %']]) {
      const [x, y] = polar(f, R + 11);
      el('text', { x: x.toFixed(1), y: (y + 3).toFixed(1), class: 'gauge-tick', 'text-anchor': f === 0 ? 'start' : f === 1 ? 'end' : 'middle' }, svg).textContent = t;
    }
    this.value = document.createElement('div');
    this.value.className = 'gauge-value';
    this.value.dataset.testid = `gauge-${side}-value`;
    box.appendChild(this.value);
    this.detail = document.createElement('div');
    this.detail.className = 'gauge-detail';
    this.detail.dataset.testid = `gauge-${side}-sigma`;
    box.appendChild(this.detail);
    this.status = document.createElement('div');
    this.status.className = 'badge';
    this.status.dataset.testid = `gauge-${side}-status`;
    box.appendChild(this.status);
    this.box = box;
  }

  render(fault, info) {
    const t = fault?.thrusters?.[this.side];
    const seed = fault?.model === 'seed_method';
    const loss = t?.loss;
    const sigma = t?.sigma;
    const status = t?.status ?? 'not_excited';
    const colour = STATUS_COLOUR[status] ?? STATUS_COLOUR.not_excited;
    const has = Number.isFinite(loss) && !seed;
    set(this.fill, 'd', has ? arc(0, loss) : 'M0 0');
    set(this.fill, 'stroke', colour);
    set(this.sigma, 'd', has && Number.isFinite(sigma) ? arc(loss - 2 * sigma, loss + 2 * sigma) : 'M0 0');
    const [nx, ny] = polar(has ? Math.min(1, Math.max(0, loss)) : 0, R - 14);
    set(this.needle, 'x2', nx.toFixed(2));
    set(this.needle, 'y2', ny.toFixed(2));
    set(this.needle, 'visibility', has ? 'visible' : 'hidden');
    const lvl = (f) => {
      const [a, b] = [polar(f, R - 9), polar(f, R + 9)];
      return `M${a[0].toFixed(2)} ${a[1].toFixed(2)}L${b[0].toFixed(2)} ${b[1].toFixed(2)}`;
    };
    set(this.suspect, 'd', info ? lvl(info.suspect_loss) : 'M0 0');
    set(this.faultLevel, 'd', info ? lvl(info.fault_loss) : 'M0 0');
    text(this.value, has ? `${pct(loss)} %` : seed ? 'not observable' : '–');
    this.value.dataset.loss = has ? String(loss) : '';
    this.value.dataset.sigma = has && Number.isFinite(sigma) ? String(sigma) : '';
    text(
      this.detail,
      has
        ? `± ${pct(sigma)} % (1σ)${t.excited ? '' : ' · not excited'}`
        : seed
          ? 'GNSS only: the seed method cannot tell thrust loss'
          : 'no estimate yet',
    );
    text(this.status, status.replace('_', ' '));
    this.status.dataset.status = status;
    this.box.dataset.status = status;
    this.status.style.background = colour;
  }
}

export class Gauges {
  constructor(root, store) {
    this.store = store;
    this.port = new Gauge(root, 'port');
    this.starboard = new Gauge(root, 'starboard');
    this.note = document.getElementById('gauge-note');
  }

  render() {
    const v = this.store.vessels.get(this.store.followed);
    const f = v?.fault;
    this.port.render(f, this.store.info);
    this.starboard.render(f, this.store.info);
    if (!this.note) return;
    if (!f) text(this.note, 'waiting for twin/fault');
    else if (f.model === 'seed_method')
      text(this.note, `seed method (GNSS only) · input faults a ${f.seed_input_faults[0].toFixed(2)}, r ${f.seed_input_faults[1].toFixed(2)}`);
    else {
      const r = f.effectiveness_ratio;
      text(
        this.note,
        `extended twin · ${f.excited ? 'excited' : 'not excited'}${r ? ` · effectiveness ratio ${r.value.toFixed(3)} ± ${r.sigma.toFixed(3)}` : ''}${f.onset ? ` · onset ${f.onset.slice(11, 19)}` : ''}${f.profile_mismatch ? ' · comparison withheld: the profile does not describe this vessel' : ''}`,
      );
    }
  }
}
