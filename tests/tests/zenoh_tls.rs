//! TLS with the shipped `config/zenoh-tls.json5` (TLS only, mutual
//! authentication): a throwaway certificate authority and certificates are
//! made at run time with `rcgen` (nothing secret is committed), a router
//! listens on `tls/127.0.0.1:PORT`, and the daemon (`twind::run`), a vessel's
//! publisher and an operator connect as clients, every one with the same file
//! and only its paths, mode and endpoints replaced.
//!
//! What it shows:
//! - a GNSS fix published over TLS goes through the daemon: its state comes
//!   out, over TLS, to the operator;
//! - a session that trusts another CA, one that presents no client
//!   certificate, one whose certificate another CA signed, and a plain-TCP
//!   session cannot connect to the router.

use std::net::{IpAddr, Ipv4Addr};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rcgen::{
    BasicConstraints, CertificateParams, CertifiedIssuer, DnType, ExtendedKeyUsagePurpose, IsCa,
    KeyPair, KeyUsagePurpose, SanType,
};
use serde_json::Value;
use tokio_util::sync::CancellationToken;
use twin_tests::net::free_port;
use twin_tests::wire::wait_matching;
use twin_wire::messages::{GnssMessage, TimeSource};
use twind::settings::Settings;
use zenoh::Session;

/// Throwaway PKI material in a temporary directory, removed on drop: a CA
/// and, per name, a certificate and key signed by it (`{name}.pem`,
/// `{name}-key.pem`), valid for `localhost` and 127.0.0.1.
struct Pki {
    dir: PathBuf,
}

impl Pki {
    fn new(dir: &Path, ca_name: &str, names: &[&str]) -> Self {
        std::fs::create_dir_all(dir).unwrap();
        let mut ca_params = CertificateParams::new(Vec::<String>::new()).unwrap();
        ca_params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
        ca_params
            .distinguished_name
            .push(DnType::CommonName, ca_name);
        ca_params.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
        let ca = CertifiedIssuer::self_signed(ca_params, KeyPair::generate().unwrap()).unwrap();
        std::fs::write(dir.join("ca.pem"), ca.pem()).unwrap();
        for name in names {
            let mut p = CertificateParams::new(vec!["localhost".to_string()]).unwrap();
            p.subject_alt_names
                .push(SanType::IpAddress(IpAddr::V4(Ipv4Addr::LOCALHOST)));
            p.distinguished_name.push(DnType::CommonName, *name);
            p.key_usages = vec![KeyUsagePurpose::DigitalSignature];
            p.extended_key_usages = vec![
                ExtendedKeyUsagePurpose::ServerAuth,
                ExtendedKeyUsagePurpose::ClientAuth,
            ];
            let key = KeyPair::generate().unwrap();
            let cert = p.signed_by(&key, &ca).unwrap();
            std::fs::write(dir.join(format!("{name}.pem")), cert.pem()).unwrap();
            std::fs::write(dir.join(format!("{name}-key.pem")), key.serialize_pem()).unwrap();
        }
        Self {
            dir: dir.to_path_buf(),
        }
    }

    fn path(&self, file: &str) -> String {
        self.dir.join(file).to_string_lossy().into_owned()
    }
}

