//! The plumbing of `twin-bench daemon`, not its speed: a small fleet
//! (3 vessels x 5 Hz) through twind in-process over Zenoh on loopback for a
//! one-second window, and the same straight through Zenoh. Every vessel's
//! messages must come back, none lost, none refused by the daemon, and every
//! latency must be positive and finite. No figure of speed is asserted here
//! (ARCHITECTURE.md: speed figures live in benchmarks, never in tests).

use twin_bench::daemon::load::{Path, PointResult, PointSpec, measure};

fn spec(path: Path) -> PointSpec {
    PointSpec {
        path,
        vessels: 3,
        rate_hz: Some(5.0),
        warmup_s: 0.5,
        window_s: 1.0,
        // Generous: a loaded machine must not fail the test.
        grace_s: 2.0,
        vessel_liveliness: true,
        liveliness_outside_prefix: false,
    }
}

fn check_common(r: &PointResult) {
    // 3 vessels x 5 Hz over 1 s: about 15 fixes in the window.
    assert!(r.fixes_sent >= 6, "{} fixes sent", r.fixes_sent);
    assert_eq!(r.per_vessel_delivered.len(), 3);
    assert!(
        r.per_vessel_delivered.iter().all(|&d| d > 0),
        "every vessel's messages came back: {:?}",
        r.per_vessel_delivered
    );
    assert_eq!(r.vessels_delivered, 3);
    assert_eq!(
        r.delivered, r.fixes_sent,
        "every fix sent in the window came back"
    );
    assert_eq!(r.lost(), 0);
    assert_eq!(r.unparsable, 0);
    let l = &r.latency;
    assert_eq!(l.count, r.delivered);
    let (min, p50, p99, max) = (
        l.min_ns.unwrap(),
        l.p50_ns.unwrap(),
        l.p99_ns.unwrap(),
        l.max_ns.unwrap(),
    );
    assert!(min > 0, "latency {min} ns");
    assert!(min <= p50 && p50 <= p99 && p99 <= max, "{l:?}");
    assert!(l.mean_ns.unwrap().is_finite());
    // Finite: under a minute, whatever the machine does.
    assert!(max < 60_000_000_000, "{l:?}");
    assert!(r.gnss_bytes_mean > 50.0 && r.actuators_bytes_mean > 30.0);
}

#[test]
fn a_small_fleet_through_the_daemon_comes_back_whole() {
    let r = measure(&spec(Path::Daemon)).unwrap();
    check_common(&r);
    assert_eq!(r.repeats, 0, "no stale republication within the window");
    let daemon = r.daemon.as_ref().expect("the daemon's counters");
    assert!(
        daemon.rejected.is_empty(),
        "the generator's messages are all valid: {:?}",
        daemon.rejected
    );
    assert!(daemon.accepted.get("gnss").copied().unwrap_or(0) >= r.fixes_sent);
    assert!(daemon.accepted.get("actuators").copied().unwrap_or(0) >= r.actuators_sent);
    // A fault payload is larger than the fix that produced it.
    assert!(r.received_bytes_mean > r.gnss_bytes_mean);
    // The forecasts are counted (how many depends on the idle CPU time).
    assert!(
        r.forecasts_per_s.is_some_and(|f| f.is_finite() && f >= 0.0),
        "{:?}",
        r.forecasts_per_s
    );
}

#[test]
fn a_small_fleet_straight_through_zenoh_comes_back_whole() {
    let r = measure(&spec(Path::Raw)).unwrap();
    check_common(&r);
    assert!(r.daemon.is_none());
    assert!(r.forecasts_per_s.is_none(), "no daemon, no forecasts");
    // Raw: the subscriber receives the fixes themselves.
    assert!((r.received_bytes_mean - r.gnss_bytes_mean).abs() < 2.0);
}
