//! systemd's service notifications (`sd_notify(3)`), written by hand: one
//! datagram per state on the Unix socket named by `$NOTIFY_SOCKET` (a path,
//! or `@name` in the abstract namespace). `READY=1` once the daemon serves,
//! `WATCHDOG=1` every half of `$WATCHDOG_USEC` from the daemon's run loop
//! after it has locked the dispatcher (so a dispatcher or a runtime that
//! hangs stops the pings and systemd restarts the service), `STOPPING=1`
//! when the shutdown begins. Without `$NOTIFY_SOCKET` (not under systemd,
//! or `Type=` other than `notify`) nothing is sent. A notification that
//! cannot be sent is logged once and never stops the daemon.

use std::os::unix::net::{SocketAddr, UnixDatagram};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Where the notifications go, and how often the watchdog wants one.
#[derive(Debug, Clone, Default)]
pub struct Notifier {
    target: Option<Arc<Target>>,
    watchdog: Option<Duration>,
}

#[derive(Debug)]
struct Target {
    socket: UnixDatagram,
    address: SocketAddr,
    warned: AtomicBool,
}

/// The socket address `$NOTIFY_SOCKET` names.
fn address_of(name: &str) -> std::io::Result<SocketAddr> {
    match name.strip_prefix('@') {
        Some(abstract_name) => {
            #[cfg(target_os = "linux")]
            {
                use std::os::linux::net::SocketAddrExt;
                SocketAddr::from_abstract_name(abstract_name.as_bytes())
            }
            #[cfg(not(target_os = "linux"))]
            {
                let _ = abstract_name;
                Err(std::io::Error::other("abstract sockets are Linux only"))
            }
        }
        None => SocketAddr::from_pathname(name),
    }
}

/// Half of `$WATCHDOG_USEC`, when the watchdog is this process's
/// (`$WATCHDOG_PID` unset or ours).
fn watchdog_interval(usec: Option<&str>, pid: Option<&str>) -> Option<Duration> {
    if let Some(pid) = pid
        && pid.parse::<u32>().ok() != Some(std::process::id())
    {
        return None;
    }
    let usec: u64 = usec?.parse().ok().filter(|u| *u > 0)?;
    Some(Duration::from_micros(usec / 2))
}

impl Notifier {
    /// Nothing is sent (the daemon in tests, the demo).
    pub fn disabled() -> Self {
        Self::default()
    }

    /// From systemd's environment (`$NOTIFY_SOCKET`, `$WATCHDOG_USEC`,
    /// `$WATCHDOG_PID`); disabled when there is no socket.
    pub fn from_env() -> Self {
        let var = |name| std::env::var(name).ok();
        let Some(name) = var("NOTIFY_SOCKET").filter(|n| !n.is_empty()) else {
            return Self::disabled();
        };
        let target = address_of(&name).and_then(|address| {
            Ok(Target {
                socket: UnixDatagram::unbound()?,
                address,
                warned: AtomicBool::new(false),
            })
        });
        match target {
            Ok(target) => Self {
                target: Some(Arc::new(target)),
                watchdog: watchdog_interval(
                    var("WATCHDOG_USEC").as_deref(),
                    var("WATCHDOG_PID").as_deref(),
                ),
            },
            Err(e) => {
                tracing::warn!("NOTIFY_SOCKET {name:?} unusable, systemd is not told: {e}");
                Self::disabled()
            }
        }
    }

    /// How often to send `WATCHDOG=1` (half the watchdog's timeout), if
    /// systemd watches.
    pub fn watchdog_interval(&self) -> Option<Duration> {
        self.target.as_ref().and(self.watchdog)
    }

    /// Sends one notification (`READY=1`, `WATCHDOG=1`, `STOPPING=1`...).
    pub fn notify(&self, state: &str) {
        let Some(t) = &self.target else {
            return;
        };
        if let Err(e) = t.socket.send_to_addr(state.as_bytes(), &t.address)
            && !t.warned.swap(true, Ordering::Relaxed)
        {
            tracing::warn!("cannot tell systemd {state:?} (further failures not logged): {e}");
        }
    }

    /// `READY=1`: the daemon serves.
    pub fn ready(&self) {
        self.notify("READY=1\nSTATUS=serving");
    }

    /// `WATCHDOG=1`: the daemon is alive.
    pub fn watchdog(&self) {
        self.notify("WATCHDOG=1");
    }

    /// `STOPPING=1`: the shutdown has begun.
    pub fn stopping(&self) {
        self.notify("STOPPING=1\nSTATUS=draining the vessels");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_watchdog_pings_at_half_its_timeout_and_only_for_its_own_process() {
        let ours = std::process::id().to_string();
        assert_eq!(
            watchdog_interval(Some("10000000"), None),
            Some(Duration::from_secs(5))
        );
        assert_eq!(
            watchdog_interval(Some("400000"), Some(&ours)),
            Some(Duration::from_millis(200))
        );
        assert_eq!(watchdog_interval(Some("400000"), Some("1")), None);
        assert_eq!(watchdog_interval(Some("0"), None), None);
        assert_eq!(watchdog_interval(Some("soon"), None), None);
        assert_eq!(watchdog_interval(None, None), None);
    }

    #[test]
    fn a_notification_arrives_on_the_named_socket() {
        let dir = std::env::temp_dir().join(format!("twind-notify-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("notify.sock");
        let _ = std::fs::remove_file(&path);
        let listener = UnixDatagram::bind(&path).unwrap();
        let n = Notifier {
            target: Some(Arc::new(Target {
                socket: UnixDatagram::unbound().unwrap(),
                address: address_of(path.to_str().unwrap()).unwrap(),
                warned: AtomicBool::new(false),
            })),
            watchdog: None,
        };
        n.ready();
        let mut buf = [0u8; 256];
        let len = listener.recv(&mut buf).unwrap();
        assert_eq!(&buf[..len], b"READY=1\nSTATUS=serving");
        assert!(Notifier::disabled().watchdog_interval().is_none());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
