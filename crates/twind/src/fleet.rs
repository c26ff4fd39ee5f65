//! Several daemons sharing a fleet (`[fleet] enabled`): who is the active
//! owner of each vessel, and the fleet's report of overlaps and gaps.
//!
//! # Election
//! Every daemon of the fleet holds one Zenoh liveliness token,
//! `{fleet}/daemon/{id}/{priority}/{start_ms}/{share}` (`{share}` is the
//! daemon's `[vessels] own` with `%`, `$` and `*` percent-encoded), and
//! watches the others' (a liveliness query at start, then a liveliness
//! subscriber). The active owner of a vessel is, among the live daemons
//! whose share covers it, the one with the smallest `(priority, start_ms,
//! id)`: every daemon reads the same keys and so computes the same owner,
//! with no message exchanged. A daemon that starts later is younger: it
//! becomes a standby, and does not take vessels back from an older daemon
//! that learnt them meanwhile (a restarted daemon does not pre-empt).
//!
//! Every daemon whose share covers a vessel runs the vessel's twin (it
//! receives the same inputs: a hot standby); only the active owner publishes
//! the vessel's outputs, holds its `twin/alive` token and answers its
//! queries. When an owner's token goes (its process ended, its session
//! closed, or its link's lease expired), the next daemon in the order
//! publishes the vessel's state and fault at once, from the twin it kept.
//!
//! Declarations are O(daemons): one token per daemon, not per vessel.
//!
//! # Failure modes
//! - A process killed or a machine switched off: the router drops the
//!   token when the link closes (at once for a killed process, whose socket
//!   the kernel closes) or when the link's lease expires (Zenoh's
//!   `transport/link/tx/lease`, 10 s by default: set it to a few seconds for
//!   a takeover within 5 s of a machine's loss, docs/deploy.md).
//! - A network partition: each side sees only its own daemons and each
//!   elects an owner (split brain); both publish. Every output a fleet
//!   daemon publishes carries its daemon id as the Zenoh attachment
//!   `daemon=<id>`, and each daemon's report names its members, so a
//!   consumer can tell the two apart. When the partition heals, the owners
//!   agree again within one liveliness update.
//! - A share no live daemon covers: the vessels of the roster
//!   (`[fleet] roster`) without an owner are named in every report (a gap).
//! - Overlapping shares: allowed (that is how a standby is made), and named
//!   in every report.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, RwLock};
use std::time::Duration;

use serde::{Deserialize, Serialize};
use tokio::sync::watch;
use tokio_util::sync::CancellationToken;
use zenoh::Session;
use zenoh::bytes::Encoding;
use zenoh::key_expr::KeyExpr;
use zenoh::sample::SampleKind;

use crate::settings::SettingsError;

/// `[fleet]` as read from the file.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawFleet {
    enabled: Option<bool>,
    priority: Option<u32>,
    prefix: Option<String>,
    roster: Option<Vec<String>>,
    report_interval_s: Option<f64>,
    join_wait_s: Option<f64>,
    share_calibrations: Option<bool>,
    calibration_wait_s: Option<f64>,
}

/// `[fleet]`, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct FleetSettings {
    /// Take part in an election with the other daemons of the fleet; off,
    /// the daemon owns every vessel of its share alone, as a single daemon.
    pub enabled: bool,
    /// Smaller first: the daemon with the smallest priority among those
    /// alive whose share covers a vessel is its active owner (then the
    /// oldest, then the smallest id).
    pub priority: u32,
    /// The first chunk of the fleet's keys (tokens and reports), outside the
    /// data prefix; default `{keys.prefix}-fleet`.
    pub prefix: String,
    /// Vessel ids that must have an owner: those without one are named as
    /// gaps in the reports and the log.
    pub roster: Vec<String>,
    /// The report is published this often (and at every change), s.
    pub report_interval_s: f64,
    /// At start, how long to wait for the other daemons' tokens before
    /// serving, s.
    pub join_wait_s: f64,
    /// Put each vessel's calibration on `{prefix}/calibration/{vessel}`
    /// when the active owner saves it, and ask that key for it when a
    /// vessel's twin starts (a storage on the routers keeps it:
    /// docs/deploy.md); only with `enabled`.
    pub share_calibrations: bool,
    /// How long a starting twin waits for the network's calibration, s.
    pub calibration_wait_s: f64,
}

