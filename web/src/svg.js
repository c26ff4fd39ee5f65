// Small helpers for building SVG by hand.
const NS = 'http://www.w3.org/2000/svg';

export function el(name, attrs = {}, parent = null) {
  const e = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}

/** Sets an attribute only when it changes (DOM writes are what cost). */
export function set(e, name, value) {
  const v = String(value);
  if (e.getAttribute(name) !== v) e.setAttribute(name, v);
}

export function text(e, value) {
  const v = String(value);
  if (e.textContent !== v) e.textContent = v;
}

export const f1 = (x) => (Number.isFinite(x) ? x.toFixed(1) : '–');
export const f2 = (x) => (Number.isFinite(x) ? x.toFixed(2) : '–');
export const pct = (x) => (Number.isFinite(x) ? (100 * x).toFixed(1) : '–');

export const STATUS_COLOUR = {
  nominal: '#3fb950',
  suspect: '#d29922',
  fault: '#f85149',
  not_excited: '#8b949e',
};
export const SIDE_COLOUR = { port: '#6cb6ff', starboard: '#e0a3ff' };
