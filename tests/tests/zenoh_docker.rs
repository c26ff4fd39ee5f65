//! The deployment files of `docker/`, checked without a Docker engine (none
//! runs where these tests run, so the image is never built here):
//! - `docker/Dockerfile`: every `COPY` source from the build context exists,
//!   every `COPY --from` names an earlier stage, the `cargo build` line builds
//!   exactly the binaries the runtime stage copies, each of them a binary
//!   target of the workspace (`cargo metadata`), and the runtime stage runs
//!   as a non-root user;
//! - `docker/Dockerfile.dockerignore` keeps out no source the build needs
//!   (including the files the crates embed with `include_bytes!`);
//! - `docker/compose.yaml` parses as YAML and runs the safe configuration:
//!   the router is the official Zenoh image of the Zenoh version in
//!   `Cargo.lock` running `config/zenoh-acl.json5` (log-in, deny by
//!   default) with its password dictionary on the secrets volume; the
//!   daemon and the replay run binaries of the image with files that exist,
//!   connect to the router's service name and port, each logged in as an
//!   identity the secrets service makes and the access rules allow to do
//!   what it does (the daemon: the replayed vessel's outputs and its own
//!   statistics; the replay: that vessel's inputs); the daemon's state
//!   directory is a named volume.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde_yaml::Value as Yaml;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .unwrap()
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(repo().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// A Dockerfile's instructions: comments dropped, continuation lines joined,
/// each as (INSTRUCTION, rest).
fn instructions(text: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut current = String::new();
    for line in text.lines() {
        let trimmed = line.trim();
        if current.is_empty() && (trimmed.is_empty() || trimmed.starts_with('#')) {
            continue;
        }
        if let Some(head) = trimmed.strip_suffix('\\') {
            current.push_str(head);
            current.push(' ');
            continue;
        }
        current.push_str(trimmed);
        let (word, rest) = current
            .split_once(char::is_whitespace)
            .unwrap_or((&current, ""));
        out.push((word.to_uppercase(), rest.trim().to_string()));
        current.clear();
    }
    out
}

/// The binary targets of the workspace's members, by `cargo metadata`.
fn workspace_binaries() -> BTreeSet<String> {
    let output = std::process::Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--no-deps",
            "--offline",
            "--format-version",
            "1",
        ])
        .current_dir(repo())
        .output()
        .expect("cargo metadata runs");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    meta["packages"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|p| p["targets"].as_array().unwrap().iter())
        .filter(|t| t["kind"].as_array().unwrap().iter().any(|k| k == "bin"))
        .map(|t| t["name"].as_str().unwrap().to_string())
        .collect()
}

/// What the Dockerfile builds and ships.
struct Image {
    /// `--bin` arguments of the `cargo build` line.
    built: BTreeSet<String>,
    /// Binaries copied out of target/release.
    copied: BTreeSet<String>,
    /// The runtime stage's user and working directory.
    user: String,
    workdir: String,
    /// The default command's program.
    cmd: String,
}

