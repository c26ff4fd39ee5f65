//! Reading a source: UDP (unicast, broadcast, multicast), a TCP client
//! that reconnects, a serial port that is reopened when it disappears,
//! standard input, a SocketCAN interface. Each runs on its own thread with
//! blocking reads that time out every [`TICK`], so that it notices a stop
//! and tells its pipeline that time passes ([`Event::Idle`]).
//!
//! # Faults
//! Nothing a source does stops the bridge: a refused or lost connection, a
//! port that cannot be opened, a device that is unplugged, are reported
//! ([`Event::Disconnected`], with a reason) and retried with a backoff from
//! 0.25 s doubling to 10 s, back to 0.25 s once data flows again. A TCP
//! peer or serial port silent for [`SILENCE`] is taken as gone (a peer
//! that lost power sends no FIN) and reconnected. Only standard input ends.

use std::io::{self, Read, Write};
use std::net::{IpAddr, Ipv4Addr, TcpStream, ToSocketAddrs, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crate::spec::{Format, SourceSpec, Transport};

/// How often a blocked read wakes up.
pub const TICK: Duration = Duration::from_millis(100);

/// A connected source silent this long is reconnected.
pub const SILENCE: Duration = Duration::from_secs(30);

/// The first wait before retrying, and the longest.
pub const BACKOFF: (Duration, Duration) = (Duration::from_millis(250), Duration::from_secs(10));

/// The UDP receive buffer asked for (the kernel may grant less): a burst
/// must not overflow it while a put is under way.
pub const UDP_RECEIVE_BUFFER_BYTES: usize = 4 << 20;

/// What gpsd is asked for on connecting.
pub const GPSD_WATCH: &[u8] = b"?WATCH={\"enable\":true,\"json\":true};\n";

/// What a source does.
#[derive(Debug)]
pub enum Event<'a> {
    /// Connected (or bound, or opened); the text says to what.
    Connected(String),
    /// The connection was refused or lost.
    Disconnected {
        /// A short reason: `bind_failed`, `connect_failed`, `closed`,
        /// `silent`, `open_failed`, `io`.
        reason: &'static str,
        /// What happened.
        detail: String,
    },
    /// Bytes received at `received_s`.
    Bytes {
        /// The bytes.
        bytes: &'a [u8],
        /// Seconds since the epoch.
        received_s: f64,
        /// A whole datagram.
        datagram: bool,
    },
    /// A CAN frame received at `received_s`.
    CanFrame {
        /// The CAN id (29 bits when extended).
        id: u32,
        /// An extended (29-bit) frame.
        extended: bool,
        /// Its data.
        data: &'a [u8],
        /// Seconds since the epoch.
        received_s: f64,
    },
    /// Nothing arrived for a [`TICK`].
    Idle,
}

/// Why a source cannot run at all.
#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    /// SocketCAN exists only on Linux.
    #[error("a SocketCAN interface ({0}) can only be read on Linux")]
    NoSocketCan(String),
}

/// Waits, doubling, between retries.
struct Backoff {
    next: Duration,
}

impl Backoff {
    fn new() -> Self {
        Self { next: BACKOFF.0 }
    }

    fn reset(&mut self) {
        self.next = BACKOFF.0;
    }

    /// Sleeps the current wait (returns early on stop); false on stop.
    fn wait(&mut self, stop: &AtomicBool) -> bool {
        let until = Instant::now() + self.next;
        self.next = (self.next * 2).min(BACKOFF.1);
        while Instant::now() < until {
            if stop.load(Ordering::Relaxed) {
                return false;
            }
            std::thread::sleep(TICK.min(until.saturating_duration_since(Instant::now())));
        }
        !stop.load(Ordering::Relaxed)
    }
}

fn timed_out(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
    )
}

