// Builds the page into crates/twind/web-dist/, which twind embeds at compile
// time (src/web.rs lists the files). Fixed file names: the server serves
// exactly index.html, assets/app.js and assets/app.css.
import { defineConfig } from 'vite';
import { fileURLToPath } from 'node:url';

// three.js is MIT-licensed: its notice goes at the top of the bundle (after
// minification, which drops comments), and the full text is served beside it
// (web-dist/licenses/three.txt, copied by scripts/stamp.js).
const NOTICE =
  '/*! twind web page. Bundles three.js: MIT licence, Copyright © 2010-2026 three.js authors; full text at /licenses/three.txt */\n';
const notice = {
  name: 'three-licence-notice',
  generateBundle(_options, bundle) {
    for (const chunk of Object.values(bundle)) if (chunk.type === 'chunk') chunk.code = NOTICE + chunk.code;
  },
};

export default defineConfig({
  base: '/',
  plugins: [notice],
  build: {
    outDir: fileURLToPath(new URL('../crates/twind/web-dist', import.meta.url)),
    emptyOutDir: true,
    target: 'es2022',
    sourcemap: false,
    modulePreload: false,
    cssCodeSplit: false,
    chunkSizeWarningLimit: 1200,
    rollupOptions: {
      output: {
        entryFileNames: 'assets/app.js',
        chunkFileNames: 'assets/[name].js',
        assetFileNames: (info) => (info.names?.[0]?.endsWith('.css') || info.name?.endsWith('.css') ? 'assets/app.css' : 'assets/[name][extname]'),
      },
    },
  },
  server: {
    // `npm run dev` against a running twind: the page's requests go to it.
    proxy: { '/events': 'http://127.0.0.1:8080', '/api': 'http://127.0.0.1:8080' },
  },
});
