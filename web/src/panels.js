// The vessel list, the alarms and the findings.

import { text, f1, pct, STATUS_COLOUR } from './svg.js';

export class VesselList {
  constructor(root, filter, count, store, onPick) {
    this.root = root;
    this.filter = filter;
    this.count = count;
    this.store = store;
    this.rows = new Map();
    this.onPick = onPick;
    filter.addEventListener('input', () => store.dirty.add('list'));
  }

  row(id) {
    let r = this.rows.get(id);
    if (r) return r;
    const li = document.createElement('li');
    li.dataset.testid = 'vessel-item';
    li.dataset.vessel = id;
    li.tabIndex = 0;
    li.innerHTML = '<span class="dot"></span><span class="name"></span><span class="meta"></span>';
    li.querySelector('.name').textContent = id;
    li.addEventListener('click', () => this.onPick(id));
    li.addEventListener('keydown', (e) => {
      if (e.key === 'Enter') this.onPick(id);
    });
    r = { li, dot: li.firstChild, meta: li.lastChild, key: '' };
    this.rows.set(id, r);
    return r;
  }

  render() {
    const store = this.store;
    const q = this.filter.value.trim().toLowerCase();
    const ids = [...store.vessels.keys()].sort();
    text(this.count, `${ids.length}`);
    const now = performance.now();
    let prev = null;
    for (const id of ids) {
      const v = store.vessels.get(id);
      const r = this.row(id);
      const show = !q || id.toLowerCase().includes(q);
      r.li.hidden = !show;
      const f = v.fault;
      const status = f?.status ?? 'not_excited';
      const silent = now - v.heardMs > 5000 || v.state?.stale;
      const loss =
        f && f.model === 'kinetic'
          ? `P ${pct(f.thrusters.port.loss)} · S ${pct(f.thrusters.starboard.loss)} %`
          : f
            ? 'GNSS only'
            : '';
      const meta = `${v.state ? `${f1(v.state.sog_mps)} m/s` : '…'} ${loss}${silent ? ' · stale' : ''}`;
      const key = `${status}|${meta}|${id === store.followed}`;
      if (key !== r.key) {
        r.key = key;
        r.dot.style.background = STATUS_COLOUR[status] ?? STATUS_COLOUR.not_excited;
        r.dot.title = status;
        r.meta.textContent = meta;
        r.li.classList.toggle('followed', id === store.followed);
        r.li.dataset.status = status;
      }
      // Keep the DOM order sorted, touching only rows out of place.
      const want = prev ? prev.nextSibling : this.root.firstChild;
      if (want !== r.li) this.root.insertBefore(r.li, want);
      prev = r.li;
    }
  }
}

export class Alarms {
  constructor(root, store) {
    this.root = root;
    this.store = store;
    this.shown = -1;
  }

  render() {
    const store = this.store;
    const list = store.alarms;
    const key = `${list.length}:${list[list.length - 1]?.time}:${store.followed}`;
    if (key === this.shown) return;
    this.shown = key;
    this.root.textContent = '';
    if (!list.length) {
      const li = document.createElement('li');
      li.className = 'empty';
      li.textContent = 'no alarms';
      this.root.appendChild(li);
      return;
    }
    for (const a of list.slice(-50).reverse()) {
      const li = document.createElement('li');
      li.dataset.testid = 'alarm';
      li.classList.toggle('followed', a.vessel === store.followed);
      const dot = document.createElement('span');
      dot.className = 'dot';
      dot.style.background = STATUS_COLOUR[a.to] ?? STATUS_COLOUR.not_excited;
      li.appendChild(dot);
      const t = document.createElement('span');
      t.className = 'alarm-text';
      t.textContent = `${a.time.slice(11, 19)} ${a.vessel}: ${a.what} (confidence ${(100 * a.confidence).toFixed(0)} %, onset ${a.onset.slice(11, 19)})`;
      li.appendChild(t);
      this.root.appendChild(li);
    }
  }
}

/** Findings: `twin/finding` (twin_wire::outputs::FindingsMessage): what
 *  the daemon's diagnosis of the recent data named (cause, parameters with
 *  their sigma, the gain on held-out data); an empty list when the nominal
 *  model explains the data; and, where the findings leave the held-out
 *  residuals well outside what the filter expects (`unexplained`), that
 *  figure and the biased components. Absent until the daemon publishes
 *  one. */
