//! `twin-bridge bench`: how many NMEA 0183 sentences a second the bridge
//! forwards on one core, from a UDP socket on loopback to Zenoh puts that
//! a second Zenoh peer on loopback receives. The traffic is a boat at 10 Hz
//! (RMC, GGA, VTG, HDT and two RPM sentences an epoch), one sentence a
//! datagram as a multiplexer sends them, as fast as the sender can. The
//! rate is the sentences the bridge decoded divided by the time from its
//! first to its last; datagrams the kernel dropped because the bridge was
//! behind are not counted (and are reported). Each run is a fresh bridge;
//! the median run is the figure.

use std::net::UdpSocket;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use twin_core::geodesy::LatLon;
use twin_core::sample::{GnssFix, Side};
use twin_wire::measurement::{FixMethod, Talker};
use twin_wire::write::nmea0183::{gga, hdt, rmc, rpm, vtg};
use twin_wire::{KeySpace, VesselId};
use zenoh::Wait;

use crate::output::ZenohOutputs;
use crate::pipeline::{Pipeline, PipelineConfig};
use crate::spec::{Format, NmeaPublish, SourceSpec};
use crate::stats::Counter;
use crate::transport::{self, Event};

/// The first epoch of the generated traffic (2026-08-03T04:27:20Z).
const T0_S: f64 = 1_785_731_240.0;

/// A boat on a 200 m circle at 2 m/s, 10 epochs a second, as NMEA 0183:
/// `epochs` x (RMC, GGA, VTG, HDT, RPM port, RPM starboard).
pub fn boat_sentences(epochs: usize) -> Vec<String> {
    let mut out = Vec::with_capacity(epochs * 6);
    let gp = Talker::GP;
    for k in 0..epochs {
        let t = T0_S + k as f64 * 0.1;
        let angle = k as f64 * 0.1 * 2.0 / 200.0;
        let fix = GnssFix {
            time_s: t,
            position: LatLon {
                lat_deg: 59.9 + 200.0 * angle.sin() / 111_320.0,
                lon_deg: 10.7 + 200.0 * (1.0 - angle.cos()) / 55_800.0,
            },
            sog_mps: Some(2.0),
            cog_rad: Some(angle),
            heading_rad: Some(angle),
            yaw_rate_radps: None,
            hdop: Some(0.8),
        };
        let sentences = [
            rmc(gp, &fix),
            gga(gp, &fix, FixMethod::Dgnss, Some(12), Some(40.0)),
            vtg(gp, fix.cog_rad, fix.sog_mps),
            hdt(gp, angle),
            rpm(gp, Side::Port, 120.0),
            rpm(gp, Side::Starboard, 118.0),
        ];
        out.extend(sentences.into_iter().filter_map(Result::ok));
    }
    out
}

/// One run's figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunFigures {
    /// Sentences sent.
    pub sent: u64,
    /// Sentences the bridge decoded.
    pub forwarded: u64,
    /// Messages the subscriber received.
    pub received: u64,
    /// Sentences decoded per second.
    pub sentences_per_s: f64,
}

/// The figures of every run and their median.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchReport {
    /// What was published: fixes or sentences.
    pub mode: NmeaPublish,
    /// Each run.
    pub runs: Vec<RunFigures>,
}

impl BenchReport {
    /// The median run's rate, sentences per second.
    pub fn median_sentences_per_s(&self) -> f64 {
        let mut rates: Vec<f64> = self.runs.iter().map(|r| r.sentences_per_s).collect();
        rates.sort_by(f64::total_cmp);
        rates.get(rates.len() / 2).copied().unwrap_or(0.0)
    }
}

fn free_port() -> std::io::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port())
}

fn loopback(listen: Option<u16>, connect: Option<u16>) -> anyhow::Result<zenoh::Config> {
    let args = twin_zenoh::ZenohArgs {
        mode: Some(twin_zenoh::Mode::Peer),
        listen: listen
            .map(|p| vec![format!("tcp/127.0.0.1:{p}")])
            .unwrap_or_default(),
        connect: connect
            .map(|p| vec![format!("tcp/127.0.0.1:{p}")])
            .unwrap_or_default(),
        no_multicast_scouting: true,
        ..twin_zenoh::ZenohArgs::default()
    };
    Ok(args.to_config()?)
}

