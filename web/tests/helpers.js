// Shared by the browser tests: find (or build) twind, start it, start
// Debian's Chromium through playwright-core, and read the page's numbers.
//
// Environment:
//   TWIND_BIN        the twind binary (default: build it with cargo and use
//                    $CARGO_TARGET_DIR/debug/twind, or ../target/debug/twind)
//   TWIN_FLEET_HARNESS  the fleet publisher (default: the test binary of
//                    crates/twind/tests/web_fleet.rs, built with cargo)
//   CHROMIUM         the browser (default /usr/bin/chromium)
//   WEB_ARTIFACTS    where screenshots go (default ../target/web-artifacts)

import { spawn, execFileSync } from 'node:child_process';
import { mkdirSync, existsSync, mkdtempSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

export const WEB = fileURLToPath(new URL('..', import.meta.url));
export const ROOT = resolve(WEB, '..');
export const ARTIFACTS = resolve(process.env.WEB_ARTIFACTS || join(ROOT, 'target', 'web-artifacts'));
mkdirSync(ARTIFACTS, { recursive: true });

function targetDir() {
  return resolve(ROOT, process.env.CARGO_TARGET_DIR || 'target');
}

/** The twind binary: $TWIND_BIN, or built now with cargo (debug). */
export function twindBin() {
  if (process.env.TWIND_BIN) return resolve(process.env.TWIND_BIN);
  execFileSync('cargo', ['build', '-p', 'twind', '--bin', 'twind'], { cwd: ROOT, stdio: 'inherit' });
  const bin = join(targetDir(), 'debug', 'twind');
  if (!existsSync(bin)) throw new Error(`no twind at ${bin}`);
  return bin;
}

/** The fleet publisher: $TWIN_FLEET_HARNESS, or the web_fleet test binary. */
export function fleetHarness() {
  if (process.env.TWIN_FLEET_HARNESS) return resolve(process.env.TWIN_FLEET_HARNESS);
  const out = execFileSync('cargo', ['test', '-p', 'twind', '--test', 'web_fleet', '--no-run', '--message-format=json'], {
    cwd: ROOT,
    stdio: ['ignore', 'pipe', 'inherit'],
    maxBuffer: 64 << 20,
  }).toString();
  for (const line of out.split('\n')) {
    if (!line.startsWith('{')) continue;
    const m = JSON.parse(line);
    if (m.reason === 'compiler-artifact' && m.target?.name === 'web_fleet' && m.executable) return m.executable;
  }
  throw new Error('cargo did not name the web_fleet test binary');
}

/** Starts a program and resolves once a line of its stdout matches `ready`. */
export function start(cmd, args, { ready, timeoutMs = 60_000, cwd, env } = {}) {
  const child = spawn(cmd, args, { cwd: cwd ?? mkdtempSync(join(tmpdir(), 'twind-web-')), env: { ...process.env, ...env }, stdio: ['ignore', 'pipe', 'pipe'] });
  let out = '';
  let err = '';
  child.stderr.on('data', (d) => {
    err = (err + d).slice(-20_000);
  });
  const exited = new Promise((res) => child.on('exit', (code, signal) => res({ code, signal })));
  const match = new Promise((res, rej) => {
    const timer = setTimeout(() => rej(new Error(`${cmd}: no ${ready} within ${timeoutMs} ms\nstdout: ${out}\nstderr: ${err}`)), timeoutMs);
    child.stdout.on('data', (d) => {
      out += d;
      const m = ready ? ready.exec(out) : [''];
      if (m) {
        clearTimeout(timer);
        res(m);
      }
    });
    exited.then(({ code, signal }) => {
      clearTimeout(timer);
      rej(new Error(`${cmd} exited (${code ?? signal}) before it was ready\nstdout: ${out}\nstderr: ${err}`));
    });
  });
  return {
    child,
    match,
    exited,
    output: () => ({ out, err }),
    async stop() {
      if (child.exitCode !== null || child.signalCode !== null) return;
      child.kill('SIGTERM');
      const t = setTimeout(() => child.kill('SIGKILL'), 10_000);
      await exited;
      clearTimeout(t);
    },
  };
}

/** Starts twind and resolves with its page URL (it prints it). */
export async function startTwind(args) {
  const p = start(twindBin(), args, { ready: /twind web page: (http:\/\/\S+)/ });
  const m = await p.match;
  return { ...p, url: m[1] };
}

/** Debian's Chromium, headless, as the machine notes say it runs here. */
export async function launch() {
  return chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    headless: true,
    args: [
      '--no-sandbox',
      '--disable-gpu',
      '--disable-quic',
      '--no-first-run',
      '--disable-background-networking',
      '--disable-component-update',
      '--disable-sync',
      '--disable-dev-shm-usage',
      // WebGL on the CPU for the 3D view (there is no GPU here).
      '--enable-unsafe-swiftshader',
      '--use-angle=swiftshader',
    ],
  });
}

export async function waitFor(fn, { timeoutMs = 60_000, everyMs = 200, what = 'condition' } = {}) {
  const deadline = Date.now() + timeoutMs;
  let last;
  while (Date.now() < deadline) {
    last = await fn();
    if (last) return last;
    await new Promise((r) => setTimeout(r, everyMs));
  }
  throw new Error(`timed out waiting for ${what} (last: ${JSON.stringify(last)})`);
}

export function quantile(xs, q) {
  const s = [...xs].sort((a, b) => a - b);
  if (!s.length) return NaN;
  return s[Math.min(s.length - 1, Math.floor(q * s.length))];
}