export class Findings {
  constructor(root, store) {
    this.root = root;
    this.store = store;
  }

  render() {
    const v = this.store.vessels.get(this.store.followed);
    const f = v?.finding;
    this.root.textContent = '';
    const para = (cls, textValue) => {
      const p = document.createElement('p');
      p.className = cls;
      p.textContent = textValue;
      this.root.appendChild(p);
      return p;
    };
    if (!f) {
      para('empty', 'No findings published for this vessel (twin/finding).');
      return;
    }
    const list = Array.isArray(f.findings) ? f.findings : f.cause ? [f] : [];
    const when = f.time ? `${f.time.slice(11, 19)} · ` : '';
    const what = [
      f.window_s ? `${Math.round(f.window_s)} s of data` : '',
      f.base_model ? `${f.base_model} model` : '',
      f.trigger ? `trigger ${f.trigger}` : '',
      Number.isFinite(f.nominal_nis_per_dof) ? `nominal NIS/dof ${f.nominal_nis_per_dof.toFixed(2)}` : '',
    ]
      .filter(Boolean)
      .join(' · ');
    const u = f.unexplained;
    const verdict = list.length
      ? `${list.length} finding${list.length > 1 ? 's' : ''}`
      : u
        ? 'no cause of the catalogue found'
        : 'the nominal model explains the data';
    para('muted', `${when}${verdict}${what ? ` · ${what}` : ''}`);
    if (u) {
      // The findings leave the held-out residuals outside what the filter
      // expects: the model is wrong in a way no cause describes.
      const biased = (Array.isArray(u.biased) ? u.biased : [])
        .map((b) => `${b.component} ${Number.isFinite(b.bias_z) ? b.bias_z.toFixed(1) : b.bias_z} SE`)
        .join(', ');
      const p = para('unexplained', `Unexplained: held-out NIS/dof ${Number.isFinite(u.nis_per_dof) ? u.nis_per_dof.toFixed(2) : u.nis_per_dof}${biased ? ` · biased: ${biased}` : ''}`);
      p.dataset.testid = 'unexplained';
    }
    const num = (x) => (Math.abs(x) < 10 ? x.toFixed(3) : x.toFixed(1));
    for (const x of list) {
      const div = document.createElement('div');
      div.className = 'finding';
      div.dataset.testid = 'finding';
      div.dataset.cause = x.cause;
      const params = Object.entries(x.parameters || {})
        .map(([k, val]) => {
          if (typeof val !== 'number') return `${k} ${val}`;
          const sd = x.uncertainty?.[k];
          return `${k} ${num(val)}${Number.isFinite(sd) ? ` ± ${num(sd)}` : ''}`;
        })
        .join(', ');
      const head = document.createElement('b');
      head.textContent = x.cause;
      div.appendChild(head);
      div.appendChild(document.createTextNode(` ${params}`));
      const g = x.gain;
      let gain = '';
      if (typeof g === 'number') gain = `gain ${g.toFixed(3)}`;
      else if (g && typeof g === 'object') {
        const parts = [];
        if (Number.isFinite(g.heldout_nll_gain)) parts.push(`held-out NLL gain ${g.heldout_nll_gain.toFixed(1)}${g.heldout_steps ? ` (${g.heldout_steps} steps)` : ''}`);
        if (g.nis_per_dof) parts.push(`NIS/dof ${g.nis_per_dof.before.toFixed(2)} → ${g.nis_per_dof.after.toFixed(2)}`);
        const r = g.prediction_rmse_m?.[g.prediction_rmse_m.length - 1];
        if (r) parts.push(`${r.horizon_s.toFixed(0)} s forecast RMSE ${r.before.toFixed(1)} → ${r.after.toFixed(1)} m`);
        gain = parts.join(' · ');
      }
      if (gain) {
        const small = document.createElement('div');
        small.className = 'muted';
        small.textContent = gain;
        div.appendChild(small);
      }
      this.root.appendChild(div);
    }
  }
}