fn image() -> Image {
    let text = read("docker/Dockerfile");
    let mut stages: Vec<String> = Vec::new();
    let mut image = Image {
        built: BTreeSet::new(),
        copied: BTreeSet::new(),
        user: String::new(),
        workdir: String::new(),
        cmd: String::new(),
    };
    for (word, rest) in instructions(&text) {
        match word.as_str() {
            "FROM" => {
                let name = rest
                    .split_whitespace()
                    .collect::<Vec<_>>()
                    .windows(2)
                    .find(|w| w[0].eq_ignore_ascii_case("as"))
                    .map(|w| w[1].to_string())
                    .unwrap_or_default();
                stages.push(name);
                // The runtime stage's settings are those after its FROM.
                image.user.clear();
                image.workdir.clear();
            }
            "COPY" => {
                let words: Vec<&str> = rest.split_whitespace().collect();
                let from = words.iter().find_map(|w| w.strip_prefix("--from="));
                let paths: Vec<&str> = words
                    .iter()
                    .copied()
                    .filter(|w| !w.starts_with("--"))
                    .collect();
                assert!(paths.len() >= 2, "COPY {rest}");
                match from {
                    Some(stage) => assert!(
                        stages[..stages.len() - 1].iter().any(|s| s == stage),
                        "COPY --from={stage}: no earlier stage of that name in {stages:?}"
                    ),
                    None => {
                        for src in &paths[..paths.len() - 1] {
                            assert!(
                                repo().join(src).exists(),
                                "COPY {src}: not in the build context (the repository root)"
                            );
                        }
                    }
                }
            }
            "RUN" if rest.contains("cargo build") => {
                let words: Vec<&str> = rest.split_whitespace().collect();
                for w in words.windows(2) {
                    if w[0] == "--bin" {
                        image.built.insert(w[1].to_string());
                    }
                }
                assert!(words.contains(&"--release"), "{rest}");
                assert!(words.contains(&"--locked"), "{rest}");
                for w in &words {
                    if let Some(bin) = w.strip_prefix("target/release/") {
                        image.copied.insert(bin.to_string());
                    }
                }
            }
            "USER" => image.user = rest,
            "WORKDIR" => image.workdir = rest,
            "CMD" => {
                let cmd: Vec<String> = serde_json::from_str(&rest).expect("CMD in exec form");
                image.cmd = cmd[0].clone();
            }
            _ => {}
        }
    }
    assert_eq!(stages.len(), 2, "a build stage and a runtime stage");
    image
}

#[test]
fn the_dockerfile_builds_the_workspace_binaries_it_ships() {
    let image = image();
    let workspace = workspace_binaries();
    println!(
        "Dockerfile builds {:?}, ships {:?}, runs {:?} as {:?} in {:?}; workspace binaries {workspace:?}",
        image.built, image.copied, image.cmd, image.user, image.workdir
    );
    let expected: BTreeSet<String> = ["twind", "twin-replay", "twin-bridge", "twin"]
        .map(String::from)
        .into();
    assert_eq!(image.built, expected);
    assert_eq!(image.copied, expected);
    for bin in &image.built {
        assert!(
            workspace.contains(bin),
            "{bin} is not a binary of the workspace"
        );
    }
    assert!(expected.contains(&image.cmd));
    let user = image.user.split(':').next().unwrap();
    assert!(
        !user.is_empty() && user != "root" && user != "0",
        "runs as {user:?}"
    );
    // The binaries find config/ and data/ relative to the working directory.
    assert_eq!(image.workdir, "/app");
}

/// Whether a `.dockerignore` pattern (as used here: plain paths, `*` in a
/// final component's suffix, `**/` for any depth) excludes `path`.
fn ignored(patterns: &[String], path: &str) -> bool {
    let components: Vec<&str> = path.split('/').collect();
    patterns.iter().any(|p| {
        let (anywhere, p) = match p.strip_prefix("**/") {
            Some(rest) => (true, rest),
            None => (false, p.as_str()),
        };
        let matches = |c: &str| match p.strip_suffix('*') {
            Some(prefix) => c.starts_with(prefix),
            None => c == p,
        };
        if p.contains('/') {
            let depth = p.split('/').count();
            components.len() >= depth && components[..depth].join("/") == p
        } else if anywhere {
            components.iter().any(|c| matches(c))
        } else {
            matches(components[0])
        }
    })
}

/// Files the crates embed at compile time (`include_bytes!`/`include_str!`),
/// relative to the repository root.
fn embedded_files() -> Vec<String> {
    let root = repo();
    let mut found = Vec::new();
    let mut dirs = vec![root.join("crates")];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let text = std::fs::read_to_string(&path).unwrap();
                for marker in ["include_bytes!(\"", "include_str!(\""] {
                    for piece in text.split(marker).skip(1) {
                        let Some(rel) = piece.split('"').next() else {
                            continue;
                        };
                        let Ok(file) = path.parent().unwrap().join(rel).canonicalize() else {
                            continue;
                        };
                        if let Ok(inside) = file.strip_prefix(&root) {
                            found.push(inside.to_string_lossy().into_owned());
                        }
                    }
                }
            }
        }
    }
    found.sort();
    found.dedup();
    found
}