impl Drop for Pki {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn json(v: impl Into<Value>) -> String {
    v.into().to_string()
}

/// `config/zenoh-tls.json5` for the node `name` of `pki` (its certificate
/// and key on both sides, `pki`'s CA as the root), in `mode`, listening on
/// or connecting to `tls/127.0.0.1:port`. Clients try once.
fn tls(pki: &Pki, name: &str, mode: &str, port: u16) -> zenoh::Config {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config/zenoh-tls.json5");
    let mut c = zenoh::Config::from_file(file).unwrap();
    let endpoint = format!("tls/127.0.0.1:{port}");
    let set = |c: &mut zenoh::Config, key: &str, value: String| {
        c.insert_json5(key, &value)
            .unwrap_or_else(|e| panic!("{key} = {value}: {e}"))
    };
    set(&mut c, "mode", json(mode));
    if mode == "client" {
        set(&mut c, "listen/endpoints", "[]".into());
        set(&mut c, "connect/endpoints", json(vec![endpoint]));
        set(&mut c, "connect/timeout_ms", "0".into());
        set(&mut c, "connect/exit_on_failure", "true".into());
    } else {
        set(&mut c, "listen/endpoints", json(vec![endpoint]));
    }
    set(&mut c, "scouting/gossip/enabled", "false".into());
    let tls = "transport/link/tls";
    set(
        &mut c,
        &format!("{tls}/root_ca_certificate"),
        json(pki.path("ca.pem")),
    );
    for side in ["listen", "connect"] {
        set(
            &mut c,
            &format!("{tls}/{side}_certificate"),
            json(pki.path(&format!("{name}.pem"))),
        );
        set(
            &mut c,
            &format!("{tls}/{side}_private_key"),
            json(pki.path(&format!("{name}-key.pem"))),
        );
    }
    c
}

fn fix(i: usize) -> Vec<u8> {
    let t_ms = 200 * i as u64;
    serde_json::to_vec(&GnssMessage {
        time: format!("2024-06-01T12:00:{:02}.{:03}Z", t_ms / 1000, t_ms % 1000),
        lat_deg: 59.9 + i as f64 * 0.2 / 111_320.0,
        lon_deg: 10.7,
        sog_mps: 1.0,
        cog_rad: 0.0,
        heading_rad: Some(0.0),
        hdop: Some(0.8),
        replay: false,
        time_source: TimeSource::Source,
    })
    .unwrap()
}

async fn refused(what: &str, config: zenoh::Config) {
    let result = tokio::time::timeout(Duration::from_secs(20), zenoh::open(config))
        .await
        .unwrap_or_else(|_| panic!("{what}: no answer"));
    match result {
        Ok(s) => {
            s.close().await.unwrap();
            panic!("{what}: a session was opened");
        }
        Err(e) => println!("{what}: refused ({e})"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fix_goes_through_the_daemon_over_tls_and_strangers_stay_out() {
    let root = std::env::temp_dir().join(format!("twin-zenoh-tls-{}", std::process::id()));
    let fleet = Pki::new(
        &root.join("fleet"),
        "throwaway fleet CA",
        &["router", "twind", "otter-1", "operator"],
    );
    let stranger = Pki::new(
        &root.join("stranger"),
        "throwaway stranger CA",
        &["mallory"],
    );
    let port = free_port();

    let router = zenoh::open(tls(&fleet, "router", "router", port))
        .await
        .unwrap();
    let daemon: Session = zenoh::open(tls(&fleet, "twind", "client", port))
        .await
        .unwrap();
    let vessel = zenoh::open(tls(&fleet, "otter-1", "client", port))
        .await
        .unwrap();
    let operator = zenoh::open(tls(&fleet, "operator", "client", port))
        .await
        .unwrap();
    for s in [&daemon, &vessel, &operator] {
        let links = s.info().routers_zid().await.count();
        assert_eq!(links, 1, "every client is linked to the router");
    }

    let cancel = CancellationToken::new();
    let handle = tokio::spawn(twind::run(twind::RunConfig::new(
        Settings::default(),
        daemon.clone(),
        cancel.clone(),
    )));
    let states = operator
        .declare_subscriber("asv/*/twin/state")
        .await
        .unwrap();
    let gnss = vessel.declare_publisher("asv/otter-1/gnss").await.unwrap();
    wait_matching(&gnss, Duration::from_secs(10)).await;
    let started = Instant::now();
    for i in 0..5 {
        gnss.put(fix(i)).await.unwrap();
    }
    let sample = tokio::time::timeout(Duration::from_secs(10), states.recv_async())
        .await
        .expect("a state over TLS")
        .unwrap();
    let state: Value = serde_json::from_slice(&sample.payload().to_bytes()).unwrap();
    println!(
        "over TLS: asv/otter-1/gnss -> {} in {:.0} ms: {state}",
        sample.key_expr(),
        started.elapsed().as_secs_f64() * 1e3
    );
    assert_eq!(sample.key_expr().as_str(), "asv/otter-1/twin/state");
    assert_eq!(state["vessel"], "otter-1");

    // Strangers.
    refused(
        "trusting another CA",
        tls(&stranger, "mallory", "client", port),
    )
    .await;
    let mut no_cert = tls(&fleet, "operator", "client", port);
    for key in ["enable_mtls", "connect_certificate", "connect_private_key"] {
        let value = if key == "enable_mtls" {
            "false"
        } else {
            "null"
        };
        no_cert
            .insert_json5(&format!("transport/link/tls/{key}"), value)
            .unwrap();
    }
    refused("no client certificate", no_cert).await;
    let mut foreign_cert = tls(&fleet, "operator", "client", port);
    foreign_cert
        .insert_json5(
            "transport/link/tls/connect_certificate",
            &json(stranger.path("mallory.pem")),
        )
        .unwrap();
    foreign_cert
        .insert_json5(
            "transport/link/tls/connect_private_key",
            &json(stranger.path("mallory-key.pem")),
        )
        .unwrap();
    refused("a client certificate from another CA", foreign_cert).await;
    let mut plain = twin_tests::net::config("client", &[], &[port]);
    plain.insert_json5("connect/timeout_ms", "0").unwrap();
    refused("plain TCP", plain).await;

    cancel.cancel();
    let summary = tokio::time::timeout(Duration::from_secs(20), handle)
        .await
        .unwrap()
        .unwrap()
        .unwrap();
    assert_eq!(summary.vessels["otter-1"].total_rejected(), 0);
    for s in [daemon, vessel, operator, router] {
        s.close().await.unwrap();
    }
    drop((fleet, stranger));
    let _ = std::fs::remove_dir_all(&root);
}
