//! End-to-end replays over in-process Zenoh sessions on loopback: one session
//! replays, another collects `asv/{vessel}/**`, and what arrives is held
//! against what `FixAssembler` makes of the same log.

mod common;

use std::fs::File;
use std::io::{BufReader, Cursor};
use std::path::Path;
use std::time::Instant;

use common::*;
use twin_replay::{Progress, Rate, ReplayError, ReplayOptions, replay_log, replay_reader};
use twin_wire::VesselId;
use twin_wire::messages::{decode_actuators, decode_gnss};
use zenoh::Session;

fn options(vessel: &VesselId, rate: Rate) -> ReplayOptions {
    ReplayOptions {
        rate,
        ..ReplayOptions::new(vessel.clone())
    }
}

fn times_of(messages: &[Received]) -> Vec<f64> {
    messages
        .iter()
        .map(|(key, payload)| {
            if key.ends_with("/gnss") {
                let d = decode_gnss(payload).unwrap();
                assert!(d.replay, "{key}: not marked replay");
                d.value.time_s
            } else {
                let d = decode_actuators(payload).unwrap();
                assert!(d.replay, "{key}: not marked replay");
                match d.value {
                    twin_wire::ActuatorCommand::Speeds(s) => s.time_s,
                    twin_wire::ActuatorCommand::Thrust(t) => t.time_s,
                }
            }
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn replay_delivers_every_assembled_message_in_order_with_original_times() {
    let path = Path::new(REAL_LOGS).join("aava-n2k.data");
    let vessel = VesselId::new("aava").unwrap();
    let (expected, unencodable) = expected(
        BufReader::new(File::open(&path).unwrap()),
        &vessel,
        0.0,
        None,
    );
    assert!(expected.len() > 500, "{}", expected.len());

    let (_sub_session, collector, session) = subscriber_and_publisher(&vessel).await;
    let summary = replay_log(&session, &path, &options(&vessel, Rate::Max), |_| {})
        .await
        .unwrap();
    let received = collector.wait_for(expected.len()).await;

    assert_eq!(summary.published.total() as usize, expected.len());
    assert_eq!(
        (summary.skipped.gnss + summary.skipped.actuators) as usize,
        unencodable
    );
    assert_eq!(received.len(), expected.len(), "lost or extra messages");
    // Byte for byte, in order: the same keys, the same original times.
    for (i, (got, want)) in received.iter().zip(&expected).enumerate() {
        assert_eq!(got, want, "message {i} differs");
    }
    let times = times_of(&received);
    assert!(times.windows(2).all(|w| w[1] >= w[0]), "not in time order");
    assert_eq!(summary.first_published_s, times.first().copied());
    assert_eq!(summary.last_published_s, times.last().copied());
    assert_eq!(summary.passes, 1);
    assert!(!summary.interrupted);
    assert!(summary.read_stats.total_records() > 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn max_rate_plaka_delivers_all_7250_fixes() {
    let path = Path::new(REAL_LOGS).join("plaka.log");
    let vessel = VesselId::new("plaka").unwrap();
    let (expected, unencodable) = expected(
        BufReader::new(File::open(&path).unwrap()),
        &vessel,
        0.0,
        None,
    );
    // 7250 fixes; the last has no course (its VTG never came), so the
    // contract cannot carry it.
    assert_eq!(expected.len() + unencodable, 7250);

    let (_sub_session, collector, session) = subscriber_and_publisher(&vessel).await;
    let started = Instant::now();
    let summary = replay_log(&session, &path, &options(&vessel, Rate::Max), |_| {})
        .await
        .unwrap();
    let published_in = started.elapsed();
    let received = collector.wait_for(expected.len()).await;
    println!(
        "plaka.log at --rate max: {} messages published in {:.3} s ({:.3} s by the replay's own clock), {} received",
        summary.published.total(),
        published_in.as_secs_f64(),
        summary.wall.as_secs_f64(),
        received.len()
    );
    assert_eq!(summary.published.gnss as usize, expected.len());
    assert_eq!(summary.skipped.gnss as usize, unencodable);
    assert_eq!(received.len(), expected.len());
    assert!(
        received == expected,
        "received messages differ from the log's"
    );
    // A 4-hour log: the span is what was published, not the wall time.
    assert!(
        summary.log_span_s() > 3.5 * 3600.0,
        "{}",
        summary.log_span_s()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn ten_log_seconds_at_rate_ten_take_about_one_second() {
    let vessel = VesselId::new("pace").unwrap();
    let log = generated_log(20);
    let (expected, _) = expected(Cursor::new(log.clone()), &vessel, 2.02, Some(10.0));
    assert_eq!(expected.len(), 200);

    let (_sub_session, collector, session) = subscriber_and_publisher(&vessel).await;
    let options = ReplayOptions {
        start_offset_s: 2.02,
        duration_s: Some(10.0),
        ..options(&vessel, Rate::Factor(10.0))
    };
    let mut reports: Vec<Progress> = Vec::new();
    let started = Instant::now();
    let summary = replay_reader(&session, "generated", bytes(log), &options, |p| {
        reports.push(p.clone())
    })
    .await
    .unwrap();
    let wall = started.elapsed().as_secs_f64();
    println!("10 log seconds at rate 10: {wall:.3} s of wall time");
    assert!((0.7..3.0).contains(&wall), "took {wall} s");
    let received = collector.wait_for(expected.len()).await;
    assert_eq!(received, expected);
    // The last report is the final one: everything done.
    let last = reports.last().unwrap();
    assert_eq!(last.fraction, Some(1.0));
    assert_eq!(last.published, summary.published);
}

/// A daemon that subscribes after the replay has started (still starting
/// up) still gets the whole log: the replay waits for it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_subscriber_that_comes_late_gets_the_whole_log() {
    let vessel = VesselId::new("late").unwrap();
    let log = generated_log(3);
    let (expected, _) = expected(Cursor::new(log.clone()), &vessel, 0.0, None);
    let (sub_session, endpoint) = listening_session().await;
    let session = connected_session(&endpoint).await;
    let options = options(&vessel, Rate::Max);
    let replay = tokio::spawn(async move {
        replay_reader(&session, "generated", bytes(log), &options, |_| {}).await
    });
    tokio::time::sleep(std::time::Duration::from_millis(500)).await;
    let collector = Collector::new(&sub_session, "asv/late/**").await;
    let summary = replay.await.unwrap().unwrap();
    let received = collector.wait_for(expected.len()).await;
    assert_eq!(summary.published.total() as usize, expected.len());
    assert_eq!(received, expected);
}

/// With nobody subscribed the replay ends with an error that names the key,
/// having published nothing; a wait of 0 publishes regardless.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_no_subscriber_nothing_is_published_unless_asked() {
    let vessel = VesselId::new("alone").unwrap();
    let (_sub_session, endpoint) = listening_session().await;
    let session = connected_session(&endpoint).await;
    let waiting = ReplayOptions {
        wait_for_subscriber_s: 0.3,
        ..options(&vessel, Rate::Max)
    };
    let e = replay_reader(&session, "gen", bytes(generated_log(1)), &waiting, |_| {})
        .await
        .unwrap_err();
    assert!(matches!(e, ReplayError::NoSubscriber { .. }), "{e:?}");
    assert!(e.to_string().contains("asv/alone/gnss"), "{e}");
    let at_once = ReplayOptions {
        wait_for_subscriber_s: 0.0,
        ..waiting
    };
    let summary = replay_reader(&session, "gen", bytes(generated_log(1)), &at_once, |_| {})
        .await
        .unwrap();
    assert!(summary.published.gnss > 0, "{summary:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn start_and_duration_select_the_window() {
    let vessel = VesselId::new("window").unwrap();
    let log = generated_log(12);
    let (_sub_session, collector, session) = subscriber_and_publisher(&vessel).await;
    let options = ReplayOptions {
        start_offset_s: 3.02,
        duration_s: Some(4.0),
        ..options(&vessel, Rate::Max)
    };
    let summary = replay_reader(&session, "generated", bytes(log.clone()), &options, |_| {})
        .await
        .unwrap();
    let (expected, _) = expected(Cursor::new(log), &vessel, 3.02, Some(4.0));
    let received = collector.wait_for(expected.len()).await;
    assert_eq!(received, expected);
    // 4 s at 10 Hz of each: fixes at 3.1 .. 7.0 s, speeds at 3.05 .. 6.95 s.
    assert_eq!(
        (summary.published.gnss, summary.published.actuators),
        (40, 40)
    );
    let times = times_of(&received);
    let offsets: Vec<f64> = times.iter().map(|t| t - GENERATED_T0_S).collect();
    assert!((offsets[0] - 3.05).abs() < 1e-3, "{}", offsets[0]);
    assert!(
        (offsets[offsets.len() - 1] - 7.0).abs() < 1e-3,
        "{offsets:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn loop_two_publishes_the_log_twice() {
    let vessel = VesselId::new("loops").unwrap();
    let log = generated_log(2);
    let (once, _) = expected(Cursor::new(log.clone()), &vessel, 0.0, None);
    let (_sub_session, collector, session) = subscriber_and_publisher(&vessel).await;
    let options = ReplayOptions {
        loops: 2,
        ..options(&vessel, Rate::Max)
    };
    let summary = replay_reader(&session, "generated", bytes(log), &options, |_| {})
        .await
        .unwrap();
    let received = collector.wait_for(2 * once.len()).await;
    assert_eq!(summary.passes, 2);
    assert_eq!(summary.published.total() as usize, 2 * once.len());
    assert_eq!(received.len(), 2 * once.len());
    assert_eq!(&received[..once.len()], &once[..]);
    assert_eq!(&received[once.len()..], &once[..]);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unreadable_logs_are_errors_and_publish_nothing() {
    let vessel = VesselId::new("broken").unwrap();
    let (_sub_session, collector, session) = subscriber_and_publisher(&vessel).await;
    let options = options(&vessel, Rate::Max);

    let missing = Path::new(REAL_LOGS).join("no-such-log.data");
    let e = replay_log(&session, &missing, &options, |_| {})
        .await
        .unwrap_err();
    assert!(matches!(e, ReplayError::Open { .. }), "{e:?}");
    assert!(e.to_string().contains("no-such-log.data"), "{e}");

    let garbage = b"garbage\n".repeat(100);
    let e = replay_reader(&session, "garbage", bytes(garbage), &options, |_| {})
        .await
        .unwrap_err();
    assert!(
        matches!(
            e,
            ReplayError::Unreadable {
                source: twin_wire::read::OpenError::UnknownFormat,
                ..
            }
        ),
        "{e:?}"
    );
    let e = replay_reader(&session, "empty", bytes(Vec::new()), &options, |_| {})
        .await
        .unwrap_err();
    assert!(matches!(e, ReplayError::Unreadable { .. }), "{e:?}");

    let bad = ReplayOptions {
        duration_s: Some(-1.0),
        ..options.clone()
    };
    let e = replay_reader(&session, "gen", bytes(generated_log(1)), &bad, |_| {})
        .await
        .unwrap_err();
    assert!(
        matches!(
            e,
            ReplayError::InvalidOption {
                option: "duration",
                ..
            }
        ),
        "{e:?}"
    );

    tokio::time::sleep(std::time::Duration::from_millis(100)).await;
    assert_eq!(collector.len(), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn run_stops_on_shutdown_and_delivers_what_it_published() {
    let vessel = VesselId::new("stop").unwrap();
    let (sub_session, endpoint) = listening_session().await;
    let collector = Collector::new(&sub_session, "asv/stop/**").await;
    let path = scratch("stop.jsonl", &generated_log(20));
    let config = loopback("tcp/127.0.0.1:0", Some(&endpoint))
        .to_config()
        .unwrap();
    // At the recorded pace 20 s of log; stopped after about one.
    let shutdown = tokio::time::sleep(std::time::Duration::from_secs(1));
    let summary = twin_replay::run(
        config,
        &path,
        &options(&vessel, Rate::Factor(1.0)),
        |_| {},
        shutdown,
    )
    .await
    .unwrap();
    assert!(summary.interrupted);
    let published = summary.published.total() as usize;
    assert!((1..400).contains(&published), "{published}");
    // Closing the session flushed everything published.
    let received = collector.wait_for(published).await;
    assert_eq!(received.len(), published);
}

/// The daemon spawns replays on its runtime: the futures must be `Send`.
#[test]
fn replay_futures_are_send() {
    fn is_send<T: Send>(_: T) {}
    fn check(session: &Session, options: &ReplayOptions) {
        is_send(replay_log(session, Path::new("x"), options, |_| {}));
        is_send(replay_reader(
            session,
            "x",
            bytes(Vec::new()),
            options,
            |_| {},
        ));
    }
    let _ = check as fn(&Session, &ReplayOptions);
}
