//! What the hidden-effect tests share (`hidden_effects.rs` on the project's
//! simulator, `hidden_effects_othersim.rs` on the independent one): the
//! effect a draw hides, and the verdict on a diagnosis of it: exactly the
//! right cause named, its size within 20 % (a current as a vector within
//! 20 % of its speed; a scale's error from one), nothing named on a clean
//! log.

use rand::Rng;
use rand::rngs::StdRng;
use twin_cli::diagnose::DiagnoseReport;

/// The hidden effect of one draw, as the test knows it (the diagnosis does not).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Hidden {
    Nothing,
    Current {
        speed_mps: f64,
        toward_deg: f64,
    },
    HeadingOffset {
        offset_deg: f64,
    },
    SogScale {
        scale: f64,
    },
    Latency {
        latency_s: f64,
    },
    Loss {
        port: bool,
        loss: f64,
    },
    /// A rate gyro reading `scale` times the true yaw rate (drawn by the
    /// gyro tests only; the test files that share this module without them
    /// never build it).
    #[allow(dead_code)]
    YawRateScale {
        scale: f64,
    },
    /// A rate gyro reading `bias_deg_s` when the vessel does not turn
    /// (drawn by the gyro tests only).
    #[allow(dead_code)]
    YawRateBias {
        bias_deg_s: f64,
    },
}

/// The `i`th draw of the rate-gyro tests, in turn: a gyro reading
/// 1 ± U(0.06, 0.12) times the yaw rate, a true gyro (nothing hidden), a
/// gyro biased by ± U(0.2, 0.8) deg/s; each sign as likely.
#[allow(dead_code)]
pub fn draw_gyro(rng: &mut StdRng, i: usize) -> Hidden {
    let sign = |rng: &mut StdRng| if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    match i % 3 {
        0 => {
            let size = rng.random_range(0.06..0.12);
            Hidden::YawRateScale {
                scale: 1.0 + sign(rng) * size,
            }
        }
        1 => Hidden::Nothing,
        _ => {
            let size = rng.random_range(0.2..0.8);
            Hidden::YawRateBias {
                bias_deg_s: sign(rng) * size,
            }
        }
    }
}

/// A finding's numeric parameter.
fn param(r: &DiagnoseReport, i: usize, name: &str) -> f64 {
    r.findings[i].parameters[name].as_f64().unwrap()
}

/// Checks a diagnosis against the hidden effect; `Err` says what is wrong.
pub fn judge(h: Hidden, r: &DiagnoseReport) -> Result<(), String> {
    let causes: Vec<&str> = r.findings.iter().map(|f| f.cause.as_str()).collect();
    let within = |got: f64, want: f64| (got - want).abs() <= 0.2 * want.abs();
    match h {
        Hidden::Nothing => {
            return if causes.is_empty() {
                Ok(())
            } else {
                Err(format!("named {causes:?} on a clean log"))
            };
        }
        _ if causes.len() != 1 => return Err(format!("named {causes:?}")),
        _ => {}
    }
    let ok = match h {
        Hidden::Nothing => unreachable!(),
        Hidden::Current {
            speed_mps,
            toward_deg,
        } => {
            causes[0] == "current" && {
                let (s, d) = (param(r, 0, "speed_mps"), param(r, 0, "toward_deg"));
                // The current as a vector within 20 % of its speed.
                let (tn, te) = (
                    speed_mps * toward_deg.to_radians().cos(),
                    speed_mps * toward_deg.to_radians().sin(),
                );
                let (gn, ge) = (s * d.to_radians().cos(), s * d.to_radians().sin());
                (gn - tn).hypot(ge - te) <= 0.2 * speed_mps
            }
        }
        Hidden::HeadingOffset { offset_deg } => {
            causes[0] == "heading_offset" && within(param(r, 0, "offset_deg"), offset_deg)
        }
        Hidden::SogScale { scale } => {
            causes[0] == "sog_scale" && within(param(r, 0, "scale") - 1.0, scale - 1.0)
        }
        Hidden::Latency { latency_s } => {
            causes[0] == "gnss_latency" && within(param(r, 0, "latency_s"), latency_s)
        }
        Hidden::Loss { port, loss } => {
            causes[0] == "thruster_loss"
                && r.findings[0].parameters["side"] == if port { "port" } else { "starboard" }
                && within(param(r, 0, "loss"), loss)
        }
        Hidden::YawRateScale { scale } => {
            causes[0] == "yaw_rate_scale" && within(param(r, 0, "scale") - 1.0, scale - 1.0)
        }
        Hidden::YawRateBias { bias_deg_s } => {
            causes[0] == "yaw_rate_bias" && within(param(r, 0, "bias_deg_s"), bias_deg_s)
        }
    };
    if ok {
        Ok(())
    } else {
        Err(format!(
            "named {:?} with {:?}",
            causes, r.findings[0].parameters
        ))
    }
}