impl FleetSettings {
    /// The key of `vessel`'s calibration in the network,
    /// `{prefix}/calibration/{vessel}`; `None` unless the daemon is in a
    /// fleet that shares calibrations.
    pub fn calibration_key(&self, vessel: &str) -> Option<String> {
        (self.enabled && self.share_calibrations)
            .then(|| format!("{}/calibration/{vessel}", self.prefix))
    }

    pub(crate) fn from_raw(raw: RawFleet, prefix: &str) -> Result<Self, SettingsError> {
        let fleet_prefix = raw.prefix.unwrap_or_else(|| format!("{prefix}-fleet"));
        if twin_wire::keys::validate_vessel_id(&fleet_prefix).is_err() || fleet_prefix == prefix {
            return Err(SettingsError::Invalid {
                key: "fleet.prefix",
                reason: format!(
                    "{fleet_prefix:?} must be one plain key chunk (letters, digits, `-`, `_`) \
                     other than keys.prefix"
                ),
            });
        }
        let mut roster = raw.roster.unwrap_or_default();
        for id in &roster {
            twin_wire::keys::validate_vessel_id(id).map_err(|e| SettingsError::Invalid {
                key: "fleet.roster",
                reason: format!("{id:?}: {e}"),
            })?;
        }
        roster.sort();
        roster.dedup();
        let seconds = |key: &'static str, v: Option<f64>, default: f64| {
            let v = v.unwrap_or(default);
            if v.is_finite() && v > 0.0 && v <= 3600.0 {
                Ok(v)
            } else {
                Err(SettingsError::Invalid {
                    key,
                    reason: format!("must be more than 0 s and at most 3600 s, got {v}"),
                })
            }
        };
        Ok(Self {
            enabled: raw.enabled.unwrap_or(false),
            priority: raw.priority.unwrap_or(0),
            prefix: fleet_prefix,
            roster,
            report_interval_s: seconds("fleet.report_interval_s", raw.report_interval_s, 5.0)?,
            join_wait_s: seconds("fleet.join_wait_s", raw.join_wait_s, 2.0)?,
            share_calibrations: raw.share_calibrations.unwrap_or(true),
            calibration_wait_s: seconds("fleet.calibration_wait_s", raw.calibration_wait_s, 2.0)?,
        })
    }
}

/// One live daemon of the fleet, as its token says.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Member {
    /// The daemon's id.
    pub id: String,
    /// Its priority (smaller first).
    pub priority: u32,
    /// When it started, ms since the Unix epoch (older first).
    pub start_ms: u64,
    /// Its share, `[vessels] own`.
    pub share: String,
}

impl Member {
    /// The token key of this member under `fleet_prefix`.
    pub fn token_key(&self, fleet_prefix: &str) -> String {
        format!(
            "{fleet_prefix}/daemon/{}/{}/{}/{}",
            self.id,
            self.priority,
            self.start_ms,
            encode_share(&self.share)
        )
    }

    /// The member a token key names; `None` when it is not one.
    pub fn from_token_key(fleet_prefix: &str, key: &str) -> Option<Self> {
        let rest = key.strip_prefix(fleet_prefix)?.strip_prefix("/daemon/")?;
        let mut chunks = rest.split('/');
        let id = chunks.next()?;
        let priority = chunks.next()?.parse().ok()?;
        let start_ms = chunks.next()?.parse().ok()?;
        let share = decode_share(chunks.next()?)?;
        if chunks.next().is_some() || twin_wire::keys::validate_vessel_id(id).is_err() {
            return None;
        }
        Some(Self {
            id: id.to_string(),
            priority,
            start_ms,
            share,
        })
    }

    fn order(&self) -> (u32, u64, &str) {
        (self.priority, self.start_ms, &self.id)
    }
}

