// After `vite build`: copies three.js's licence beside the bundle and writes
// web-dist/SOURCE-HASH, the SHA-256 of every source the bundle is built from
// and of every file built. crates/twind/tests/web_bundle.rs recomputes both
// and fails when the committed bundle is older than its sources (run
// `npm ci && npm run build` in web/ and commit crates/twind/web-dist/).
//
// The sources: index.html, vite.config.js, package.json, package-lock.json,
// and everything under src/ and scripts/. Paths are relative to web/, sorted
// bytewise; the hash of the sources is the SHA-256 of the lines
// "<sha256 of the file>  <path>\n", as sha256sum prints them.

import { createHash } from 'node:crypto';
import { readFileSync, readdirSync, writeFileSync, mkdirSync, copyFileSync, statSync } from 'node:fs';
import { join, relative, sep } from 'node:path';
import { fileURLToPath } from 'node:url';

const web = fileURLToPath(new URL('..', import.meta.url));
const dist = join(web, '..', 'crates', 'twind', 'web-dist');

function walk(dir) {
  const out = [];
  for (const name of readdirSync(dir)) {
    const p = join(dir, name);
    if (statSync(p).isDirectory()) out.push(...walk(p));
    else out.push(p);
  }
  return out;
}

const sha = (bytes) => createHash('sha256').update(bytes).digest('hex');
const rel = (root, p) => relative(root, p).split(sep).join('/');
const cmp = (a, b) => Buffer.compare(Buffer.from(a), Buffer.from(b));

export function sourceFiles() {
  const files = ['index.html', 'vite.config.js', 'package.json', 'package-lock.json'];
  for (const d of ['src', 'scripts']) files.push(...walk(join(web, d)).map((p) => rel(web, p)));
  return files.sort(cmp);
}

export function listing(root, files) {
  return files.map((f) => `${sha(readFileSync(join(root, f)))}  ${f}\n`).join('');
}

if (process.argv[1] && fileURLToPath(import.meta.url) === process.argv[1]) {
  mkdirSync(join(dist, 'licenses'), { recursive: true });
  copyFileSync(join(web, 'node_modules', 'three', 'LICENSE'), join(dist, 'licenses', 'three.txt'));
  const sources = listing(web, sourceFiles());
  const built = walk(dist)
    .map((p) => rel(dist, p))
    .filter((f) => f !== 'SOURCE-HASH')
    .sort(cmp);
  const record = {
    note: 'Written by web/scripts/stamp.js (npm run build); checked by crates/twind/tests/web_bundle.rs.',
    sources_sha256: sha(sources),
    sources: sources.trimEnd().split('\n'),
    built: listing(dist, built).trimEnd().split('\n'),
  };
  writeFileSync(join(dist, 'SOURCE-HASH'), `${JSON.stringify(record, null, 2)}\n`);
  console.log(`web-dist: ${built.length} files, sources ${record.sources_sha256.slice(0, 16)}…`);
}
