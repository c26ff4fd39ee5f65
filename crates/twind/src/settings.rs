//! The daemon's own settings, in two steps (as ripgrep parses flags): a raw
//! serde form read from `config/twind.toml` with every field optional and
//! unknown keys refused, validated into [`Settings`], the form the code uses.
//! Every validation error names the bad key. Zenoh's settings stay in Zenoh's
//! own JSON5 file (`config/zenoh.json5`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use twin_core::diagnose::MonitorConfig;
use twin_core::twin::TwinConfig;
use twin_wire::KeySpace;
use twin_wire::profile::VesselProfile;

/// Why the settings cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SettingsError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
    },
    /// The file is not valid TOML for these settings (unknown key, wrong type).
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// toml's message, which names the key and line.
        message: String,
    },
    /// A value is out of its range.
    #[error("setting `{key}`: {reason}")]
    Invalid {
        /// The dotted key.
        key: &'static str,
        /// What is wrong.
        reason: String,
    },
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSettings {
    #[serde(default)]
    keys: RawKeys,
    #[serde(default)]
    vessels: RawVessels,
    #[serde(default)]
    publish: RawPublish,
    #[serde(default)]
    input: RawInput,
    #[serde(default)]
    persistence: RawPersistence,
    #[serde(default)]
    web: RawWeb,
    #[serde(default)]
    metrics: RawMetrics,
    #[serde(default)]
    twin: RawTwin,
    #[serde(default)]
    diagnose: RawDiagnose,
    #[serde(default)]
    daemon: RawDaemon,
    #[serde(default)]
    profiles: RawProfiles,
    #[serde(default)]
    ros2: crate::ros2::RawRos2,
    #[serde(default)]
    fleet: crate::fleet::RawFleet,
    #[serde(default)]
    signalk: Option<crate::signalk::RawSignalk>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProfiles {
    files: Option<Vec<PathBuf>>,
    default: Option<String>,
    vessels: Option<Vec<RawProfileRule>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProfileRule {
    id: String,
    profile: String,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDaemon {
    id: Option<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawDiagnose {
    enabled: Option<bool>,
    window_s: Option<f64>,
    min_window_s: Option<f64>,
    interval_s: Option<f64>,
    min_interval_s: Option<f64>,
    bias_window_s: Option<f64>,
    bias_t: Option<f64>,
    max_concurrent: Option<usize>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawKeys {
    prefix: Option<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawVessels {
    own: Option<String>,
    drop_after_silence_s: Option<f64>,
    stale_after_s: Option<f64>,
    max_vessels: Option<usize>,
    queue_depth: Option<usize>,
    known: Option<Vec<String>>,
    admit_per_s: Option<f64>,
    admit_burst: Option<usize>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPublish {
    prediction_interval_s: Option<f64>,
    prediction_horizon_s: Option<f64>,
    prediction_step_s: Option<f64>,
    stats_interval_s: Option<f64>,
    vessel_liveliness: Option<bool>,
    vessel_liveliness_key: Option<String>,
    forecast_threads: Option<usize>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawInput {
    max_payload_bytes: Option<usize>,
    live_max_ahead_s: Option<f64>,
    live_max_behind_s: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPersistence {
    dir: Option<PathBuf>,
    save_interval_s: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWeb {
    enabled: Option<bool>,
    listen: Option<String>,
    tile_url: Option<String>,
    tile_overlay_url: Option<String>,
    tile_attribution: Option<String>,
    tile_max_zoom: Option<u8>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMetrics {
    listen: Option<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTwin {
    estimate_current: Option<bool>,
    forgetting_time_constant_s: Option<f64>,
    suspect_loss: Option<f64>,
    fault_loss: Option<f64>,
    clear_loss: Option<f64>,
}

/// Which vessels this daemon serves, and how long it keeps them.
#[derive(Debug, Clone, PartialEq)]
pub struct VesselSettings {
    /// The vessel-id chunk of the subscribed key expressions, in Zenoh's
    /// syntax: `*` for every vessel, `north-$*` for ids starting `north-`.
    pub own: String,
    /// A vessel silent this long is dropped (its calibration saved), s.
    pub drop_after_silence_s: f64,
    /// A vessel with no fix for this long is published as stale, s.
    pub stale_after_s: f64,
    /// Most vessels admitted at once, not counting those of `known`;
    /// messages for more are refused.
    pub max_vessels: usize,
    /// Messages queued per vessel before the dispatcher waits for it.
    pub queue_depth: usize,
    /// Vessel ids always admitted (even beyond `max_vessels` and the
    /// admission rate), sorted.
    pub known: Vec<String>,
    /// Vessels not in `known` admitted per second, on average (a token
    /// bucket refilled at this rate)...
    pub admit_per_s: f64,
    /// ... and at most this many at once (the bucket's size, full at start).
    pub admit_burst: usize,
}

/// Who the daemon is.
#[derive(Debug, Clone, PartialEq)]
pub struct DaemonSettings {
    /// Its id in `{prefix}/@twind/{id}/stats`; `None`: its Zenoh session id.
    pub id: Option<String>,
}

/// Bounds on the time stamps of live input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveTimeSettings {
    /// A live message (not a replay) stamped more than this ahead of the
    /// daemon's clock is refused (`time_ahead_of_clock`), s.
    pub max_ahead_s: f64,
    /// A live message stamped more than this behind the daemon's clock is
    /// refused (`time_behind_clock`), s.
    pub max_behind_s: f64,
}

/// What is published and how often.
#[derive(Debug, Clone, PartialEq)]
pub struct PublishSettings {
    /// A forecast is published each time this much message time has passed, s.
    pub prediction_interval_s: f64,
    /// Forecast horizon, s.
    pub prediction_horizon_s: f64,
    /// Forecast step, s.
    pub prediction_step_s: f64,
    /// Statistics are published this often (wall clock), s.
    pub stats_interval_s: f64,
    /// Whether each vessel's twin holds the liveliness token
    /// `{prefix}/{vessel}/twin/alive` (the contract; default true). Off,
    /// `twin/state` and its `stale` flag still say whether a twin runs.
    /// With Zenoh 1.10 every token under the prefix makes the routing of
    /// every undeclared key dearer; the daemon declares each vessel's keys
    /// (`vessel.rs`), so turning the tokens off is not needed for speed
    /// (`twin-bench daemon --no-vessel-liveliness` measures it).
    pub vessel_liveliness: bool,
    /// The token's key with `{vessel}` for the vessel id, where it is not
    /// the contract's `{prefix}/{vessel}/twin/alive` (`None`). A key outside
    /// the data prefix with the vessel's chunk two levels down, e.g.
    /// `asv-twins/alive/{vessel}`, keeps the tokens off the routing of
    /// undeclared keys under the prefix (Zenoh 1.10 looks at every child of
    /// a top-level node, so `asv-alive/{vessel}` would not); with the
    /// daemon declaring each vessel's keys it is not needed for speed
    /// (docs/performance.md).
    pub vessel_liveliness_key: Option<String>,
    /// Threads computing the forecasts, at a lower scheduling priority than
    /// the rest of the daemon (see `forecast`); 0 in the file means half the
    /// cores, at least one.
    pub forecast_threads: usize,
}

/// Where calibrations are kept.
#[derive(Debug, Clone, PartialEq)]
pub struct PersistenceSettings {
    /// Directory of the per-vessel calibration files; `None` keeps nothing.
    pub dir: Option<PathBuf>,
    /// Calibrations are saved this often (wall clock), and on shutdown, s.
    pub save_interval_s: f64,
}

/// The web page.
#[derive(Debug, Clone, PartialEq)]
pub struct WebSettings {
    /// Serve the page.
    pub enabled: bool,
    /// Address to serve it on.
    pub listen: String,
    /// The chart's background tiles; `None` keeps the page tile-less (it then
    /// makes no request beyond the daemon).
    pub tiles: Option<TileSettings>,
}

/// Web Mercator tiles drawn under the page's track (`[web] tile_url`...);
/// the page reads them as they serialize, in `GET /api/info`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TileSettings {
    /// The base map's URL template (`{z}`, `{x}`, `{y}`), if any.
    pub url: Option<String>,
    /// A transparent layer drawn over the base map (e.g. OpenSeaMap's
    /// seamarks), if any.
    pub overlay_url: Option<String>,
    /// Shown on the chart, as the tile servers' terms ask.
    pub attribution: String,
    /// The most detailed zoom level requested (closer views enlarge it).
    pub max_zoom: u8,
}

/// Most detailed zoom level a tile server is asked for unless told.
pub const DEFAULT_TILE_MAX_ZOOM: u8 = 19;
/// Longest tile URL template accepted, bytes.
const MAX_TILE_URL_BYTES: usize = 2048;
/// Longest attribution accepted, characters.
const MAX_TILE_ATTRIBUTION_CHARS: usize = 300;

/// The Prometheus metrics' own listener (they are also on the web page's
/// port when the page is served).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MetricsSettings {
    /// Serve `/metrics` alone on this address.
    pub listen: Option<std::net::SocketAddr>,
}

/// The live residual monitor (`twin diagnose` on each vessel's recent past).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiagnoseSettings {
    /// Run it.
    pub enabled: bool,
    /// When and over what (message time).
    pub monitor: MonitorConfig,
    /// Most diagnoses running at once across all vessels (each on a
    /// blocking thread, one thread per diagnosis).
    pub max_concurrent: usize,
}

/// The validated settings.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Key expressions under the configured prefix.
    pub keys: KeySpace,
    /// Vessels served.
    pub vessels: VesselSettings,
    /// Publication.
    pub publish: PublishSettings,
    /// Largest payload accepted, bytes; larger ones are refused unread.
    pub max_payload_bytes: usize,
    /// Bounds on live time stamps against the daemon's clock.
    pub live_time: LiveTimeSettings,
    /// Who the daemon is.
    pub daemon: DaemonSettings,
    /// Calibration storage.
    pub persistence: PersistenceSettings,
    /// Web page.
    pub web: WebSettings,
    /// The metrics' own listener.
    pub metrics: MetricsSettings,
    /// The twin each vessel runs.
    pub twin: TwinConfig,
    /// The live residual monitor.
    pub diagnose: DiagnoseSettings,
    /// ROS 2 over rmw_zenoh (`crate::ros2`).
    pub ros2: crate::ros2::Ros2Settings,
    /// Several daemons sharing a fleet: election and reports
    /// (`crate::fleet`); off by default.
    pub fleet: crate::fleet::FleetSettings,
    /// Vessel profiles, and which vessel uses which.
    pub profiles: ProfileSettings,
    /// The Signal K output (`[signalk]`), if on.
    pub signalk: Option<crate::signalk::SignalkSettings>,
}

/// The vessel profiles a daemon knows, and which vessel runs on which.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileSettings {
    /// Every profile by name: the shipped Otter's and those of
    /// `[profiles] files`, each validated.
    pub by_name: BTreeMap<String, Arc<VesselProfile>>,
    /// `(vessel id or pattern, profile name)`, in the file's order: the
    /// first that matches a vessel's id wins (`*` matches any run of
    /// characters).
    pub rules: Vec<(String, String)>,
    /// The profile of a vessel no rule matches.
    pub default: String,
}

impl ProfileSettings {
    /// The profile vessel `id` runs on.
    pub fn for_vessel(&self, id: &str) -> &Arc<VesselProfile> {
        let name = self
            .rules
            .iter()
            .find(|(pattern, _)| id_matches(pattern, id))
            .map_or(&self.default, |(_, name)| name);
        &self.by_name[name]
    }
}

/// Whether `id` matches `pattern`, where `*` matches any run of
/// characters (none included) and every other character itself.
fn id_matches(pattern: &str, id: &str) -> bool {
    let mut parts = pattern.split('*');
    let first = parts.next().unwrap_or("");
    let Some(mut rest) = id.strip_prefix(first) else {
        return false;
    };
    let parts: Vec<&str> = parts.collect();
    let Some((last, middle)) = parts.split_last() else {
        return rest.is_empty();
    };
    for part in middle {
        match rest.find(part) {
            Some(at) => rest = &rest[at + part.len()..],
            None => return false,
        }
    }
    rest.len() >= last.len() && rest.ends_with(last)
}

impl Default for Settings {
    fn default() -> Self {
        Self::from_raw(RawSettings::default()).expect("the defaults are valid")
    }
}

/// A liveliness key template: `{vessel}` exactly once, and with a vessel id
/// in its place a plain Zenoh key (no wildcards, no `$`).
fn liveliness_key_template(template: String) -> Result<String, SettingsError> {
    let invalid = |reason: String| SettingsError::Invalid {
        key: "publish.vessel_liveliness_key",
        reason,
    };
    if template.matches("{vessel}").count() != 1 {
        return Err(invalid(format!(
            "{template:?}: must hold {{vessel}} exactly once"
        )));
    }
    let example = template.replace("{vessel}", "v0");
    if example.contains(['*', '$']) {
        return Err(invalid(format!("{template:?}: no wildcards")));
    }
    zenoh::key_expr::KeyExpr::try_from(example.as_str())
        .map_err(|e| invalid(format!("{template:?} is not a key expression: {e}")))?;
    Ok(template)
}

impl PublishSettings {
    /// The liveliness token's key for `vessel`.
    pub fn liveliness_key(&self, keys: &KeySpace, vessel: &twin_wire::VesselId) -> String {
        match &self.vessel_liveliness_key {
            Some(template) => template.replace("{vessel}", vessel.as_str()),
            None => keys.twin_alive(vessel),
        }
    }
}

fn positive(key: &'static str, v: f64) -> Result<f64, SettingsError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(SettingsError::Invalid {
            key,
            reason: format!("must be a positive number of seconds, got {v}"),
        })
    }
}

fn fraction(key: &'static str, v: f64) -> Result<f64, SettingsError> {
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(SettingsError::Invalid {
            key,
            reason: format!("must be in [0, 1], got {v}"),
        })
    }
}

impl Settings {
    /// The twin and profile vessel `id` runs on: the `[twin]` tuning for
    /// the vessel its profile describes.
    pub fn twin_for(&self, id: &str) -> (TwinConfig, Arc<VesselProfile>) {
        let profile = self.profiles.for_vessel(id);
        (profile.twin_config(self.twin), Arc::clone(profile))
    }

    /// Reads and validates a settings file.
    pub fn from_file(path: &Path) -> Result<Self, SettingsError> {
        let text = std::fs::read_to_string(path).map_err(|source| SettingsError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        Self::from_toml_in(&text, base).map_err(|e| match e {
            SettingsError::Parse { message, .. } => SettingsError::Parse {
                path: path.to_path_buf(),
                message,
            },
            other => other,
        })
    }

    /// Parses and validates settings from TOML text (profile files
    /// relative to the working directory).
    pub fn from_toml(text: &str) -> Result<Self, SettingsError> {
        Self::from_toml_in(text, Path::new("."))
    }

    /// Parses and validates settings from TOML text, profile files
    /// relative to `base`.
    fn from_toml_in(text: &str, base: &Path) -> Result<Self, SettingsError> {
        let mut raw: RawSettings = toml::from_str(text).map_err(|e| SettingsError::Parse {
            path: PathBuf::from("<settings>"),
            message: e.to_string(),
        })?;
        if let Some(files) = &mut raw.profiles.files {
            for file in files.iter_mut() {
                if file.is_relative() {
                    *file = base.join(&*file);
                }
            }
        }
        Self::from_raw(raw)
    }

    fn from_raw(raw: RawSettings) -> Result<Self, SettingsError> {
        let prefix = raw.keys.prefix.unwrap_or_else(|| "asv".to_string());
        let keys = KeySpace::new(&prefix).map_err(|e| SettingsError::Invalid {
            key: "keys.prefix",
            reason: e.to_string(),
        })?;
        let vessels = vessel_settings(raw.vessels)?;
        let publish = publish_settings(raw.publish)?;
        let max_payload_bytes = raw.input.max_payload_bytes.unwrap_or(64 * 1024);
        if !(256..=16 * 1024 * 1024).contains(&max_payload_bytes) {
            return Err(SettingsError::Invalid {
                key: "input.max_payload_bytes",
                reason: format!("must be between 256 B and 16 MiB, got {max_payload_bytes}"),
            });
        }
        let live_time = LiveTimeSettings {
            max_ahead_s: positive(
                "input.live_max_ahead_s",
                raw.input.live_max_ahead_s.unwrap_or(30.0),
            )?,
            max_behind_s: positive(
                "input.live_max_behind_s",
                raw.input.live_max_behind_s.unwrap_or(600.0),
            )?,
        };
        let daemon = DaemonSettings {
            id: match raw.daemon.id {
                Some(id) => {
                    twin_wire::keys::validate_vessel_id(&id).map_err(|e| {
                        SettingsError::Invalid {
                            key: "daemon.id",
                            reason: format!("{id:?}: {e}"),
                        }
                    })?;
                    Some(id)
                }
                None => None,
            },
        };
        let persistence = PersistenceSettings {
            dir: raw.persistence.dir,
            save_interval_s: positive(
                "persistence.save_interval_s",
                raw.persistence.save_interval_s.unwrap_or(30.0),
            )?,
        };
        let web = web_settings(raw.web)?;
        let metrics = MetricsSettings {
            listen: match raw.metrics.listen {
                Some(a) => Some(a.parse().map_err(|_| SettingsError::Invalid {
                    key: "metrics.listen",
                    reason: format!("{a:?} is not an address such as 127.0.0.1:9464"),
                })?),
                None => None,
            },
        };
        let twin = twin_config(&raw.twin)?;
        let diagnose = diagnose_settings(&raw.diagnose)?;
        let profiles = profile_settings(raw.profiles)?;
        Ok(Self {
            keys,
            vessels,
            publish,
            max_payload_bytes,
            live_time,
            daemon,
            persistence,
            web,
            metrics,
            twin,
            diagnose,
            profiles,
            ros2: crate::ros2::Ros2Settings::from_raw(raw.ros2)?,
            fleet: crate::fleet::FleetSettings::from_raw(raw.fleet, &prefix)?,
            signalk: raw
                .signalk
                .map(crate::signalk::SignalkSettings::from_raw)
                .transpose()?,
        })
    }
}

/// `[profiles]`: every file read and validated, every name used defined.
fn profile_settings(raw: RawProfiles) -> Result<ProfileSettings, SettingsError> {
    let otter = VesselProfile::otter();
    let mut by_name = BTreeMap::from([(otter.name.clone(), Arc::new(otter))]);
    for path in raw.files.unwrap_or_default() {
        let profile = VesselProfile::from_file(&path).map_err(|e| SettingsError::Invalid {
            key: "profiles.files",
            reason: format!("{}: {e}", path.display()),
        })?;
        if by_name.contains_key(&profile.name) {
            return Err(SettingsError::Invalid {
                key: "profiles.files",
                reason: format!(
                    "{}: a profile named {:?} is already defined",
                    path.display(),
                    profile.name
                ),
            });
        }
        by_name.insert(profile.name.clone(), Arc::new(profile));
    }
    let known = |key: &'static str, name: &str| {
        if by_name.contains_key(name) {
            Ok(())
        } else {
            Err(SettingsError::Invalid {
                key,
                reason: format!(
                    "no profile named {name:?} (defined: {})",
                    by_name.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
            })
        }
    };
    let default = raw.default.unwrap_or_else(|| "otter".to_owned());
    known("profiles.default", &default)?;
    let mut rules = Vec::new();
    for rule in raw.vessels.unwrap_or_default() {
        let literal = rule.id.replace('*', "");
        if rule.id.is_empty()
            || (!literal.is_empty() && twin_wire::keys::validate_vessel_id(&literal).is_err())
        {
            return Err(SettingsError::Invalid {
                key: "profiles.vessels",
                reason: format!("{:?} is not a vessel id or a pattern of one", rule.id),
            });
        }
        known("profiles.vessels", &rule.profile)?;
        rules.push((rule.id, rule.profile));
    }
    Ok(ProfileSettings {
        by_name,
        rules,
        default,
    })
}

/// `[web]`, validated.
fn web_settings(raw: RawWeb) -> Result<WebSettings, SettingsError> {
    let listen = raw.listen.unwrap_or_else(|| "127.0.0.1:8080".to_string());
    if listen.parse::<std::net::SocketAddr>().is_err() {
        return Err(SettingsError::Invalid {
            key: "web.listen",
            reason: format!("{listen:?} is not an address such as 127.0.0.1:8080"),
        });
    }
    let url = raw
        .tile_url
        .map(|u| tile_url_template("web.tile_url", u))
        .transpose()?;
    let overlay_url = raw
        .tile_overlay_url
        .map(|u| tile_url_template("web.tile_overlay_url", u))
        .transpose()?;
    let max_zoom = raw.tile_max_zoom.unwrap_or(DEFAULT_TILE_MAX_ZOOM);
    if max_zoom > 24 {
        return Err(SettingsError::Invalid {
            key: "web.tile_max_zoom",
            reason: format!("must be between 0 and 24, got {max_zoom}"),
        });
    }
    let tiles = if url.is_none() && overlay_url.is_none() {
        if raw.tile_attribution.is_some() {
            return Err(SettingsError::Invalid {
                key: "web.tile_attribution",
                reason: "there are no tiles to attribute: set web.tile_url or web.tile_overlay_url"
                    .into(),
            });
        }
        None
    } else {
        let attribution = raw.tile_attribution.unwrap_or_default();
        let attribution = attribution.trim();
        if attribution.is_empty() || attribution.chars().count() > MAX_TILE_ATTRIBUTION_CHARS {
            return Err(SettingsError::Invalid {
                key: "web.tile_attribution",
                reason: format!(
                    "required with tile URLs, at most {MAX_TILE_ATTRIBUTION_CHARS} characters \
                     (the tile servers' terms ask for it, e.g. \"© OpenStreetMap contributors\")"
                ),
            });
        }
        Some(TileSettings {
            url,
            overlay_url,
            attribution: attribution.to_string(),
            max_zoom,
        })
    };
    Ok(WebSettings {
        enabled: raw.enabled.unwrap_or(false),
        listen,
        tiles,
    })
}

/// A tile URL template, checked: `http://` or `https://`, a fixed host (it
/// goes into the page's content security policy), `{z}`, `{x}` and `{y}` in
/// the path and no other placeholder, printable ASCII without quotes,
/// spaces, `;` or `,`.
fn tile_url_template(key: &'static str, url: String) -> Result<String, SettingsError> {
    let invalid = |reason: String| SettingsError::Invalid { key, reason };
    if url.len() > MAX_TILE_URL_BYTES {
        return Err(invalid(format!("longer than {MAX_TILE_URL_BYTES} bytes")));
    }
    let Some(rest) = url
        .strip_prefix("https://")
        .or_else(|| url.strip_prefix("http://"))
    else {
        return Err(invalid(format!(
            "{url:?} must start with http:// or https://"
        )));
    };
    if let Some(c) = url.chars().find(|c| {
        !c.is_ascii_graphic() || matches!(c, '\'' | '"' | ';' | ',' | '<' | '>' | '\\' | '`')
    }) {
        return Err(invalid(format!(
            "{url:?} has {c:?}: printable ASCII only, without quotes, spaces, `;` or `,` \
             (percent-encode, and write international hosts in punycode)"
        )));
    }
    let host = rest.split(['/', '?', '#']).next().unwrap_or_default();
    if host.is_empty() || host.contains(['{', '}', '@']) {
        return Err(invalid(format!(
            "{url:?} must name a fixed host, without placeholders or user names"
        )));
    }
    for placeholder in ["{z}", "{x}", "{y}"] {
        if !url.contains(placeholder) {
            return Err(invalid(format!(
                "{url:?} has no {placeholder}: a tile URL template has {{z}}, {{x}} and {{y}}, \
                 e.g. https://tile.openstreetmap.org/{{z}}/{{x}}/{{y}}.png"
            )));
        }
    }
    let bare = url.replace("{z}", "").replace("{x}", "").replace("{y}", "");
    if bare.contains(['{', '}']) {
        return Err(invalid(format!(
            "{url:?}: only {{z}}, {{x}} and {{y}} are filled in (no {{s}} subdomains)"
        )));
    }
    Ok(url)
}

/// `[vessels]`, validated.
fn vessel_settings(raw: RawVessels) -> Result<VesselSettings, SettingsError> {
    let own = raw.own.unwrap_or_else(|| "*".to_string());
    if own.is_empty() || own.contains('/') || own.contains("**") {
        return Err(SettingsError::Invalid {
            key: "vessels.own",
            reason: format!("{own:?} must be one key-expression chunk such as `*` or `north-$*`"),
        });
    }
    let vessels = VesselSettings {
        own,
        drop_after_silence_s: positive(
            "vessels.drop_after_silence_s",
            raw.drop_after_silence_s.unwrap_or(300.0),
        )?,
        stale_after_s: positive("vessels.stale_after_s", raw.stale_after_s.unwrap_or(2.0))?,
        max_vessels: at_least_one("vessels.max_vessels", raw.max_vessels.unwrap_or(20_000))?,
        queue_depth: at_least_one("vessels.queue_depth", raw.queue_depth.unwrap_or(256))?,
        known: known_vessels(raw.known.unwrap_or_default())?,
        admit_per_s: positive("vessels.admit_per_s", raw.admit_per_s.unwrap_or(50.0))?,
        admit_burst: at_least_one("vessels.admit_burst", raw.admit_burst.unwrap_or(500))?,
    };
    Ok(vessels)
}

/// `[vessels] known`: valid ids, sorted, once each.
fn known_vessels(mut known: Vec<String>) -> Result<Vec<String>, SettingsError> {
    for id in &known {
        twin_wire::keys::validate_vessel_id(id).map_err(|e| SettingsError::Invalid {
            key: "vessels.known",
            reason: format!("{id:?}: {e}"),
        })?;
    }
    known.sort();
    known.dedup();
    Ok(known)
}

/// `n`, refused when zero.
fn at_least_one(key: &'static str, n: usize) -> Result<usize, SettingsError> {
    if n == 0 {
        return Err(SettingsError::Invalid {
            key,
            reason: "must be at least 1".into(),
        });
    }
    Ok(n)
}

/// `[publish]`, validated.
fn publish_settings(raw: RawPublish) -> Result<PublishSettings, SettingsError> {
    let publish = PublishSettings {
        prediction_interval_s: positive(
            "publish.prediction_interval_s",
            raw.prediction_interval_s.unwrap_or(1.0),
        )?,
        prediction_horizon_s: positive(
            "publish.prediction_horizon_s",
            raw.prediction_horizon_s.unwrap_or(60.0),
        )?,
        prediction_step_s: positive(
            "publish.prediction_step_s",
            raw.prediction_step_s.unwrap_or(1.0),
        )?,
        stats_interval_s: positive(
            "publish.stats_interval_s",
            raw.stats_interval_s.unwrap_or(5.0),
        )?,
        vessel_liveliness: raw.vessel_liveliness.unwrap_or(true),
        vessel_liveliness_key: match raw.vessel_liveliness_key {
            Some(template) => Some(liveliness_key_template(template)?),
            None => None,
        },
        forecast_threads: match raw.forecast_threads.unwrap_or(0) {
            0 => std::thread::available_parallelism()
                .map(|n| (n.get() / 2).max(1))
                .unwrap_or(1),
            n if n > 256 => {
                return Err(SettingsError::Invalid {
                    key: "publish.forecast_threads",
                    reason: format!("{n} threads: at most 256"),
                });
            }
            n => n,
        },
    };
    if publish.prediction_horizon_s / publish.prediction_step_s > 3600.0 {
        return Err(SettingsError::Invalid {
            key: "publish.prediction_step_s",
            reason: "more than 3600 forecast points per horizon".into(),
        });
    }
    Ok(publish)
}

/// `[twin]`: the estimator's settings over its defaults, validated.
fn twin_config(raw: &RawTwin) -> Result<TwinConfig, SettingsError> {
    let mut twin = TwinConfig::default();
    if let Some(b) = raw.estimate_current {
        twin.kinetic.estimate_current = b;
    }
    if let Some(t) = raw.forgetting_time_constant_s {
        twin.kinetic.filter.forgetting_time_constant_s =
            positive("twin.forgetting_time_constant_s", t)?;
    }
    if let Some(v) = raw.suspect_loss {
        twin.decision.suspect_loss = fraction("twin.suspect_loss", v)?;
    }
    if let Some(v) = raw.fault_loss {
        twin.decision.fault_loss = fraction("twin.fault_loss", v)?;
    }
    if let Some(v) = raw.clear_loss {
        twin.decision.clear_loss = fraction("twin.clear_loss", v)?;
    }
    let d = twin.decision;
    if !(d.clear_loss < d.suspect_loss && d.suspect_loss <= d.fault_loss) {
        return Err(SettingsError::Invalid {
            key: "twin.suspect_loss",
            reason: format!(
                "need clear_loss < suspect_loss <= fault_loss, got {} / {} / {}",
                d.clear_loss, d.suspect_loss, d.fault_loss
            ),
        });
    }
    Ok(twin)
}

fn diagnose_settings(raw: &RawDiagnose) -> Result<DiagnoseSettings, SettingsError> {
    let d = MonitorConfig::default();
    let monitor = MonitorConfig {
        window_s: raw.window_s.unwrap_or(d.window_s),
        min_window_s: raw.min_window_s.unwrap_or(d.min_window_s),
        interval_s: raw.interval_s.unwrap_or(d.interval_s),
        min_interval_s: raw.min_interval_s.unwrap_or(d.min_interval_s),
        bias_window_s: raw.bias_window_s.unwrap_or(d.bias_window_s),
        bias_t: raw.bias_t.unwrap_or(d.bias_t),
        new_track_gap_s: d.new_track_gap_s,
    };
    monitor
        .validate()
        .map_err(|(field, reason)| SettingsError::Invalid {
            key: match field {
                "window_s" => "diagnose.window_s",
                "min_window_s" => "diagnose.min_window_s",
                "interval_s" => "diagnose.interval_s",
                "min_interval_s" => "diagnose.min_interval_s",
                "bias_window_s" => "diagnose.bias_window_s",
                "bias_t" => "diagnose.bias_t",
                _ => "diagnose",
            },
            reason,
        })?;
    if monitor.window_s > 3600.0 {
        return Err(SettingsError::Invalid {
            key: "diagnose.window_s",
            reason: format!(
                "at most 3600 s of history are kept, got {}",
                monitor.window_s
            ),
        });
    }
    let max_concurrent = raw.max_concurrent.unwrap_or(1);
    if max_concurrent == 0 {
        return Err(SettingsError::Invalid {
            key: "diagnose.max_concurrent",
            reason: "must be at least 1 (set diagnose.enabled = false to turn it off)".into(),
        });
    }
    Ok(DiagnoseSettings {
        enabled: raw.enabled.unwrap_or(true),
        monitor,
        max_concurrent,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_and_the_shipped_file_are_valid() {
        let s = Settings::default();
        assert_eq!(s.keys.prefix(), "asv");
        assert_eq!(s.vessels.own, "*");
        assert!(!s.web.enabled);
        let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/twind.toml");
        let file = Settings::from_file(Path::new(shipped)).unwrap();
        // The contract's per-vessel liveliness token is on unless asked off.
        assert!(s.publish.vessel_liveliness);
        assert!(file.publish.vessel_liveliness);
        let off = Settings::from_toml("[publish]\nvessel_liveliness = false\n").unwrap();
        assert!(!off.publish.vessel_liveliness);
    }

    /// The token's key is the contract's unless a template moves it; bad
    /// templates are refused with the key named.
    #[test]
    fn the_liveliness_key_is_the_contracts_unless_moved() {
        let v = twin_wire::VesselId::new("otter-1").unwrap();
        let s = Settings::default();
        assert_eq!(
            s.publish.liveliness_key(&s.keys, &v),
            "asv/otter-1/twin/alive"
        );
        let moved = Settings::from_toml(
            "[publish]\nvessel_liveliness_key = \"asv-twins/alive/{vessel}\"\n",
        )
        .unwrap();
        assert_eq!(
            moved.publish.liveliness_key(&moved.keys, &v),
            "asv-twins/alive/otter-1"
        );
        for bad in [
            "asv-alive",
            "a/{vessel}/{vessel}",
            "a/*/{vessel}",
            "a//{vessel}",
            "$x/{vessel}",
        ] {
            let err =
                Settings::from_toml(&format!("[publish]\nvessel_liveliness_key = \"{bad}\"\n"))
                    .unwrap_err()
                    .to_string();
            assert!(
                err.contains("publish.vessel_liveliness_key"),
                "{bad}: {err}"
            );
        }
    }

    #[test]
    fn tile_urls_are_templates_with_a_fixed_host() {
        let s = Settings::default();
        assert_eq!(s.web.tiles, None, "no tiles unless asked");
        let ok = Settings::from_toml(
            "[web]\ntile_url = \"https://tile.openstreetmap.org/{z}/{x}/{y}.png\"\n\
             tile_overlay_url = \"https://tiles.openseamap.org/seamark/{z}/{x}/{y}.png\"\n\
             tile_attribution = \"© OpenStreetMap contributors, OpenSeaMap\"\n",
        )
        .unwrap();
        let tiles = ok.web.tiles.unwrap();
        assert_eq!(
            tiles.url.as_deref(),
            Some("https://tile.openstreetmap.org/{z}/{x}/{y}.png")
        );
        assert_eq!(
            tiles.overlay_url.as_deref(),
            Some("https://tiles.openseamap.org/seamark/{z}/{x}/{y}.png")
        );
        assert_eq!(
            tiles.attribution,
            "© OpenStreetMap contributors, OpenSeaMap"
        );
        assert_eq!(tiles.max_zoom, DEFAULT_TILE_MAX_ZOOM);
        let local = Settings::from_toml(
            "[web]\ntile_url = \"http://127.0.0.1:8081/t/{z}/{y}/{x}?style=1\"\n\
             tile_attribution = \"local\"\ntile_max_zoom = 12\n",
        )
        .unwrap();
        assert_eq!(local.web.tiles.unwrap().max_zoom, 12);

        let attribution = "tile_attribution = \"x\"\n";
        let bad = [
            ("ftp://h/{z}/{x}/{y}.png", "http:// or https://"),
            (
                "tile.openstreetmap.org/{z}/{x}/{y}.png",
                "http:// or https://",
            ),
            ("https://h/{z}/{x}.png", "no {y}"),
            ("https://h/{x}/{y}.png", "no {z}"),
            ("https://h/{z}/{y}.png", "no {x}"),
            ("https://{s}.tile.example/{z}/{x}/{y}.png", "fixed host"),
            ("https://h/{s}/{z}/{x}/{y}.png", "no {s}"),
            ("https://user@h/{z}/{x}/{y}.png", "fixed host"),
            ("https://h/{z}/{x}/{y}.png; img-src *", "has ';'"),
            ("https://h/{z} /{x}/{y}.png", "has ' '"),
            ("https:///{z}/{x}/{y}.png", "fixed host"),
        ];
        for (key, extra) in [
            ("web.tile_url", attribution),
            ("web.tile_overlay_url", attribution),
        ] {
            let name = key.trim_start_matches("web.");
            for (url, why) in bad {
                let text = format!("[web]\n{name} = \"{url}\"\n{extra}");
                let err = Settings::from_toml(&text).unwrap_err().to_string();
                assert!(err.contains(key) && err.contains(why), "{text:?}: {err}");
            }
        }
        // A tile URL needs its attribution; an attribution needs tiles.
        for text in [
            "[web]\ntile_url = \"https://h/{z}/{x}/{y}.png\"\n",
            "[web]\ntile_overlay_url = \"https://h/{z}/{x}/{y}.png\"\ntile_attribution = \" \"\n",
            "[web]\ntile_attribution = \"© OpenStreetMap contributors\"\n",
        ] {
            let err = Settings::from_toml(text).unwrap_err().to_string();
            assert!(err.contains("web.tile_attribution"), "{text:?}: {err}");
        }
    }

    #[test]
    fn errors_name_the_bad_key() {
        let cases = [
            (
                "[publish]\nprediction_step_s = -1\n",
                "publish.prediction_step_s",
            ),
            ("[vessels]\nown = \"a/b\"\n", "vessels.own"),
            ("[keys]\nprefix = \"a b\"\n", "keys.prefix"),
            (
                "[input]\nmax_payload_bytes = 10\n",
                "input.max_payload_bytes",
            ),
            ("[web]\nlisten = \"nowhere\"\n", "web.listen"),
            ("[metrics]\nlisten = \"nowhere\"\n", "metrics.listen"),
            (
                "[twin]\nsuspect_loss = 0.5\nfault_loss = 0.2\n",
                "twin.suspect_loss",
            ),
            ("[vessels]\nqueue_depth = 0\n", "vessels.queue_depth"),
            ("[diagnose]\nmin_window_s = 900\n", "diagnose.min_window_s"),
            ("[diagnose]\nbias_t = 0\n", "diagnose.bias_t"),
            ("[diagnose]\nwindow_s = 7200\n", "diagnose.window_s"),
            (
                "[diagnose]\nmax_concurrent = 0\n",
                "diagnose.max_concurrent",
            ),
            ("[vessels]\nknown = [\"a b\"]\n", "vessels.known"),
            ("[vessels]\nadmit_per_s = 0\n", "vessels.admit_per_s"),
            ("[vessels]\nadmit_burst = 0\n", "vessels.admit_burst"),
            ("[input]\nlive_max_ahead_s = -1\n", "input.live_max_ahead_s"),
            ("[daemon]\nid = \"a/b\"\n", "daemon.id"),
            ("[web]\ntile_max_zoom = 30\n", "web.tile_max_zoom"),
        ];
        for (text, key) in cases {
            let err = Settings::from_toml(text).unwrap_err().to_string();
            assert!(err.contains(key), "{text:?}: {err}");
        }
        // Unknown keys and wrong types are refused by name too.
        let err = Settings::from_toml("[publish]\nprediction_horizon = 5\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("prediction_horizon"), "{err}");
        let err = Settings::from_toml("[vessels]\nstale_after_s = \"soon\"\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("stale_after_s"), "{err}");
    }

    /// A profile file in a fresh directory: the Otter's with `name`, and
    /// `key = value` replaced.
    fn profile_file(dir: &Path, name: &str, key: &str, value: &str) -> PathBuf {
        let text = twin_wire::profile::OTTER_PROFILE_TOML
            .lines()
            .map(|l| match l.split('=').next().map(str::trim) {
                Some("name") => format!("name = \"{name}\""),
                Some(k) if k == key => format!("{key} = {value}"),
                _ => l.to_owned(),
            })
            .collect::<Vec<_>>()
            .join("\n");
        std::fs::create_dir_all(dir).unwrap();
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, text).unwrap();
        path
    }

    /// Vessels map to profiles by id, then by pattern, then the default;
    /// relative profile paths are the settings file's.
    #[test]
    fn vessels_run_on_the_profiles_their_rules_name() {
        let dir = std::env::temp_dir().join(format!("twind-profiles-{}", std::process::id()));
        profile_file(&dir.join("profiles"), "cat", "mass_kg", "160.0");
        let settings_path = dir.join("twind.toml");
        std::fs::write(
            &settings_path,
            "[profiles]\nfiles = [\"profiles/cat.toml\"]\nvessels = [\n  \
             { id = \"survey-7\", profile = \"otter\" },\n  \
             { id = \"survey-*\", profile = \"cat\" },\n]\n",
        )
        .unwrap();
        let settings = Settings::from_file(&settings_path).unwrap();
        let name = |id: &str| settings.profiles.for_vessel(id).name.clone();
        assert_eq!(name("survey-7"), "otter");
        assert_eq!(name("survey-12"), "cat");
        assert_eq!(name("otter-1"), "otter");
        let (config, profile) = settings.twin_for("survey-3");
        assert_eq!(config.kinetic.params.mass_kg, 160.0);
        assert_eq!(profile.name, "cat");
        // The settings' tuning is kept on the vessel's profile.
        assert_eq!(config.decision, settings.twin.decision);
        assert_eq!(settings.twin_for("otter-1").0, settings.twin);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn id_patterns_match_as_globs() {
        assert!(id_matches("survey-*", "survey-12"));
        assert!(id_matches("*-b", "a-b"));
        assert!(id_matches("a*c*e", "abcde"));
        assert!(!id_matches("a*c*e", "abcdf"));
        assert!(!id_matches("survey-*", "north-survey-1"));
        assert!(id_matches("otter-1", "otter-1"));
        assert!(!id_matches("otter-1", "otter-12"));
        assert!(!id_matches("ab*ba", "aba"));
    }

    /// A profile the daemon cannot use stops it at start, with the file
    /// and the profile's key named.
    #[test]
    fn a_bad_profile_or_an_unknown_name_is_refused_at_start() {
        let dir = std::env::temp_dir().join(format!("twind-bad-profiles-{}", std::process::id()));
        let cases = [
            ("mass_kg", "-5.0", "mass.mass_kg"),
            ("lateral_offset_m", "0.0", "propellers.lateral_offset_m"),
            ("mass_kg", "80.0\nmass_lb = 176.0", "mass_lb"),
        ];
        for (key, value, named) in cases {
            let path = profile_file(&dir, "bad", key, value);
            let text = format!("[profiles]\nfiles = [{:?}]\n", path.display().to_string());
            let err = Settings::from_toml(&text).unwrap_err().to_string();
            assert!(
                err.contains("profiles.files") && err.contains(named),
                "{err}"
            );
            assert!(err.contains("bad.toml"), "{err}");
        }
        let missing = "[profiles]\nfiles = [\"/nonexistent/cat.toml\"]\n";
        let err = Settings::from_toml(missing).unwrap_err().to_string();
        assert!(err.contains("cannot read"), "{err}");
        let err = Settings::from_toml("[profiles]\ndefault = \"cat\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("profiles.default") && err.contains("\"cat\""),
            "{err}"
        );
        let rule = "[profiles]\nvessels = [{ id = \"x-*\", profile = \"cat\" }]\n";
        let err = Settings::from_toml(rule).unwrap_err().to_string();
        assert!(err.contains("profiles.vessels"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