/// The verdict on a diagnosis of a log without propeller data hiding `h`,
/// which the kinematic water base diagnoses: the simulated hull's own drift
/// in its turns, if named, as an outward sideslip (negative, of either
/// shape: [`is_sideslip`]); the rest by
/// [`judge`] (used by the tests of logs without propeller data only).
#[allow(dead_code)]
pub fn judge_without_propellers(h: Hidden, r: &DiagnoseReport) -> Result<(), String> {
    if r.base_model != "water" {
        return Err(format!("diagnosed on the {} base", r.base_model));
    }
    if let Some(f) = r.findings.iter().find(|f| is_sideslip(&f.cause)) {
        let k = f.parameters["lateral_mps_per_radps"].as_f64().unwrap();
        if k >= 0.0 {
            return Err(format!("a sideslip of {k:.3} m/s per rad/s, inward"));
        }
    }
    let mut others = r.clone();
    others.findings.retain(|f| !is_sideslip(&f.cause));
    judge(h, &others)
}

/// Whether `cause` is the hull's drift in its turns, of either shape (its
/// sway in proportion to the yaw rate, or to the yaw rate and the speed).
#[allow(dead_code)]
pub fn is_sideslip(cause: &str) -> bool {
    matches!(cause, "sideslip" | "sideslip_with_speed")
}

/// The hidden effect in the table's words.
pub fn describe(h: Hidden) -> String {
    match h {
        Hidden::Nothing => "nothing".into(),
        Hidden::Current {
            speed_mps,
            toward_deg,
        } => format!("current {speed_mps:.3} m/s toward {toward_deg:.1} deg"),
        Hidden::HeadingOffset { offset_deg } => format!("heading offset {offset_deg:+.2} deg"),
        Hidden::SogScale { scale } => format!("SOG scale {scale:.4}"),
        Hidden::Latency { latency_s } => format!("GNSS latency {latency_s:.3} s"),
        Hidden::Loss { port, loss } => {
            format!("{} loss {loss:.3}", if port { "port" } else { "starboard" })
        }
        Hidden::YawRateScale { scale } => format!("yaw-rate scale {scale:.4}"),
        Hidden::YawRateBias { bias_deg_s } => format!("yaw-rate bias {bias_deg_s:+.3} deg/s"),
    }
}

/// The findings in the table's words.
pub fn named(r: &DiagnoseReport) -> String {
    if r.findings.is_empty() {
        return "nothing".into();
    }
    r.findings
        .iter()
        .map(|f| {
            let p = |n: &str| {
                f.parameters
                    .get(n)
                    .and_then(serde_json::Value::as_f64)
                    .unwrap_or(f64::NAN)
            };
            let what = match f.cause.as_str() {
                "current" => format!(
                    "current {:.3} m/s toward {:.1} deg",
                    p("speed_mps"),
                    p("toward_deg")
                ),
                "heading_offset" => format!("heading offset {:+.2} deg", p("offset_deg")),
                "sog_scale" => format!("SOG scale {:.4}", p("scale")),
                "yaw_rate_scale" => format!("yaw-rate scale {:.4}", p("scale")),
                "yaw_rate_bias" => format!("yaw-rate bias {:+.3} deg/s", p("bias_deg_s")),
                "gnss_latency" => format!("GNSS latency {:.3} s", p("latency_s")),
                "thruster_loss" => format!(
                    "{} loss {:.3}",
                    f.parameters["side"].as_str().unwrap_or("?"),
                    p("loss")
                ),
                "lever_arm" => format!("lever arm x {:.2} m, y {:.2} m", p("x_m"), p("y_m")),
                "sideslip" | "sideslip_with_speed" => format!(
                    "{} {:.3} m/s per rad/s",
                    f.cause,
                    p("lateral_mps_per_radps")
                ),
                "surge_damping" | "yaw_damping" | "mass" => {
                    format!("{} x {:.3}", f.cause, p("scale"))
                }
                other => format!("{other} {:?}", f.parameters),
            };
            format!("{what} (gain {:.0})", f.gain.heldout_nll_gain)
        })
        .collect::<Vec<_>>()
        .join("; ")
}
