//! What the machine was doing while a benchmark ran: the load average, the
//! number of cores and the processor. The machine is shared, so every figure
//! is printed beside these.

/// The 1, 5 and 15 minute load averages, from `/proc/loadavg`, or `None`
/// where that file does not exist (not Linux).
pub fn load_average() -> Option<[f64; 3]> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    let mut it = text.split_whitespace().map(|v| v.parse::<f64>().ok());
    Some([it.next()??, it.next()??, it.next()??])
}

/// The load averages as `"1.23 0.98 0.75"`, or `"unknown"`.
pub fn load_average_text() -> String {
    match load_average() {
        Some([a, b, c]) => format!("{a:.2} {b:.2} {c:.2}"),
        None => "unknown".into(),
    }
}

/// The processor's model name, from `/proc/cpuinfo`, or `"unknown"`.
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}

/// Cores this process may use.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn load_average_reads_on_linux() {
        if cfg!(target_os = "linux") {
            let l = load_average().unwrap();
            assert!(l.iter().all(|v| v.is_finite() && *v >= 0.0), "{l:?}");
        }
        assert!(cores() >= 1);
    }
}