fn one_run(sentences: &[String], mode: NmeaPublish) -> anyhow::Result<RunFigures> {
    let zenoh_port = free_port()?;
    let keys = KeySpace::default();
    let vessel = VesselId::new("bench")?;
    let receiver = zenoh::open(loopback(Some(zenoh_port), None)?)
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let received = Arc::new(AtomicU64::new(0));
    let count = received.clone();
    let _subscriber = receiver
        .declare_subscriber(format!("{}/{vessel}/*", keys.prefix()))
        .callback(move |_| {
            count.fetch_add(1, Ordering::Relaxed);
        })
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let session = zenoh::open(loopback(None, Some(zenoh_port))?)
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let probe = session
        .declare_publisher(keys.gnss(&vessel))
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let deadline = Instant::now() + Duration::from_secs(10);
    while !probe
        .matching_status()
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?
        .matching()
    {
        anyhow::ensure!(Instant::now() < deadline, "the subscriber never matched");
        std::thread::sleep(Duration::from_millis(10));
    }
    let outputs = Arc::new(
        ZenohOutputs::declare(&session, &keys, &vessel).map_err(|e| anyhow::anyhow!("{e}"))?,
    );

    let udp_port = UdpSocket::bind("127.0.0.1:0")?.local_addr()?.port();
    let spec: SourceSpec = format!("nmea0183:udp:127.0.0.1:{udp_port}").parse()?;
    let counter = Counter::new(&spec.name, "nmea0183", "udp");
    let config = crate::BridgeConfig::new(vessel.clone(), vec![spec.clone()]);
    let mut pipeline_config: PipelineConfig = crate::pipeline_config(&config, &spec);
    pipeline_config.nmea_publish = mode;
    let mut pipeline = Pipeline::new(
        Format::Nmea0183,
        pipeline_config,
        outputs,
        counter.clone(),
        false,
    );
    let stop = Arc::new(AtomicBool::new(false));
    let ready = Arc::new(AtomicBool::new(false));
    let span = Arc::new(Mutex::new((None::<Instant>, None::<Instant>)));
    let bridge = {
        let (stop, ready, span) = (stop.clone(), ready.clone(), span.clone());
        std::thread::spawn(move || {
            transport::run(&spec, &stop, &mut |event| match event {
                Event::Connected(_) => ready.store(true, Ordering::Relaxed),
                Event::Bytes {
                    bytes,
                    received_s,
                    datagram,
                } => {
                    pipeline.on_bytes(bytes, received_s, datagram);
                    let now = Instant::now();
                    let mut s = span.lock().unwrap_or_else(|e| e.into_inner());
                    s.0.get_or_insert(now);
                    s.1 = Some(now);
                }
                Event::Idle => pipeline.on_idle(Instant::now()),
                _ => {}
            })
        })
    };
    while !ready.load(Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(5));
    }
    let sender = UdpSocket::bind("127.0.0.1:0")?;
    for s in sentences {
        let mut datagram = s.clone().into_bytes();
        datagram.extend_from_slice(b"\r\n");
        sender.send_to(&datagram, ("127.0.0.1", udp_port))?;
    }
    // Wait until the bridge has been idle for half a second.
    loop {
        std::thread::sleep(Duration::from_millis(100));
        let last = span.lock().unwrap_or_else(|e| e.into_inner()).1;
        if last.is_some_and(|t| t.elapsed() > Duration::from_millis(500)) {
            break;
        }
    }
    stop.store(true, Ordering::Relaxed);
    bridge
        .join()
        .map_err(|_| anyhow::anyhow!("the bridge thread panicked"))??;
    std::thread::sleep(Duration::from_millis(200));
    let (first, last) = *span.lock().unwrap_or_else(|e| e.into_inner());
    let forwarded = counter.snapshot().lines;
    let seconds = match (first, last) {
        (Some(a), Some(b)) => (b - a).as_secs_f64().max(1e-9),
        _ => f64::INFINITY,
    };
    let figures = RunFigures {
        sent: sentences.len() as u64,
        forwarded,
        received: received.load(Ordering::Relaxed),
        sentences_per_s: forwarded as f64 / seconds,
    };
    drop(probe);
    session.close().wait().map_err(|e| anyhow::anyhow!("{e}"))?;
    receiver
        .close()
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(figures)
}

/// Runs the benchmark: `runs` fresh bridges, each sent `epochs` x 6
/// sentences.
pub fn bench(
    epochs: usize,
    runs: usize,
    mode: NmeaPublish,
    mut progress: impl FnMut(&RunFigures),
) -> anyhow::Result<BenchReport> {
    let sentences = boat_sentences(epochs);
    let mut report = BenchReport {
        mode,
        runs: Vec::new(),
    };
    for _ in 0..runs {
        let figures = one_run(&sentences, mode)?;
        progress(&figures);
        report.runs.push(figures);
    }
    Ok(report)
}