/// `share` with `%`, `$` and `*` percent-encoded (a token's key is no
/// pattern).
fn encode_share(share: &str) -> String {
    share
        .replace('%', "%25")
        .replace('$', "%24")
        .replace('*', "%2A")
}

fn decode_share(chunk: &str) -> Option<String> {
    let share = chunk
        .replace("%2A", "*")
        .replace("%24", "$")
        .replace("%25", "%");
    (!share.is_empty() && !share.contains('/')).then_some(share)
}

/// The live members and what follows from them.
#[derive(Debug, Clone, Default)]
struct View {
    /// Sorted by `(priority, start_ms, id)`, each with its share's key
    /// expression `{prefix}/{share}`.
    members: Vec<(Member, KeyExpr<'static>)>,
}

impl View {
    fn insert(&mut self, member: Member, prefix: &str) -> bool {
        if self.members.iter().any(|(m, _)| *m == member) {
            return false;
        }
        let Ok(ke) = KeyExpr::try_from(format!("{prefix}/{}", member.share)) else {
            return false;
        };
        self.members.retain(|(m, _)| m.id != member.id);
        self.members.push((member, ke));
        self.members.sort_by(|a, b| a.0.order().cmp(&b.0.order()));
        true
    }

    fn remove(&mut self, member: &Member) -> bool {
        let before = self.members.len();
        self.members.retain(|(m, _)| m != member);
        self.members.len() != before
    }

    /// The active owner of `vessel` (its key `{prefix}/{vessel}`).
    fn owner(&self, vessel_key: &KeyExpr<'_>) -> Option<&Member> {
        self.members
            .iter()
            .find(|(_, share)| share.includes(vessel_key))
            .map(|(m, _)| m)
    }

    fn overlaps(&self) -> Vec<Overlap> {
        let mut out = Vec::new();
        for (i, (a, ka)) in self.members.iter().enumerate() {
            for (b, kb) in &self.members[i + 1..] {
                if ka.intersects(kb) {
                    out.push(Overlap {
                        daemons: [a.id.clone(), b.id.clone()],
                        shares: [a.share.clone(), b.share.clone()],
                    });
                }
            }
        }
        out
    }
}

/// Two live daemons whose shares intersect (the first is the one that is
/// active for the vessels they both cover).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Overlap {
    /// Their ids, in election order.
    pub daemons: [String; 2],
    /// Their shares, in the same order.
    pub shares: [String; 2],
}

/// The report a fleet daemon publishes on `{fleet}/report/{id}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FleetReport {
    /// The reporting daemon.
    pub daemon: String,
    /// Wall clock, s since the Unix epoch.
    pub time: f64,
    /// Live daemons in election order: `[id, share]`.
    pub members: Vec<[String; 2]>,
    /// Live daemons whose shares intersect.
    pub overlaps: Vec<Overlap>,
    /// Vessels of the roster that no live daemon's share covers.
    pub gaps: Vec<String>,
}

/// The fleet as this daemon sees it; cheap to clone. A daemon outside any
/// fleet ([`Fleet::solo`]) is the active owner of every vessel.
#[derive(Clone)]
pub struct Fleet(Arc<FleetInner>);

struct FleetInner {
    /// `None`: not in a fleet.
    me: Option<Member>,
    prefix: String,
    view: RwLock<View>,
    generation: AtomicU64,
    changed: watch::Sender<u64>,
}

impl std::fmt::Debug for Fleet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fleet").field("me", &self.0.me).finish()
    }
}

impl Default for Fleet {
    fn default() -> Self {
        Self::solo()
    }
}

impl Fleet {
    /// A daemon alone: active for every vessel; its role never changes.
    pub fn solo() -> Self {
        Self(Arc::new(FleetInner {
            me: None,
            prefix: String::new(),
            view: RwLock::new(View::default()),
            generation: AtomicU64::new(0),
            changed: watch::channel(0).0,
        }))
    }