#[test]
fn the_dockerignore_keeps_what_the_build_needs() {
    let patterns: Vec<String> = read("docker/Dockerfile.dockerignore")
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| l.trim_end_matches('/').to_string())
        .collect();
    assert!(
        patterns
            .iter()
            .all(|p| !p.starts_with('!') && !p.contains('?') && !p.contains('[')),
        "the checker below understands plain patterns only: {patterns:?}"
    );
    // Sanity of the matcher, then what must stay out and what must go in.
    for out in [
        "target/release/twind",
        ".git/HEAD",
        "fuzz/target/x",
        "target-deploy/x",
    ] {
        assert!(ignored(&patterns, out), "{out} should be left out");
    }
    let embedded = embedded_files();
    println!("embedded by the crates: {embedded:?}");
    assert!(!embedded.is_empty());
    let needed = [
        "Cargo.toml",
        "Cargo.lock",
        "crates",
        "tests",
        "config",
        "data",
        "bench",
    ];
    for path in needed
        .iter()
        .copied()
        .chain(embedded.iter().map(String::as_str))
    {
        assert!(
            !ignored(&patterns, path),
            "{path} is needed by the build but docker/Dockerfile.dockerignore leaves it out"
        );
    }
}

fn strings(v: &Yaml) -> Vec<String> {
    match v {
        Yaml::Sequence(s) => s
            .iter()
            .filter_map(|x| x.as_str().map(String::from))
            .collect(),
        Yaml::String(s) => vec![s.clone()],
        _ => Vec::new(),
    }
}

/// The Zenoh version of Cargo.lock.
fn locked_zenoh_version() -> String {
    let lock = read("Cargo.lock");
    let at = lock
        .find("\nname = \"zenoh\"\n")
        .expect("zenoh in Cargo.lock");
    let version = lock[at..]
        .lines()
        .find_map(|l| l.strip_prefix("version = \""))
        .unwrap();
    version.trim_end_matches('"').to_string()
}

/// The names in `key_exprs` of the ACL rules of `config` that `subject`'s
/// policies give it, for `message` and `flow`.
fn acl_keys(config: &zenoh::Config, username: &str, message: &str, flow: &str) -> Vec<String> {
    let get = |key: &str| -> serde_json::Value {
        serde_json::from_str(&config.get_json(key).unwrap()).unwrap()
    };
    let (subjects, rules, policies) = (
        get("access_control/subjects"),
        get("access_control/rules"),
        get("access_control/policies"),
    );
    let mine: Vec<&str> = subjects
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| {
            s["usernames"]
                .as_array()
                .is_none_or(|u| u.iter().any(|n| n == username))
        })
        .filter_map(|s| s["id"].as_str())
        .collect();
    let rule_ids: Vec<&str> = policies
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| {
            p["subjects"]
                .as_array()
                .unwrap()
                .iter()
                .any(|s| mine.contains(&s.as_str().unwrap()))
        })
        .flat_map(|p| p["rules"].as_array().unwrap().iter())
        .filter_map(|r| r.as_str())
        .collect();
    rules
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| rule_ids.contains(&r["id"].as_str().unwrap()))
        .filter(|r| {
            r["messages"]
                .as_array()
                .unwrap()
                .iter()
                .any(|m| m == message)
        })
        .filter(|r| r["flows"].as_array().unwrap().iter().any(|f| f == flow))
        .flat_map(|r| r["key_exprs"].as_array().unwrap().iter())
        .filter_map(|k| k.as_str().map(String::from))
        .collect()
}