/// Reads `spec` until `stop` is set or the input ends, telling `on` what
/// happens.
pub fn run(
    spec: &SourceSpec,
    stop: &AtomicBool,
    on: &mut dyn FnMut(Event<'_>),
) -> Result<(), TransportError> {
    match &spec.transport {
        Transport::Udp { bind, group } => {
            udp(*bind, *group, stop, on);
            Ok(())
        }
        Transport::Tcp { address } => {
            let hello = (spec.format == Format::Gpsd).then_some(GPSD_WATCH);
            tcp(address, hello, stop, on);
            Ok(())
        }
        Transport::Serial { path, baud } => {
            serial(&path.to_string_lossy(), *baud, stop, on);
            Ok(())
        }
        Transport::Stdin => {
            stdin(stop, on);
            Ok(())
        }
        Transport::Can { interface } => can(interface, stop, on),
    }
}

fn udp_socket(bind: std::net::SocketAddr, group: Option<IpAddr>) -> io::Result<UdpSocket> {
    use socket2::{Domain, Protocol, Socket, Type};
    let socket = Socket::new(Domain::for_address(bind), Type::DGRAM, Some(Protocol::UDP))?;
    // Other programs on the boat's computer (a chart plotter) listen on
    // the same port.
    socket.set_reuse_address(true)?;
    let _ = socket.set_recv_buffer_size(UDP_RECEIVE_BUFFER_BYTES);
    socket.bind(&bind.into())?;
    match group {
        Some(IpAddr::V4(g)) => socket.join_multicast_v4(&g, &Ipv4Addr::UNSPECIFIED)?,
        Some(IpAddr::V6(g)) => socket.join_multicast_v6(&g, 0)?,
        None => {}
    }
    socket.set_read_timeout(Some(TICK))?;
    Ok(socket.into())
}

fn udp(
    bind: std::net::SocketAddr,
    group: Option<IpAddr>,
    stop: &AtomicBool,
    on: &mut dyn FnMut(Event<'_>),
) {
    let mut backoff = Backoff::new();
    let mut buf = vec![0u8; 65_536];
    while !stop.load(Ordering::Relaxed) {
        let socket = match udp_socket(bind, group) {
            Ok(s) => s,
            Err(e) => {
                on(Event::Disconnected {
                    reason: "bind_failed",
                    detail: format!("cannot listen on udp {bind}: {e}"),
                });
                if !backoff.wait(stop) {
                    return;
                }
                continue;
            }
        };
        on(Event::Connected(format!("listening on udp {bind}")));
        while !stop.load(Ordering::Relaxed) {
            match socket.recv_from(&mut buf) {
                Ok((n, _)) => {
                    backoff.reset();
                    on(Event::Bytes {
                        bytes: &buf[..n],
                        received_s: crate::now_s(),
                        datagram: true,
                    });
                }
                Err(e) if timed_out(&e) => on(Event::Idle),
                Err(e) => {
                    on(Event::Disconnected {
                        reason: "io",
                        detail: format!("udp {bind}: {e}"),
                    });
                    if !backoff.wait(stop) {
                        return;
                    }
                    break;
                }
            }
        }
    }
}

/// Reads a connected stream until it closes, errs, goes silent or `stop`.
fn stream(
    reader: &mut dyn Read,
    what: &str,
    stop: &AtomicBool,
    backoff: &mut Backoff,
    on: &mut dyn FnMut(Event<'_>),
) {
    let mut buf = vec![0u8; 16_384];
    let mut last_data = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        match reader.read(&mut buf) {
            Ok(0) => {
                on(Event::Disconnected {
                    reason: "closed",
                    detail: format!("{what} closed"),
                });
                return;
            }
            Ok(n) => {
                backoff.reset();
                last_data = Instant::now();
                on(Event::Bytes {
                    bytes: &buf[..n],
                    received_s: crate::now_s(),
                    datagram: false,
                });
            }
            Err(e) if timed_out(&e) => {
                if last_data.elapsed() >= SILENCE {
                    on(Event::Disconnected {
                        reason: "silent",
                        detail: format!("{what} sent nothing for {} s", SILENCE.as_secs()),
                    });
                    return;
                }
                on(Event::Idle);
            }
            Err(e) => {
                on(Event::Disconnected {
                    reason: "io",
                    detail: format!("{what}: {e}"),
                });
                return;
            }
        }
    }
}

fn connect(address: &str) -> io::Result<TcpStream> {
    let mut last = io::Error::new(io::ErrorKind::NotFound, "no address");
    for addr in address.to_socket_addrs()? {
        match TcpStream::connect_timeout(&addr, Duration::from_secs(3)) {
            Ok(s) => return Ok(s),
            Err(e) => last = e,
        }
    }
    Err(last)
}

fn tcp(address: &str, hello: Option<&[u8]>, stop: &AtomicBool, on: &mut dyn FnMut(Event<'_>)) {
    let mut backoff = Backoff::new();
    while !stop.load(Ordering::Relaxed) {
        let connected = connect(address).and_then(|mut s| {
            s.set_read_timeout(Some(TICK))?;
            s.set_nodelay(true)?;
            if let Some(hello) = hello {
                s.write_all(hello)?;
            }
            Ok(s)
        });
        match connected {
            Ok(mut s) => {
                on(Event::Connected(format!("connected to tcp {address}")));
                stream(&mut s, &format!("tcp {address}"), stop, &mut backoff, on);
            }
            Err(e) => on(Event::Disconnected {
                reason: "connect_failed",
                detail: format!("cannot connect to tcp {address}: {e}"),
            }),
        }
        if !backoff.wait(stop) {
            return;
        }
    }
}

fn serial(path: &str, baud: u32, stop: &AtomicBool, on: &mut dyn FnMut(Event<'_>)) {
    let mut backoff = Backoff::new();
    while !stop.load(Ordering::Relaxed) {
        match serialport::new(path, baud).timeout(TICK).open() {
            Ok(mut port) => {
                on(Event::Connected(format!("opened {path} at {baud} baud")));
                stream(&mut port, path, stop, &mut backoff, on);
            }
            Err(e) => on(Event::Disconnected {
                reason: "open_failed",
                detail: format!("cannot open {path}: {e}"),
            }),
        }
        if !backoff.wait(stop) {
            return;
        }
    }
}

fn stdin(stop: &AtomicBool, on: &mut dyn FnMut(Event<'_>)) {
    let (tx, rx) = mpsc::sync_channel::<Vec<u8>>(64);
    // Reading stdin cannot time out: a thread of its own blocks on it.
    std::thread::Builder::new()
        .name("twin-bridge-stdin".into())
        .spawn(move || {
            let mut input = io::stdin().lock();
            let mut buf = vec![0u8; 65_536];
            loop {
                match input.read(&mut buf) {
                    Ok(0) | Err(_) => return,
                    Ok(n) => {
                        if tx.send(buf[..n].to_vec()).is_err() {
                            return;
                        }
                    }
                }
            }
        })
        .map(drop)
        .unwrap_or_else(|e| tracing::error!("cannot read stdin: {e}"));
    on(Event::Connected("reading stdin".into()));
    while !stop.load(Ordering::Relaxed) {
        match rx.recv_timeout(TICK) {
            Ok(bytes) => on(Event::Bytes {
                bytes: &bytes,
                received_s: crate::now_s(),
                datagram: false,
            }),
            Err(mpsc::RecvTimeoutError::Timeout) => on(Event::Idle),
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                on(Event::Disconnected {
                    reason: "closed",
                    detail: "stdin closed".into(),
                });
                return;
            }
        }
    }
}

#[cfg(target_os = "linux")]
fn can(
    interface: &str,
    stop: &AtomicBool,
    on: &mut dyn FnMut(Event<'_>),
) -> Result<(), TransportError> {
    use socketcan::{CanFrame, CanSocket, EmbeddedFrame, Frame, Socket};
    let mut backoff = Backoff::new();
    while !stop.load(Ordering::Relaxed) {
        let socket = CanSocket::open(interface).and_then(|s| {
            s.set_read_timeout(TICK)?;
            Ok(s)
        });
        match socket {
            Ok(socket) => {
                on(Event::Connected(format!(
                    "reading CAN interface {interface}"
                )));
                while !stop.load(Ordering::Relaxed) {
                    match socket.read_frame() {
                        Ok(CanFrame::Data(frame)) => {
                            backoff.reset();
                            on(Event::CanFrame {
                                id: frame.raw_id(),
                                extended: frame.is_extended(),
                                data: frame.data(),
                                received_s: crate::now_s(),
                            });
                        }
                        // Remote and error frames carry no NMEA 2000 data:
                        // passed on as non-extended, counted as ignored.
                        Ok(_) => on(Event::CanFrame {
                            id: 0,
                            extended: false,
                            data: &[],
                            received_s: crate::now_s(),
                        }),
                        Err(e) if timed_out(&e) => on(Event::Idle),
                        Err(e) => {
                            on(Event::Disconnected {
                                reason: "io",
                                detail: format!("CAN interface {interface}: {e}"),
                            });
                            break;
                        }
                    }
                }
            }
            Err(e) => on(Event::Disconnected {
                reason: "open_failed",
                detail: format!("cannot open CAN interface {interface}: {e}"),
            }),
        }
        if !backoff.wait(stop) {
            return Ok(());
        }
    }
    Ok(())
}

#[cfg(not(target_os = "linux"))]
fn can(
    interface: &str,
    _stop: &AtomicBool,
    _on: &mut dyn FnMut(Event<'_>),
) -> Result<(), TransportError> {
    Err(TransportError::NoSocketCan(interface.to_owned()))
}