    fn member(me: Member, prefix: &str) -> Self {
        let mut view = View::default();
        view.insert(me.clone(), prefix);
        Self(Arc::new(FleetInner {
            me: Some(me),
            prefix: prefix.to_string(),
            view: RwLock::new(view),
            generation: AtomicU64::new(0),
            changed: watch::channel(0).0,
        }))
    }

    /// This daemon's id in the fleet, `None` outside one.
    pub fn daemon_id(&self) -> Option<&str> {
        self.0.me.as_ref().map(|m| m.id.as_str())
    }

    /// Bumped at every change of the live members.
    pub fn generation(&self) -> u64 {
        self.0.generation.load(Ordering::Acquire)
    }

    /// Told the generation at every change of the live members.
    pub fn subscribe(&self) -> watch::Receiver<u64> {
        self.0.changed.subscribe()
    }

    /// Whether this daemon is the active owner of `vessel`.
    pub fn is_active(&self, vessel: &str) -> bool {
        let Some(me) = &self.0.me else {
            return true;
        };
        let Ok(key) = KeyExpr::try_from(format!("{}/{vessel}", self.0.prefix)) else {
            return false;
        };
        let Ok(view) = self.0.view.read() else {
            return false;
        };
        view.owner(&key).is_some_and(|owner| owner.id == me.id)
    }

    /// Applies a token's arrival or departure; true when the view changed.
    fn apply(&self, member: Member, alive: bool) -> bool {
        if !alive && self.0.me.as_ref() == Some(&member) {
            // Our own token is ours until we stop.
            return false;
        }
        let changed = match self.0.view.write() {
            Ok(mut view) => {
                if alive {
                    view.insert(member, &self.0.prefix)
                } else {
                    view.remove(&member)
                }
            }
            Err(_) => false,
        };
        if changed {
            let g = self.0.generation.fetch_add(1, Ordering::AcqRel) + 1;
            self.0.changed.send_replace(g);
        }
        changed
    }

    /// The report as this daemon sees the fleet now.
    pub fn report(&self, roster: &[String]) -> FleetReport {
        let view = self.0.view.read().map(|v| v.clone()).unwrap_or_default();
        let gaps = roster
            .iter()
            .filter(|vessel| {
                KeyExpr::try_from(format!("{}/{vessel}", self.0.prefix))
                    .map_or(true, |key| view.owner(&key).is_none())
            })
            .cloned()
            .collect();
        FleetReport {
            daemon: self.daemon_id().unwrap_or_default().to_string(),
            time: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64()),
            members: view
                .members
                .iter()
                .map(|(m, _)| [m.id.clone(), m.share.clone()])
                .collect(),
            overlaps: view.overlaps(),
            gaps,
        }
    }
}

/// What keeps a fleet daemon in the election: its token and the task that
/// watches the others. Dropping it leaves the fleet.
pub struct FleetMembership {
    _token: zenoh::liveliness::LivelinessToken,
    watcher: tokio::task::JoinHandle<()>,
}

impl Drop for FleetMembership {
    fn drop(&mut self) {
        self.watcher.abort();
    }
}

