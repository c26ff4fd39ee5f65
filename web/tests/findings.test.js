// Browser test (c): the findings panel as Chromium draws it, from the
// page's own module (web/src/panels.js), on `twin/finding` payloads in the
// contract's shape (twin_wire::outputs::FindingsMessage, schema
// docs/schemas/finding.schema.json): a diagnosis that names causes, one
// that names none and leaves the residuals unexplained, and one where the
// nominal model explains the data. The module is served to the browser as
// it is in the source tree; no twind is needed.

import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { join } from 'node:path';
import { WEB, launch } from './helpers.js';

const ORIGIN = 'http://findings.test';

const FINDING = {
  cause: 'current',
  parameters: { speed_mps: 0.31, toward_deg: 120.0 },
  uncertainty: { speed_mps: 0.02 },
  gain: { heldout_nll_gain: 812.4, heldout_steps: 360, nis_per_dof: { before: 3.1, after: 1.02 } },
};

const UNEXPLAINED = { nis_per_dof: 4.71, biased: [{ component: 'sog', bias_z: 12.3 }, { component: 'cog', bias_z: -10.8 }] };

/** The panel's text for one `twin/finding` payload. */
async function render(page, finding) {
  return page.evaluate(async (f) => {
    const { Findings } = await import('/src/panels.js');
    const root = document.createElement('div');
    document.body.replaceChildren(root);
    const store = { vessels: new Map([['v1', { finding: f }]]), followed: 'v1' };
    new Findings(root, store).render();
    return {
      text: root.textContent,
      unexplained: root.querySelector('[data-testid=unexplained]')?.textContent ?? null,
      causes: [...root.querySelectorAll('.finding')].map((d) => d.dataset.cause),
    };
  }, finding);
}

test('findings: causes, unexplained residuals and a model that explains the data', { timeout: 60_000 }, async () => {
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
    const base = { vessel: 'v1', time: '2026-11-26T12:00:00Z', window_s: 180, base_model: 'kinetic', nominal_nis_per_dof: 3.1 };

    // Causes named, the rest explained.
    const named = await render(page, { ...base, findings: [FINDING], unexplained: null });
    assert.deepEqual(named.causes, ['current']);
    assert.match(named.text, /1 finding/);
    assert.match(named.text, /speed_mps 0\.310 ± 0\.020/);
    assert.equal(named.unexplained, null);

    // A cause named, and the residuals still unexplained: both shown.
    const both = await render(page, { ...base, findings: [FINDING], unexplained: UNEXPLAINED });
    assert.deepEqual(both.causes, ['current']);
    assert.equal(both.unexplained, 'Unexplained: held-out NIS/dof 4.71 · biased: sog 12.3 SE, cog -10.8 SE');

    // Nothing named, and not explained either: never "explains the data".
    const none = await render(page, { ...base, findings: [], unexplained: UNEXPLAINED });
    assert.deepEqual(none.causes, []);
    assert.match(none.text, /no cause of the catalogue found/);
    assert.doesNotMatch(none.text, /explains the data/);
    assert.match(none.unexplained, /NIS\/dof 4\.71/);

    // Nothing named and explained.
    const clean = await render(page, { ...base, findings: [], unexplained: null });
    assert.match(clean.text, /the nominal model explains the data/);
    assert.equal(clean.unexplained, null);

    assert.deepEqual(errors, [], 'no script errors on the page');
  } finally {
    await browser.close();
  }
});
