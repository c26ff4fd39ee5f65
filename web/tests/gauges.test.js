// Browser test: the thruster gauges' note as Chromium draws it, from the
// page's own module (web/src/gauges.js), on `twin/fault` payloads in the
// contract's shape (twin_wire::outputs::FaultMessage, schema
// docs/schemas/fault.schema.json): a vessel its profile describes, and one
// it does not, where the twin withholds the comparison of the propellers
// and says why (`profile_mismatch`). No twind is needed.

import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { join } from 'node:path';
import { WEB, launch } from './helpers.js';

const ORIGIN = 'http://gauges.test';

const THRUSTER = { loss: 0.2, sigma: 0.35, loss_raw: 0.2, excited: false, status: 'not_excited', onset: null };

const FAULT = {
  vessel: 'v1',
  time: '2026-11-26T12:00:00Z',
  thrusters: { port: THRUSTER, starboard: { ...THRUSTER, loss: 0, loss_raw: 0 } },
  status: 'not_excited',
  excited: false,
  onset: null,
  model: 'kinetic',
  effectiveness_ratio: { value: 0.8, sigma: 0.06 },
  seed_input_faults: [0.3, 0.2],
  replay: false,
  profile_mismatch: null,
};

const MISMATCH = {
  yaw_damping_error: 1.24,
  yaw_damping_bound: 0.75,
  mass_error: 0.06,
  mass_bound: 0.75,
  thrust_error: -0.12,
  thrust_bound: 0.62,
  nis_per_dof: 0.66,
  max_nis_per_dof: 2.0,
};

/** The gauges' note for one `twin/fault` payload. */
async function note(page, fault) {
  return page.evaluate(async (f) => {
    const { Gauges } = await import('/src/gauges.js');
    const root = document.createElement('div');
    const note = document.createElement('div');
    note.id = 'gauge-note';
    document.body.replaceChildren(root, note);
    const store = { vessels: new Map([['v1', { fault: f }]]), followed: 'v1', info: null };
    new Gauges(root, store).render();
    return note.textContent;
  }, fault);
}

test('gauges: the note says when the profile does not describe the vessel', { timeout: 60_000 }, async () => {
  const browser = await launch();
  try {
    const page = await browser.newPage();
    const errors = [];
    page.on('pageerror', (e) => errors.push(e.message));
    await page.route(`${ORIGIN}/**`, (route) => {
      const path = new URL(route.request().url()).pathname;
      if (path === '/') return route.fulfill({ contentType: 'text/html', body: '<!doctype html><body></body>' });
      return route.fulfill({ contentType: 'text/javascript', body: readFileSync(join(WEB, path)) });
    });
    await page.goto(`${ORIGIN}/`);

    const described = await note(page, FAULT);
    assert.match(described, /extended twin · not excited · effectiveness ratio 0\.800 ± 0\.060/);
    assert.doesNotMatch(described, /withheld/);

    const far = await note(page, { ...FAULT, profile_mismatch: MISMATCH });
    assert.match(far, /comparison withheld: the profile does not describe this vessel/);

    assert.deepEqual(errors, [], 'no script errors on the page');
  } finally {
    await browser.close();
  }
});
