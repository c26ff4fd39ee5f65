//! A calibration is saved durably (item 8): the new file's data are flushed
//! to the disk before it is renamed over the old one, and the directory is
//! flushed after the rename, so that a power cut leaves the old calibration
//! or the new one, never an empty or a missing file.
//!
//! A power cut cannot be made in a test; what can be seen is the sequence
//! of system calls. The test runs itself again (the same test binary, the
//! save alone) under `strace`, an independent observer of what the process
//! asks of the kernel, and reads the `fsync` and `rename` calls from its
//! trace. `strace` is a Debian package (`apt-get install strace`), installed
//! by `.ci/run`; without it the test fails and says so.

use std::process::Command;

use twin_core::decision::{ThrusterDecision, ThrusterStatus};
use twin_core::twin::{Calibration, FaultSource};

/// Set in the child: the directory to save into.
const CHILD_DIR: &str = "TWIND_DURABILITY_CHILD_DIR";
/// The profile the calibrations are learnt with.
const OTTER: &str = "otter@0000000000000000";

fn calibration() -> Calibration {
    Calibration {
        source: FaultSource::SeedMethod,
        theta: vec![0.25, 0.0],
        theta_covariance: vec![1e-4, 0.0, 0.0, 1e-4],
        held_information: vec![100.0, 100.0],
        surroundings: None,
        decisions: [
            ThrusterDecision {
                status: ThrusterStatus::Fault,
                onset_time_s: Some(1_700_000_000.0),
            },
            ThrusterDecision {
                status: ThrusterStatus::Nominal,
                onset_time_s: None,
            },
        ],
        time_s: 1_700_000_100.0,
    }
}

#[test]
fn a_save_flushes_the_file_before_the_rename_and_the_directory_after() {
    if let Ok(dir) = std::env::var(CHILD_DIR) {
        // The child: one save, traced by the parent's strace.
        twind::persist::save(std::path::Path::new(&dir), "otter-1", &calibration(), OTTER).unwrap();
        return;
    }
    let dir = std::env::temp_dir().join(format!("twind-durability-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // A calibration already there, as after an earlier save.
    twind::persist::save(&dir, "otter-1", &calibration(), OTTER).unwrap();
    let trace = dir.join("strace.log");
    let exe = std::env::current_exe().unwrap();
    let status = Command::new("strace")
        .args(["-f", "-qq", "-y", "-e", "signal=none"])
        .args(["-e", "trace=fsync,fdatasync,rename,renameat,renameat2"])
        .arg("-o")
        .arg(&trace)
        .arg(&exe)
        .args([
            "--exact",
            "a_save_flushes_the_file_before_the_rename_and_the_directory_after",
            "--test-threads=1",
        ])
        .env(CHILD_DIR, &dir)
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap_or_else(|e| {
            panic!("strace could not be run ({e}): install it with `apt-get install strace`")
        });
    assert!(status.success(), "the traced save failed: {status}");
    let text = std::fs::read_to_string(&trace).unwrap();
    let calls: Vec<&str> = text
        .lines()
        .filter(|l| l.contains("fsync") || l.contains("rename"))
        .collect();
    println!("{}", calls.join("\n"));
    let position = |what: &dyn Fn(&str) -> bool, name: &str| -> usize {
        calls
            .iter()
            .position(|l| what(l))
            .unwrap_or_else(|| panic!("no {name} in the trace:\n{}", calls.join("\n")))
    };
    let tmp = ".otter-1.json.tmp";
    let dir_text = dir.to_string_lossy().into_owned();
    let file_synced = position(
        &|l| (l.contains("fsync(") || l.contains("fdatasync(")) && l.contains(tmp),
        "flush of the new file",
    );
    let renamed = position(
        &|l| l.contains("rename") && l.contains(tmp) && l.contains("otter-1.json\""),
        "rename over the old file",
    );
    let dir_synced = position(
        &|l| l.contains("fsync(") && l.contains(&format!("<{dir_text}>")),
        "flush of the directory",
    );
    assert!(
        file_synced < renamed && renamed < dir_synced,
        "order: file flushed {file_synced}, renamed {renamed}, directory flushed {dir_synced}"
    );
    let saved = twind::persist::load(&dir, "otter-1", OTTER).unwrap();
    assert_eq!(saved, Some(calibration()));
    std::fs::remove_dir_all(&dir).unwrap();
}