/// The value after `flag` in `words`.
fn after<'a>(words: &'a [String], flag: &str) -> &'a str {
    &words[words
        .iter()
        .position(|w| w == flag)
        .unwrap_or_else(|| panic!("no {flag} in {words:?}"))
        + 1]
}

#[test]
#[allow(clippy::too_many_lines)] // One check per service of the compose file, in its order.
fn the_compose_file_wires_router_daemon_and_replay_safely() {
    let compose: Yaml = serde_yaml::from_str(&read("docker/compose.yaml")).expect("valid YAML");
    let services = &compose["services"];
    let image = image();
    let docker_dir = repo().join("docker");

    // The router: the official image, the Zenoh version of Cargo.lock, the
    // shipped access-controlled router configuration mounted where its
    // command reads it, its password dictionary in the secrets volume.
    let router = &services["router"];
    let router_image = router["image"].as_str().unwrap();
    assert_eq!(
        router_image,
        format!("eclipse/zenoh:{}", locked_zenoh_version())
    );
    let command = strings(&router["command"]);
    let config_in_container = after(&command, "-c");
    let router_mounts = strings(&router["volumes"]);
    let mount = router_mounts
        .iter()
        .find(|v| v.split(':').nth(1) == Some(config_in_container))
        .expect("the router's configuration is mounted");
    let host = mount.split(':').next().unwrap();
    let host_file = docker_dir.join(host).canonicalize().unwrap();
    assert_eq!(host_file, repo().join("config/zenoh-acl.json5"));
    let acl = zenoh::Config::from_file(&host_file).unwrap();
    assert_eq!(acl.get_json("access_control/enabled").unwrap(), "true");
    assert_eq!(
        acl.get_json("access_control/default_permission").unwrap(),
        "\"deny\""
    );
    let dictionary = after(&command, "--cfg")
        .strip_prefix("transport/auth/usrpwd/dictionary_file:")
        .expect("the dictionary is set")
        .trim_matches('"')
        .to_string();
    let secrets_volume = |mounts: &[String], path: &str| -> String {
        mounts
            .iter()
            .find(|v| {
                let target = v.split(':').nth(1).unwrap_or_default();
                path.starts_with(&format!("{target}/"))
            })
            .unwrap_or_else(|| panic!("{path} is on no volume of {mounts:?}"))
            .split(':')
            .next()
            .unwrap()
            .to_string()
    };
    let secrets = secrets_volume(&router_mounts, &dictionary);
    assert!(compose["volumes"].get(secrets.as_str()).is_some());
    let listen: Vec<String> =
        serde_json::from_str(&acl.get_json("listen/endpoints").unwrap()).unwrap();
    let router_port = listen[0].rsplit(':').next().unwrap();

    // The secrets service makes a log-in file per identity from the
    // shipped client file, on the same volume.
    let maker = &services["secrets"];
    let script = strings(&maker["command"]).join(" ");
    assert!(script.contains("config/zenoh-usrpwd.json5"), "{script}");
    assert!(repo().join("config/zenoh-usrpwd.json5").is_file());
    let made =
        |user: &str| script.contains(&format!(" {user} ")) || script.contains(&format!(" {user};"));

    // Our services: the image built from this Dockerfile, programs of it,
    // files that exist, the router by service name and port, each logged in
    // as an identity of the router's file that the secrets service makes.
    let mut volumes_used = Vec::new();
    let mut logins = Vec::new();
    for name in ["twind", "replay"] {
        let service = &services[name];
        let build = &service["build"];
        let context = docker_dir
            .join(build["context"].as_str().unwrap())
            .canonicalize()
            .unwrap();
        assert_eq!(context, repo(), "{name}: build context");
        assert!(
            context
                .join(build["dockerfile"].as_str().unwrap())
                .is_file()
        );
        let mut args = strings(&service["entrypoint"]);
        args.extend(strings(&service["command"]));
        // `sh -c "... && exec PROGRAM ARGS"`: the words after `exec`.
        let words: Vec<String> = if args.first().map(String::as_str) == Some("/bin/sh") {
            let script = args.last().unwrap();
            let after = script.split("exec ").nth(1).expect("exec in the script");
            after.split_whitespace().map(String::from).collect()
        } else {
            args
        };
        assert!(
            image.copied.contains(&words[0]),
            "{name} runs {}, not a binary of the image",
            words[0]
        );
        for w in &words {
            if w.starts_with("config/") || w.starts_with("data/") {
                assert!(
                    repo().join(w).is_file(),
                    "{name}: {w} is not in the repository"
                );
            }
        }
        assert_eq!(
            after(&words, "--connect"),
            format!("tcp/router:{router_port}"),
            "{name}"
        );
        let mounts = strings(&service["volumes"]);
        let login = after(&words, "--config");
        assert_eq!(secrets_volume(&mounts, login), secrets, "{name}");
        let user = std::path::Path::new(login)
            .file_stem()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        assert!(made(&user), "{name}: the secrets service makes no {user}");
        for v in mounts {
            volumes_used.push((name, v));
        }
        logins.push((name, user, words.clone()));
        println!("{name}: {}", words.join(" "));
    }
    // The daemon's identity may publish its statistics and the replayed
    // vessel's outputs; the replay's identity may put that vessel's inputs.
    let (_, daemon_user, daemon_words) = &logins[0];
    let (_, vessel_user, replay_words) = &logins[1];
    assert_eq!(after(daemon_words, "--id"), daemon_user);
    let vessel = after(replay_words, "--vessel");
    assert_eq!(vessel, vessel_user);
    let daemon_puts = acl_keys(&acl, daemon_user, "put", "ingress");
    assert!(
        daemon_puts.contains(&format!("asv/{vessel}/twin/**")),
        "{daemon_puts:?}"
    );
    assert!(daemon_puts.contains(&format!("asv/@twind/{daemon_user}/stats")));
    let vessel_puts = acl_keys(&acl, vessel_user, "put", "ingress");
    assert!(
        vessel_puts.contains(&format!("asv/{vessel}/gnss")),
        "{vessel_puts:?}"
    );
    assert!(vessel_puts.contains(&format!("asv/{vessel}/actuators")));

    // The daemon keeps its calibrations on a named volume.
    let twind_words = strings(&services["twind"]["command"]);
    let state_dir = after(&twind_words, "--state-dir");
    let (_, state_volume) = volumes_used
        .iter()
        .find(|(n, v)| *n == "twind" && v.split(':').nth(1) == Some(state_dir))
        .expect("the state directory is a volume");
    let volume_name = state_volume.split(':').next().unwrap();
    assert!(
        compose["volumes"].get(volume_name).is_some(),
        "{volume_name} is not a named volume of the file"
    );

    // The bridge: its sources are ones the bridge reads, and a UDP source's
    // port is the one the container publishes (as UDP).
    let bridge = &services["bridge"];
    let words = strings(&bridge["command"]);
    assert_eq!(words[0], "twin-bridge");
    let sources: Vec<twin_bridge::spec::SourceSpec> = words
        .windows(2)
        .filter(|w| w[0] == "--source")
        .map(|w| w[1].parse().expect("a source the bridge reads"))
        .collect();
    assert!(!sources.is_empty());
    let published = strings(&bridge["ports"]);
    for source in &sources {
        if let twin_bridge::spec::Transport::Udp { bind, .. } = source.transport {
            let port = format!(":{0}:{0}/udp", bind.port());
            assert!(
                published.iter().any(|p| p.ends_with(&port)),
                "{source}: UDP {} not published ({published:?})",
                bind.port()
            );
        }
    }
    assert!(
        words.windows(2).any(|w| w[0] == "--vessel"),
        "the bridge publishes as a vessel"
    );
}
