//! The human summary of `twin analyze` ([`Analysis::to_text`]) and the JSON
//! report ([`Analysis::to_json`]).

use std::collections::BTreeMap;

use twin_wire::outputs::ThrusterStatusName;

use super::report::Analysis;
use super::{NOT_OBSERVABLE_NOTE, SEED_NOTE};

fn format_title(f: &str) -> &'static str {
    match f {
        "nmea0183" => "NMEA 0183 text",
        "n2k" => "canboat NMEA 2000 text",
        "json_lines" => "the project's JSON lines",
        _ => "unknown",
    }
}

impl Analysis {
    /// The JSON report (one object, pretty-printed).
    pub fn to_json(&self) -> String {
        // Every field serialises (no maps with non-string keys, no NaN: the
        // writer turns non-finite floats into null).
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\":\"{e}\"}}"))
    }

    /// The human summary.
    #[allow(clippy::too_many_lines)] // The summary's sections, in the order printed.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let w = &mut s;
        let _ = writeln!(w, "twin analyze {}", self.log);
        let _ = writeln!(w, "  profile      {}", self.profile);
        let _ = writeln!(w, "  format       {}", format_title(self.format));
        match &self.span {
            Some(sp) => {
                let _ = writeln!(
                    w,
                    "  span         {} .. {} ({})",
                    sp.start,
                    sp.end,
                    duration_text(sp.duration_s)
                );
            }
            None => {
                let _ = writeln!(w, "  span         no record");
            }
        }
        if self.read.undated > 0 {
            let _ = writeln!(
                w,
                "               ({} records carry no date: 1970-01-01 assumed, times are of day)",
                self.read.undated
            );
        }
        let src = |o: &Option<String>| o.clone().unwrap_or_else(|| "-".to_string());
        let _ = writeln!(
            w,
            "  sources      position {}, course/speed {}, heading {}, yaw rate {}",
            src(&self.sources.position),
            src(&self.sources.course),
            src(&self.sources.heading),
            src(&self.sources.yaw_rate)
        );
        let records: Vec<String> = self
            .read
            .records_by_kind()
            .map(|(k, n)| format!("{n} {}", k.name()))
            .collect();
        let _ = writeln!(
            w,
            "  read         {} lines: {}; {} ignored, {} empty",
            self.read.lines,
            if records.is_empty() {
                "no record".to_string()
            } else {
                records.join(", ")
            },
            self.read.ignored,
            self.read.empty
        );
        let asm = &self.assembled;
        let mut dropped = Vec::new();
        for (n, what) in [
            (asm.positions_other_sources, "positions of other sources"),
            (asm.positions_repeated, "re-sent positions"),
            (
                asm.positions_not_after_previous,
                "positions not after the previous fix",
            ),
            (asm.courses_other_sources, "courses of other sources"),
            (asm.courses_unused, "courses not joined"),
            (asm.headings_other_sources, "headings of other sources"),
            (asm.propeller_unpaired, "unpaired shaft speeds"),
            (asm.thrust_commands, "thrust commands (unused)"),
            (asm.out_of_order, "out of order"),
        ] {
            if n > 0 {
                dropped.push(format!("{n} {what}"));
            }
        }
        let _ = writeln!(
            w,
            "  assembled    {} fixes ({} with course/speed, {} with heading, {} with yaw rate), {} propeller samples{}",
            asm.fixes,
            asm.fixes_with_course,
            asm.fixes_with_heading,
            asm.fixes_with_yaw_rate,
            asm.propeller_pairs,
            if dropped.is_empty() {
                String::new()
            } else {
                format!("; not used: {}", dropped.join(", "))
            }
        );
        let _ = writeln!(
            w,
            "  used         {} fixes, {} propeller samples",
            self.samples_by_kind.fixes, self.samples_by_kind.propellers
        );
        let reasons = |m: &BTreeMap<String, u64>| -> String {
            m.iter()
                .map(|(k, v)| format!("{v} {k}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let rr = &self.rejected_by_reason;
        let _ = writeln!(
            w,
            "  rejected     {} in all: reader {}, twin fixes {}, twin propellers {}",
            self.rejected,
            or_none(&reasons(&rr.reader)),
            or_none(&reasons(&rr.twin_fixes)),
            or_none(&reasons(&rr.twin_propellers))
        );
        for e in &self.first_rejections {
            let _ = writeln!(
                w,
                "               first {} ({}): {}",
                e.reason, e.stage, e.detail
            );
        }

        for (name, q) in [
            ("extended twin", &self.quality.kinetic),
            ("seed method", &self.quality.seed_method),
        ] {
            let Some(q) = q else { continue };
            let _ = writeln!(w, "  quality      {name}, {} steps", q.steps);
            let r = &q.innovation_rms;
            let mut parts = Vec::new();
            if let Some(v) = r.north_m {
                parts.push(format!("north {v:.2} m"));
            }
            if let Some(v) = r.east_m {
                parts.push(format!("east {v:.2} m"));
            }
            if let Some(v) = r.sog_mps {
                parts.push(format!("SOG {v:.3} m/s"));
            }
            if let Some(v) = r.cog_rad {
                parts.push(format!("COG {:.2} deg", v.to_degrees()));
            }
            if let Some(v) = r.heading_rad {
                parts.push(format!("heading {:.2} deg", v.to_degrees()));
            }
            let _ = writeln!(w, "    innovation RMS  {}", parts.join(", "));
            let _ = writeln!(
                w,
                "    NIS             mean {:.2} over {:.1} dof = {:.2} per dof; 95 % band {:.3}..{:.3}: {}; {:.1} % of steps above their 95 % quantile (5 % expected)",
                q.mean_nis,
                q.mean_dof,
                q.mean_nis_per_dof,
                q.nis_band_95[0],
                q.nis_band_95[1],
                if q.nis_within_band {
                    "within"
                } else if q.mean_nis_per_dof > q.nis_band_95[1] {
                    "ABOVE (the model or its noise levels do not explain the data)"
                } else {
                    "below (the noise levels are pessimistic)"
                },
                100.0 * q.fraction_above_95
            );
        }
        if self.quality.kinetic.is_none() && self.quality.seed_method.is_none() {
            let _ = writeln!(
                w,
                "  quality      no filter step: {}",
                if self.assembled.fixes == 0 {
                    "no GNSS fix could be assembled from this log (no position records)"
                } else {
                    "fewer than two fixes were accepted"
                }
            );
        }

        let t = &self.thrusters;
        if t.observable {
            let _ = writeln!(
                w,
                "  thrusters    extended twin (propeller speeds), at {}: {}",
                t.time.clone().unwrap_or_default(),
                status_text(t.status)
            );
            for (name, th) in [("port", &t.port), ("starboard", &t.starboard)] {
                let _ = writeln!(
                    w,
                    "    {name:<10} loss {} +- {}  {}{}{}",
                    opt(th.loss, 3),
                    opt(th.sigma, 3),
                    status_text(th.status),
                    th.onset
                        .as_ref()
                        .map(|o| format!(" (onset {o})"))
                        .unwrap_or_default(),
                    if th.excited {
                        ""
                    } else {
                        ", not excited at the end"
                    }
                );
            }
            if let Some(r) = t.effectiveness_ratio {
                let _ = writeln!(
                    w,
                    "    effectiveness ratio port/starboard {:.3} +- {:.3}",
                    r.value, r.sigma
                );
            }
            if let Some(m) = t.profile_mismatch {
                let _ = writeln!(
                    w,
                    "    comparison withheld: the profile does not describe this vessel ({m})"
                );
            }
            for al in &self.alarms {
                let _ = writeln!(
                    w,
                    "    alarm      {} thruster {} -> {} at {} (+{:.1} s), onset {}, confidence {:.3}",
                    al.side,
                    status_text(al.from),
                    status_text(al.to),
                    al.time,
                    al.elapsed_s,
                    al.onset,
                    al.confidence
                );
            }
        } else {
            let _ = writeln!(
                w,
                "  thrusters    port loss null, starboard loss null: not observable"
            );
            let _ = writeln!(w, "    {}", wrap(NOT_OBSERVABLE_NOTE, 90, "    "));
        }
        match self.current {
            Some(c) => {
                let _ = writeln!(
                    w,
                    "  current      {:.3} m/s toward {:.0} deg (north {:.3}, east {:.3}, +- {:.3} m/s)",
                    c.speed_mps, c.toward_deg, c.north_mps, c.east_mps, c.sigma_mps
                );
            }
            None => {
                let _ = writeln!(
                    w,
                    "  current      not estimated (only the extended twin estimates it)"
                );
            }
        }
        let sm = &self.seed_method;
        if let Some(th) = sm.input_faults {
            let sg = sm.input_fault_sigma.unwrap_or([f64::NAN; 2]);
            let pk = sm.input_fault_peak.unwrap_or([f64::NAN; 2]);
            let _ = writeln!(
                w,
                "  seed method  input faults [a, r] = [{:.3}, {:.3}] +- [{:.3}, {:.3}], peak |.| [{:.3}, {:.3}]; step-4 values [port, stb] {} (peak {})",
                th[0],
                th[1],
                sg[0],
                sg[1],
                pk[0],
                pk[1],
                pair_opt(sm.thruster_values),
                pair_opt(sm.thruster_peak)
            );
            let _ = writeln!(w, "    {}", wrap(SEED_NOTE, 90, "    "));
        }
        if let Some(tr) = &self.truth {
            if let (Some(l), Some(e)) = (tr.loss, tr.loss_error) {
                let _ = writeln!(
                    w,
                    "  truth        losses [port, stb] [{:.3}, {:.3}]; estimate - truth [{:+.3}, {:+.3}]",
                    l.port, l.starboard, e.port, e.starboard
                );
            } else {
                let _ = writeln!(w, "  truth        {} samples", tr.samples);
            }
        }
        if let Some(p) = &self.prediction {
            let _ = writeln!(
                w,
                "  prediction   {} from {} over {:.0} s: RMSE north {:.2} m, east {:.2} m, position {:.2} m; at the horizon {:.2} m; within 1 sigma {:.0} %, 2 sigma {:.0} %",
                if p.model == "kinetic" {
                    "extended twin through the recorded shaft speeds"
                } else {
                    "seed model with its inputs held"
                },
                p.start,
                p.horizon_s,
                p.rmse_north_m,
                p.rmse_east_m,
                p.rmse_position_m,
                p.final_error_m,
                100.0 * p.within_1_sigma,
                100.0 * p.within_2_sigma
            );
        }
        s
    }
}

fn or_none(s: &str) -> &str {
    if s.is_empty() { "none" } else { s }
}

fn opt(v: Option<f64>, decimals: usize) -> String {
    v.map_or("null".to_string(), |v| format!("{v:.decimals$}"))
}

fn pair_opt(v: [Option<f64>; 2]) -> String {
    format!("[{}, {}]", opt(v[0], 3), opt(v[1], 3))
}

fn status_text(s: ThrusterStatusName) -> &'static str {
    match s {
        ThrusterStatusName::NotExcited => "not excited",
        ThrusterStatusName::Nominal => "nominal",
        ThrusterStatusName::Suspect => "SUSPECT",
        ThrusterStatusName::Fault => "FAULT",
    }
}

