//! The process's own CPU time and resident memory, from `/proc` (Linux).
//! Elsewhere every reading is `None` and the table says "not measured".
//!
//! CPU times in `/proc/<pid>/stat` are in clock ticks; the kernel's
//! `USER_HZ` is 100 on every Linux architecture the project targets (it is
//! fixed by the ABI, whatever the kernel's internal `HZ`), so a tick is 10 ms.
//! Over a 10 s window that resolves CPU use to 0.1 % of a core.

use std::collections::BTreeMap;

/// Clock ticks per second of `/proc/*/stat` (`USER_HZ`).
pub const TICKS_PER_S: f64 = 100.0;

/// The resident set size of this process, KiB (`VmRSS` of
/// `/proc/self/status`).
pub fn rss_kib() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    text.lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
}

/// User + system time of a `stat` line, ticks, and the thread's name. The
/// name (`comm`) is in parentheses and may itself hold spaces or
/// parentheses, so the fields are counted from the last `)`.
fn parse_stat(text: &str) -> Option<(String, u64)> {
    let open = text.find('(')?;
    let close = text.rfind(')')?;
    let name = text.get(open + 1..close)?.to_string();
    // After ")": state (field 3), ..., utime (14), stime (15).
    let mut fields = text.get(close + 1..)?.split_whitespace();
    let utime: u64 = fields.nth(11)?.parse().ok()?;
    let stime: u64 = fields.next()?.parse().ok()?;
    Some((name, utime + stime))
}

/// User + system CPU time of the whole process so far (every thread, also
/// those that have ended), ticks.
pub fn process_ticks() -> Option<u64> {
    parse_stat(&std::fs::read_to_string("/proc/self/stat").ok()?).map(|(_, t)| t)
}

/// User + system CPU time of each live thread, ticks, by thread id, with
/// the thread's name.
pub fn thread_ticks() -> BTreeMap<u32, (String, u64)> {
    let mut out = BTreeMap::new();
    let Ok(dir) = std::fs::read_dir("/proc/self/task") else {
        return out;
    };
    for entry in dir.flatten() {
        let Some(tid) = entry.file_name().to_str().and_then(|s| s.parse().ok()) else {
            continue;
        };
        if let Some(parsed) = std::fs::read_to_string(entry.path().join("stat"))
            .ok()
            .and_then(|t| parse_stat(&t))
        {
            out.insert(tid, parsed);
        }
    }
    out
}

/// Which part of the benchmark a thread belongs to, from its name: the
/// daemon's tokio workers (`twind-rt`), its forecast threads
/// (`twind-forecast-N`, cut to 15 characters by the kernel), the load
/// generator (`bench-gen`),
/// Zenoh's own runtimes (`rx-0`, `tx-0`, `net-0`, `app-0`, `acc-0`: shared by
/// every session of the process; they also run the subscriber's callback),
/// or anything else (the main thread, blocking pools).
pub fn thread_group(name: &str) -> &'static str {
    let base = name.trim_end_matches(|c: char| c.is_ascii_digit() || c == '-');
    match base {
        "twind-rt" => "daemon (twind's tokio workers)",
        "twind-forecast" => "daemon (forecast threads, SCHED_IDLE)",
        "bench-gen" => "load generator",
        "rx" | "tx" | "net" | "app" | "acc" => "Zenoh runtimes (all sessions, subscriber callback)",
        _ => "other",
    }
}

/// CPU ticks spent by each thread group between two [`thread_ticks`]
/// readings (threads born in between count from zero; threads that ended
/// in between are missing: the process total is the authoritative figure).
pub fn group_ticks(
    before: &BTreeMap<u32, (String, u64)>,
    after: &BTreeMap<u32, (String, u64)>,
) -> BTreeMap<String, u64> {
    let mut out = BTreeMap::new();
    for (tid, (name, ticks)) in after {
        let start = before.get(tid).map_or(0, |(_, t)| *t);
        *out.entry(thread_group(name).to_string()).or_default() += ticks.saturating_sub(start);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_a_stat_line_with_an_awkward_name() {
        let line = "4242 (a (b) c) S 1 2 3 4 5 6 7 8 9 10 123 45 0 0 20 0 1 0 100 200 300";
        assert_eq!(parse_stat(line), Some(("a (b) c".into(), 168)));
    }

    #[test]
    fn groups_threads_by_name() {
        assert_eq!(thread_group("rx-1"), thread_group("tx-0"));
        assert_eq!(thread_group("twind-rt"), "daemon (twind's tokio workers)");
        assert_eq!(thread_group("bench-gen"), "load generator");
        assert_eq!(
            thread_group("twind-forecast-"),
            "daemon (forecast threads, SCHED_IDLE)"
        );
        assert_eq!(thread_group("twin-bench"), "other");
    }

    #[test]
    fn reads_this_process_on_linux() {
        if cfg!(target_os = "linux") {
            assert!(rss_kib().unwrap() > 0);
            assert!(process_ticks().is_some());
            assert!(!thread_ticks().is_empty());
        }
    }
}
