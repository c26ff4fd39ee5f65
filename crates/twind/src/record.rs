//! `twind --record FILE`: the owned vessels' inputs and the twin's outputs,
//! as the network carries them, written to an MCAP file
//! (`twin_wire::mcap`: a JSON channel per vessel and topic with its JSON
//! Schema, and a Foxglove location per state).
//!
//! A Zenoh subscriber on `{prefix}/{own}/**` hands every sample to a
//! writer thread through a bounded queue: the recording never holds up the
//! twin; what does not fit in the queue is dropped and counted. Log times
//! are the daemon's clock when the sample arrived (a live recording; `twin
//! analyze --mcap` uses the messages' own times instead). The file is
//! finished (summary and indexes written) when the daemon stops.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::time::{SystemTime, UNIX_EPOCH};

use twin_wire::Topic;
use twin_wire::mcap::{McapError, McapRecorder};
use zenoh::Session;
use zenoh::pubsub::Subscriber;

use crate::settings::Settings;

/// Samples waiting for the writer; more are dropped.
const QUEUE_DEPTH: usize = 8192;

/// One sample to write: vessel, topic, payload, arrival time (s since the epoch).
type Item = (String, Topic, Vec<u8>, f64);

/// What a recording wrote.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RecordSummary {
    /// The file.
    pub path: PathBuf,
    /// Messages written per channel topic.
    pub counts: BTreeMap<String, u64>,
    /// Samples dropped because the writer fell behind.
    pub dropped: u64,
    /// Samples not written: not a vessel's topic, or not JSON where JSON
    /// is due.
    pub refused: u64,
    /// Why the file could not be written or finished, if it could not.
    pub error: Option<String>,
}

/// A running recording.
pub struct Recorder {
    path: PathBuf,
    subscriber: Subscriber<()>,
    queue: SyncSender<Item>,
    dropped: Arc<AtomicU64>,
    writer: std::thread::JoinHandle<(BTreeMap<String, u64>, u64, Option<String>)>,
}

/// The vessel and topic of `key` under `prefix`, if it is one.
fn vessel_topic(prefix: &str, key: &str) -> Option<(String, Topic)> {
    let rest = key.strip_prefix(prefix)?.strip_prefix('/')?;
    let (vessel, suffix) = rest.split_once('/')?;
    Some((vessel.to_owned(), Topic::from_suffix(suffix)?))
}

/// The writer thread: every item into `recorder` until the queue closes.
fn write_all(
    mut recorder: McapRecorder<BufWriter<File>>,
    queue: &Receiver<Item>,
) -> (BTreeMap<String, u64>, u64, Option<String>) {
    let mut refused = 0;
    for (vessel, topic, payload, time_s) in queue.iter() {
        match recorder.record(&vessel, topic, &payload, time_s) {
            Ok(()) => {}
            Err(McapError::NotJson { .. }) => refused += 1,
            Err(e) => return (recorder.counts().clone(), refused, Some(e.to_string())),
        }
    }
    match recorder.finish() {
        Ok(counts) => (counts, refused, None),
        Err(e) => (BTreeMap::new(), refused, Some(e.to_string())),
    }
}

impl Recorder {
    /// Creates `path` and starts recording what the daemon owns.
    pub async fn start(
        session: &Session,
        settings: &Settings,
        path: &Path,
    ) -> anyhow::Result<Self> {
        let file = File::create(path)
            .map_err(|e| anyhow::anyhow!("cannot create the recording {}: {e}", path.display()))?;
        let recorder = McapRecorder::new(BufWriter::new(file))
            .map_err(|e| anyhow::anyhow!("cannot start the recording {}: {e}", path.display()))?;
        let (queue, received) = sync_channel::<Item>(QUEUE_DEPTH);
        let writer = std::thread::Builder::new()
            .name("twind-record".into())
            .spawn(move || write_all(recorder, &received))?;
        let dropped = Arc::new(AtomicU64::new(0));
        let key = format!("{}/{}/**", settings.keys.prefix(), settings.vessels.own);
        let prefix = settings.keys.prefix().to_owned();
        let subscriber = {
            let queue = queue.clone();
            let dropped = dropped.clone();
            session
                .declare_subscriber(&key)
                .callback(move |sample| {
                    let Some((vessel, topic)) = vessel_topic(&prefix, sample.key_expr().as_str())
                    else {
                        return;
                    };
                    let time_s = SystemTime::now()
                        .duration_since(UNIX_EPOCH)
                        .map_or(0.0, |d| d.as_secs_f64());
                    let item = (
                        vessel,
                        topic,
                        sample.payload().to_bytes().into_owned(),
                        time_s,
                    );
                    if let Err(TrySendError::Full(_)) = queue.try_send(item) {
                        dropped.fetch_add(1, Ordering::Relaxed);
                    }
                })
                .await
                .map_err(|e| anyhow::anyhow!("cannot subscribe to {key} to record it: {e}"))?
        };
        tracing::info!(file = %path.display(), keys = %key, "recording");
        Ok(Self {
            path: path.to_path_buf(),
            subscriber,
            queue,
            dropped,
            writer,
        })
    }

    /// Stops recording, finishes the file, and says what it holds.
    pub async fn finish(self) -> RecordSummary {
        let Self {
            path,
            subscriber,
            queue,
            dropped,
            writer,
        } = self;
        if let Err(e) = subscriber.undeclare().await {
            tracing::warn!("the recording's subscriber: {e}");
        }
        drop(queue);
        let (counts, refused, error) = tokio::task::spawn_blocking(move || writer.join())
            .await
            .ok()
            .and_then(Result::ok)
            .unwrap_or_else(|| (BTreeMap::new(), 0, Some("the writer thread failed".into())));
        if let Some(e) = &error {
            tracing::error!(file = %path.display(), "recording: {e}");
        }
        RecordSummary {
            path,
            counts,
            dropped: dropped.load(Ordering::Relaxed),
            refused,
            error,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_name_their_vessel_and_topic() {
        assert_eq!(
            vessel_topic("asv", "asv/otter-1/twin/fault"),
            Some(("otter-1".into(), Topic::TwinFault))
        );
        assert_eq!(
            vessel_topic("asv", "asv/otter-1/gnss"),
            Some(("otter-1".into(), Topic::Gnss))
        );
        assert_eq!(vessel_topic("asv", "asv/otter-1/twin/alive/x"), None);
        assert_eq!(vessel_topic("asv", "other/otter-1/gnss"), None);
        assert_eq!(vessel_topic("asv", "asvx/otter-1/gnss"), None);
    }
}
