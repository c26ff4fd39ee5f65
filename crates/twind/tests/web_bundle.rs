//! The web page is built from `web/` with npm and committed, built, in
//! `crates/twind/web-dist/` so that `cargo build` never needs npm. This test
//! fails when the committed bundle is older than its sources, or was edited
//! by hand: `web/scripts/stamp.js` (run by `npm run build`) records the
//! SHA-256 of every source and every built file in `web-dist/SOURCE-HASH`,
//! and this recomputes both the same way. After changing the page: in `web/`,
//! `npm ci && npm run build`, and commit `crates/twind/web-dist/`.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

fn hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) {
    for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.unwrap().path();
        if path.is_dir() {
            walk(root, &path, out);
        } else {
            let rel = path.strip_prefix(root).unwrap();
            let parts: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            out.push(parts.join("/"));
        }
    }
}

/// `sha256sum`-style lines over `files` under `root`, as stamp.js writes them.
fn listing(root: &Path, files: &[String]) -> Vec<String> {
    files
        .iter()
        .map(|f| {
            let bytes = std::fs::read(root.join(f)).unwrap_or_else(|e| panic!("{f}: {e}"));
            format!("{}  {f}", hex(&bytes))
        })
        .collect()
}

fn dirs() -> (PathBuf, PathBuf) {
    let crate_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    (crate_dir.join("../../web"), crate_dir.join("web-dist"))
}

fn record() -> serde_json::Value {
    let (_, dist) = dirs();
    let text = std::fs::read_to_string(dist.join("SOURCE-HASH"))
        .expect("web-dist/SOURCE-HASH: build the page with `npm ci && npm run build` in web/");
    serde_json::from_str(&text).expect("SOURCE-HASH is JSON")
}

fn lines(v: &serde_json::Value) -> Vec<String> {
    v.as_array()
        .expect("an array of lines")
        .iter()
        .map(|l| l.as_str().unwrap().to_string())
        .collect()
}

#[test]
fn the_committed_bundle_is_built_from_the_current_sources() {
    let (web, _) = dirs();
    let mut files: Vec<String> = [
        "index.html",
        "vite.config.js",
        "package.json",
        "package-lock.json",
    ]
    .map(String::from)
    .to_vec();
    walk(&web, &web.join("src"), &mut files);
    walk(&web, &web.join("scripts"), &mut files);
    files.sort();
    let now = listing(&web, &files);
    let rec = record();
    let then = lines(&rec["sources"]);
    let changed: Vec<&String> = now.iter().filter(|l| !then.contains(l)).collect();
    let gone: Vec<&String> = then.iter().filter(|l| !now.contains(l)).collect();
    assert!(
        changed.is_empty() && gone.is_empty(),
        "crates/twind/web-dist/ is out of date with web/: run `npm ci && npm run build` in web/ \
         and commit crates/twind/web-dist/.\nchanged or new: {changed:#?}\nas built: {gone:#?}"
    );
    let mut all = now.join("\n");
    all.push('\n');
    assert_eq!(rec["sources_sha256"].as_str().unwrap(), hex(all.as_bytes()));
}

#[test]
fn the_committed_bundle_is_as_built_and_is_what_the_server_embeds() {
    let (_, dist) = dirs();
    let mut files = Vec::new();
    walk(&dist, &dist, &mut files);
    files.retain(|f| f != "SOURCE-HASH");
    files.sort();
    assert_eq!(
        lines(&record()["built"]),
        listing(&dist, &files),
        "crates/twind/web-dist/ was changed after it was built: rebuild it with `npm run build` in web/"
    );
    // Exactly the files src/web.rs embeds and serves.
    let served: BTreeSet<&str> = [
        "index.html",
        "assets/app.js",
        "assets/app.css",
        "licenses/three.txt",
    ]
    .into();
    let built: BTreeSet<&str> = files.iter().map(String::as_str).collect();
    assert_eq!(
        built, served,
        "src/web.rs's ASSETS must list every built file"
    );
    // three.js's MIT licence travels with it.
    let licence = std::fs::read_to_string(dist.join("licenses/three.txt")).unwrap();
    assert!(licence.contains("The MIT License") && licence.contains("three.js authors"));
    // Nothing is fetched from elsewhere at run time.
    let html = std::fs::read_to_string(dist.join("index.html")).unwrap();
    assert!(
        !html.contains("http://") && !html.contains("https://"),
        "{html}"
    );
}