/// Joins the fleet when `[fleet] enabled`: declares this daemon's token,
/// learns the live members (waiting at most `join_wait_s` for their
/// answer), and watches them until `shutdown`. Outside a fleet: a solo
/// fleet and nothing to keep.
pub async fn join(
    session: &Session,
    settings: &crate::settings::Settings,
    daemon_id: &str,
    shutdown: CancellationToken,
) -> anyhow::Result<(Fleet, Option<FleetMembership>)> {
    let s = &settings.fleet;
    if !s.enabled {
        return Ok((Fleet::solo(), None));
    }
    let me = Member {
        id: daemon_id.to_string(),
        priority: s.priority,
        start_ms: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX)),
        share: settings.vessels.own.clone(),
    };
    let fleet = Fleet::member(me.clone(), settings.keys.prefix());
    let tokens = format!("{}/daemon/**", s.prefix);
    let token = session
        .liveliness()
        .declare_token(me.token_key(&s.prefix))
        .await
        .map_err(|e| anyhow::anyhow!("cannot declare the fleet token: {e}"))?;
    let subscriber = session
        .liveliness()
        .declare_subscriber(&tokens)
        .history(true)
        .await
        .map_err(|e| anyhow::anyhow!("cannot watch the fleet's tokens on {tokens}: {e}"))?;
    // The members alive now, before any vessel is served: a daemon that
    // joins a running fleet starts as a standby, not as a second owner.
    let replies = session
        .liveliness()
        .get(&tokens)
        .timeout(Duration::from_secs_f64(s.join_wait_s))
        .await
        .map_err(|e| anyhow::anyhow!("cannot ask for the fleet's tokens: {e}"))?;
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result()
            && let Some(member) = Member::from_token_key(&s.prefix, sample.key_expr().as_str())
        {
            fleet.apply(member, true);
        }
    }
    tracing::info!(
        daemon = daemon_id,
        share = %me.share,
        members = ?fleet.report(&[]).members,
        "joined the fleet"
    );
    let watcher = tokio::spawn(watch_members(
        session.clone(),
        fleet.clone(),
        subscriber,
        s.clone(),
        shutdown,
    ));
    Ok((
        fleet,
        Some(FleetMembership {
            _token: token,
            watcher,
        }),
    ))
}

type TokenSubscriber =
    zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>;