/// `1 h 02 min 03.0 s`-style durations.
pub fn duration_text(s: f64) -> String {
    if !s.is_finite() {
        return "-".to_string();
    }
    let h = (s / 3600.0).floor();
    let m = ((s - 3600.0 * h) / 60.0).floor();
    let sec = s - 3600.0 * h - 60.0 * m;
    if h > 0.0 {
        format!("{h:.0} h {m:02.0} min {sec:04.1} s")
    } else if m > 0.0 {
        format!("{m:.0} min {sec:04.1} s")
    } else {
        format!("{sec:.1} s")
    }
}

/// Wraps text at `width` columns, continuing lines with `indent`.
fn wrap(text: &str, width: usize, indent: &str) -> String {
    let mut out = String::new();
    let mut line = 0;
    for word in text.split_whitespace() {
        if line > 0 && line + 1 + word.len() > width {
            out.push('\n');
            out.push_str(indent);
            line = 0;
        } else if line > 0 {
            out.push(' ');
            line += 1;
        }
        out.push_str(word);
        line += word.len();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_and_wrapping() {
        assert_eq!(duration_text(14_845.0), "4 h 07 min 25.0 s");
        assert_eq!(duration_text(300.0), "5 min 00.0 s");
        assert_eq!(duration_text(12.34), "12.3 s");
        assert_eq!(wrap("a bb ccc", 4, "  "), "a bb\n  ccc");
    }
}