/// Follows the fleet's tokens, and publishes (and logs) the report at every
/// change and every `report_interval_s`.
async fn watch_members(
    session: Session,
    fleet: Fleet,
    subscriber: TokenSubscriber,
    settings: FleetSettings,
    shutdown: CancellationToken,
) {
    let daemon = fleet.daemon_id().unwrap_or_default().to_string();
    let report_key = format!("{}/report/{daemon}", settings.prefix);
    let mut tick = tokio::time::interval(Duration::from_secs_f64(settings.report_interval_s));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut last_logged: Option<(Vec<Overlap>, Vec<String>)> = None;
    loop {
        tokio::select! {
            _ = shutdown.cancelled() => break,
            sample = subscriber.recv_async() => {
                let Ok(sample) = sample else { break };
                let key = sample.key_expr().as_str();
                let Some(member) = Member::from_token_key(&settings.prefix, key) else {
                    tracing::debug!(key, "not a fleet token; ignored");
                    continue;
                };
                let alive = sample.kind() == SampleKind::Put;
                if !fleet.apply(member.clone(), alive) {
                    continue;
                }
                tracing::info!(
                    daemon = %member.id,
                    share = %member.share,
                    "fleet daemon {}", if alive { "joined" } else { "left" }
                );
            }
            _ = tick.tick() => {}
        }
        let report = fleet.report(&settings.roster);
        let now = (report.overlaps.clone(), report.gaps.clone());
        if last_logged.as_ref() != Some(&now) {
            if !report.overlaps.is_empty() || !report.gaps.is_empty() {
                tracing::warn!(
                    overlaps = ?report.overlaps,
                    gaps = ?report.gaps,
                    "the fleet's shares overlap or leave vessels without an owner"
                );
            }
            last_logged = Some(now);
        }
        match serde_json::to_vec(&report) {
            Ok(bytes) => {
                if let Err(e) = session
                    .put(&report_key, bytes)
                    .encoding(Encoding::APPLICATION_JSON)
                    .await
                {
                    tracing::warn!("fleet report not published: {e}");
                }
            }
            Err(e) => tracing::error!("cannot encode the fleet report: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn member(id: &str, priority: u32, start_ms: u64, share: &str) -> Member {
        Member {
            id: id.into(),
            priority,
            start_ms,
            share: share.into(),
        }
    }

    #[test]
    fn a_token_key_names_its_member_and_nothing_else() {
        let m = member("north-a", 1, 1_700_000_000_123, "north-$*");
        let key = m.token_key("asv-fleet");
        assert_eq!(key, "asv-fleet/daemon/north-a/1/1700000000123/north-%24%2A");
        assert!(KeyExpr::try_from(key.as_str()).is_ok());
        assert_eq!(Member::from_token_key("asv-fleet", &key), Some(m));
        for bad in [
            "asv-fleet/daemon/a/x/1/north",
            "asv-fleet/daemon/a/1/1",
            "asv-fleet/daemon/a/1/1/north/extra",
            "other/daemon/a/1/1/north",
        ] {
            assert_eq!(Member::from_token_key("asv-fleet", bad), None, "{bad}");
        }
    }

    #[test]
    fn the_owner_is_the_first_live_daemon_whose_share_covers_the_vessel() {
        let me = member("b", 0, 20, "*");
        let fleet = Fleet::member(me, "asv");
        // Alone, b owns everything.
        assert!(fleet.is_active("north-1"));
        // An older daemon with north: it owns north, b keeps the rest.
        assert!(fleet.apply(member("a", 0, 10, "north-$*"), true));
        assert!(!fleet.is_active("north-1"));
        assert!(fleet.is_active("south-1"));
        // A younger daemon with a smaller priority wins over both.
        assert!(fleet.apply(member("c", 0, 30, "south-$*"), true));
        assert!(fleet.is_active("south-1"));
        assert!(fleet.apply(member("d", 0, 40, "*"), true));
        assert!(fleet.is_active("south-1"));
        // a leaves: b takes north back.
        assert!(fleet.apply(member("a", 0, 10, "north-$*"), false));
        assert!(fleet.is_active("north-1"));
        assert_eq!(fleet.generation(), 4);
        let report = fleet.report(&["north-1".into()]);
        assert_eq!(report.members.len(), 3);
        assert!(report.gaps.is_empty());
        // Every pair of the three overlaps (b and d are `*`).
        assert_eq!(report.overlaps.len(), 3);
    }

    #[test]
    fn the_report_names_overlaps_and_gaps() {
        let fleet = Fleet::member(member("a", 0, 1, "north-$*"), "asv");
        fleet.apply(member("b", 0, 2, "north-$*"), true);
        fleet.apply(member("c", 0, 3, "south-$*"), true);
        let report = fleet.report(&["east-1".into(), "north-1".into(), "south-9".into()]);
        assert_eq!(report.gaps, vec!["east-1".to_string()]);
        assert_eq!(
            report.overlaps,
            vec![Overlap {
                daemons: ["a".into(), "b".into()],
                shares: ["north-$*".into(), "north-$*".into()],
            }]
        );
    }

    #[test]
    fn fleet_settings_are_validated_naming_the_key() {
        let s = crate::settings::Settings::default();
        assert!(!s.fleet.enabled);
        assert_eq!(s.fleet.prefix, "asv-fleet");
        for (text, key) in [
            ("[fleet]\nprefix = \"asv\"\n", "fleet.prefix"),
            ("[fleet]\nprefix = \"a/b\"\n", "fleet.prefix"),
            ("[fleet]\nroster = [\"a/b\"]\n", "fleet.roster"),
            (
                "[fleet]\nreport_interval_s = 0.0\n",
                "fleet.report_interval_s",
            ),
            ("[fleet]\njoin_wait_s = -1.0\n", "fleet.join_wait_s"),
            (
                "[fleet]\ncalibration_wait_s = 0.0\n",
                "fleet.calibration_wait_s",
            ),
        ] {
            let err = crate::settings::Settings::from_toml(text)
                .unwrap_err()
                .to_string();
            assert!(err.contains(key), "{text}: {err}");
        }
        // Calibrations go to the network only from a fleet that shares them.
        assert_eq!(s.fleet.calibration_key("otter-1"), None);
        let shared = crate::settings::Settings::from_toml("[fleet]\nenabled = true\n").unwrap();
        assert_eq!(
            shared.fleet.calibration_key("otter-1").as_deref(),
            Some("asv-fleet/calibration/otter-1")
        );
        let kept = crate::settings::Settings::from_toml(
            "[fleet]\nenabled = true\nshare_calibrations = false\n",
        )
        .unwrap();
        assert_eq!(kept.fleet.calibration_key("otter-1"), None);
        let err = crate::settings::Settings::from_toml("[fleet]\nbogus = 1\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("bogus"), "{err}");
    }
}
