//! A small SVG line-plot writer for the figures of `twin analyze --plot`:
//! lines, shaded bands (an estimate's sigma band), axes with "nice" ticks and
//! labels, a title and a legend. No external crate; every text is escaped.
//!
//! One [`Figure`] is one panel. Coordinates are data units; the figure maps
//! them to pixels (with `equal_aspect`, one metre is as long on both axes,
//! which a track needs). Non-finite points break a line into segments
//! rather than being drawn. Numbers in the output are rounded to 0.01 px, so
//! the same data always give the same bytes.

use std::fmt::Write;

/// A colour for a series (any SVG colour text, e.g. `#1f77b4`).
pub type Colour = &'static str;

/// A palette that stays readable in print and for most colour-blind readers.
pub const PALETTE: [Colour; 6] = [
    "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#7f7f7f",
];

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// A solid line.
    Line,
    /// A dashed line.
    Dashed,
    /// Small dots at the points, no line (raw measurements).
    Dots,
}

/// A named series of `(x, y)` points.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Points in data units.
    pub points: Vec<(f64, f64)>,
    /// Colour.
    pub colour: Colour,
    /// Drawing style.
    pub style: Style,
}

/// A shaded band between a lower and an upper curve over the same x.
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    /// Legend text.
    pub label: String,
    /// `(x, lower, upper)` in data units.
    pub points: Vec<(f64, f64, f64)>,
    /// Fill colour (drawn at 20 % opacity).
    pub colour: Colour,
}

/// One plot panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// Title above the plot.
    pub title: String,
    /// Label of the horizontal axis (with its unit).
    pub x_label: String,
    /// Label of the vertical axis (with its unit).
    pub y_label: String,
    /// Width of the image, px.
    pub width_px: f64,
    /// Height of the image, px.
    pub height_px: f64,
    /// Same scale on both axes (tracks).
    pub equal_aspect: bool,
    /// Bands, drawn first (under the lines).
    pub bands: Vec<Band>,
    /// Lines and dots.
    pub series: Vec<Series>,
    /// Fixed vertical range, else fitted to the data.
    pub y_range: Option<(f64, f64)>,
}

/// Escapes text for SVG/XML content and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if c.is_control() => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// A "nice" tick step (1, 2 or 5 times a power of ten) giving about
/// `target` intervals over `span`.
pub fn nice_step(span: f64, target: usize) -> f64 {
    if !(span.is_finite() && span > 0.0) {
        return 1.0;
    }
    let raw = span / target.max(1) as f64;
    let magnitude = 10f64.powf(raw.log10().floor());
    let fraction = raw / magnitude;
    let nice = if fraction <= 1.0 {
        1.0
    } else if fraction <= 2.0 {
        2.0
    } else if fraction <= 5.0 {
        5.0
    } else {
        10.0
    };
    nice * magnitude
}

/// Tick positions: multiples of `step` within `[lo, hi]`.
pub fn ticks(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && step > 0.0) || hi < lo {
        return Vec::new();
    }
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last.min(first + 100))
        .map(|k| {
            let v = k as f64 * step;
            // Avoid printing -0.
            if v == 0.0 { 0.0 } else { v }
        })
        .collect()
}

/// A tick label with as many decimals as the step needs.
pub fn tick_label(value: f64, step: f64) -> String {
    let decimals = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    format!("{value:.decimals$}")
}

/// The data range of the figure: `(x_lo, x_hi, y_lo, y_hi)`, padded a little
/// and never empty.
fn data_range(fig: &Figure) -> (f64, f64, f64, f64) {
    let mut xs = (f64::INFINITY, f64::NEG_INFINITY);
    let mut ys = (f64::INFINITY, f64::NEG_INFINITY);
    let mut take = |x: f64, y: f64| {
        if x.is_finite() && y.is_finite() {
            xs = (xs.0.min(x), xs.1.max(x));
            ys = (ys.0.min(y), ys.1.max(y));
        }
    };
    for s in &fig.series {
        for &(x, y) in &s.points {
            take(x, y);
        }
    }
    for b in &fig.bands {
        for &(x, lo, hi) in &b.points {
            take(x, lo);
            take(x, hi);
        }
    }
    if let Some((lo, hi)) = fig.y_range {
        ys = (lo, hi);
    }
    let widen = |(lo, hi): (f64, f64)| -> (f64, f64) {
        if !(lo.is_finite() && hi.is_finite()) {
            return (0.0, 1.0);
        }
        if hi - lo < 1e-12 {
            let d = (lo.abs() * 0.05).max(0.5);
            return (lo - d, hi + d);
        }
        (lo, hi)
    };
    let (x0, x1) = widen(xs);
    let (y0, y1) = widen(ys);
    if fig.y_range.is_some() {
        return (x0, x1, y0, y1);
    }
    let pad = 0.04 * (y1 - y0);
    (x0, x1, y0 - pad, y1 + pad)
}

/// Maps data to pixels.
struct Frame {
    left: f64,
    top: f64,
    width: f64,
    height: f64,
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
}

impl Frame {
    fn x(&self, x: f64) -> f64 {
        self.left + (x - self.x0) / (self.x1 - self.x0) * self.width
    }

    fn y(&self, y: f64) -> f64 {
        self.top + self.height - (y - self.y0) / (self.y1 - self.y0) * self.height
    }
}

/// A pixel coordinate, rounded to 0.01 px.
fn px(v: f64) -> String {
    let r = (v * 100.0).round() / 100.0;
    if r == 0.0 {
        "0".to_string()
    } else {
        format!("{r}")
    }
}

/// Splits points into runs of finite points.
fn finite_runs(points: &[(f64, f64)]) -> Vec<Vec<(f64, f64)>> {
    let mut runs = Vec::new();
    let mut run = Vec::new();
    for &(x, y) in points {
        if x.is_finite() && y.is_finite() {
            run.push((x, y));
        } else if !run.is_empty() {
            runs.push(std::mem::take(&mut run));
        }
    }
    if !run.is_empty() {
        runs.push(run);
    }
    runs
}

impl Figure {
    /// An empty figure of the usual size (720 x 420 px).
    pub fn new(title: &str, x_label: &str, y_label: &str) -> Self {
        Self {
            title: title.to_string(),
            x_label: x_label.to_string(),
            y_label: y_label.to_string(),
            width_px: 720.0,
            height_px: 420.0,
            equal_aspect: false,
            bands: Vec::new(),
            series: Vec::new(),
            y_range: None,
        }
    }

    /// Adds a line.
    pub fn line(&mut self, label: &str, colour: Colour, style: Style, points: Vec<(f64, f64)>) {
        self.series.push(Series {
            label: label.to_string(),
            points,
            colour,
            style,
        });
    }

    /// Adds a band.
    pub fn band(&mut self, label: &str, colour: Colour, points: Vec<(f64, f64, f64)>) {
        self.bands.push(Band {
            label: label.to_string(),
            points,
            colour,
        });
    }

    /// The SVG document.
    pub fn render(&self) -> String {
        let (w, h) = (self.width_px, self.height_px);
        let (mut x0, mut x1, mut y0, mut y1) = data_range(self);
        let (left, right, top, bottom) = (70.0, 20.0, 40.0, 50.0);
        let (pw, ph) = (w - left - right, h - top - bottom);
        if self.equal_aspect {
            // Widen the narrower range so that a data unit has one length.
            let scale = ((x1 - x0) / pw).max((y1 - y0) / ph);
            let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
            x0 = cx - scale * pw / 2.0;
            x1 = cx + scale * pw / 2.0;
            y0 = cy - scale * ph / 2.0;
            y1 = cy + scale * ph / 2.0;
        }
        let f = Frame {
            left,
            top,
            width: pw,
            height: ph,
            x0,
            x1,
            y0,
            y1,
        };
        let mut s = String::new();
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#
        );
        let _ = writeln!(
            s,
            r#"<rect x="0" y="0" width="{w}" height="{h}" fill="white"/>"#
        );
        let _ = writeln!(
            s,
            r#"<text x="{}" y="24" text-anchor="middle" font-size="15">{}</text>"#,
            px(w / 2.0),
            escape(&self.title)
        );
        self.render_axes(&mut s, &f);
        let _ = writeln!(
            s,
            r#"<clipPath id="plot-area"><rect x="{}" y="{}" width="{}" height="{}"/></clipPath>"#,
            px(left),
            px(top),
            px(pw),
            px(ph)
        );
        let _ = writeln!(s, r#"<g clip-path="url(#plot-area)">"#);
        for b in &self.bands {
            render_band(&mut s, &f, b);
        }
        for series in &self.series {
            render_series(&mut s, &f, series);
        }
        let _ = writeln!(s, "</g>");
        self.render_legend(&mut s, &f);
        s.push_str("</svg>\n");
        s
    }

    fn render_axes(&self, s: &mut String, f: &Frame) {
        let (l, t, r, b) = (f.left, f.top, f.left + f.width, f.top + f.height);
        let _ = writeln!(
            s,
            r##"<rect x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#333"/>"##,
            px(l),
            px(t),
            px(f.width),
            px(f.height)
        );
        let x_step = nice_step(f.x1 - f.x0, 8);
        for v in ticks(f.x0, f.x1, x_step) {
            let x = px(f.x(v));
            let _ = writeln!(
                s,
                r##"<line x1="{x}" y1="{}" x2="{x}" y2="{}" stroke="#ddd"/>"##,
                px(t),
                px(b)
            );
            let _ = writeln!(
                s,
                r#"<text x="{x}" y="{}" text-anchor="middle">{}</text>"#,
                px(b + 16.0),
                escape(&tick_label(v, x_step))
            );
        }
        let y_step = nice_step(f.y1 - f.y0, 6);
        for v in ticks(f.y0, f.y1, y_step) {
            let y = px(f.y(v));
            let _ = writeln!(
                s,
                r##"<line x1="{}" y1="{y}" x2="{}" y2="{y}" stroke="#ddd"/>"##,
                px(l),
                px(r)
            );
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{y}" text-anchor="end" dominant-baseline="middle">{}</text>"#,
                px(l - 6.0),
                escape(&tick_label(v, y_step))
            );
        }
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
            px((l + r) / 2.0),
            px(b + 38.0),
            escape(&self.x_label)
        );
        let _ = writeln!(
            s,
            r#"<text x="16" y="{}" text-anchor="middle" transform="rotate(-90 16 {})">{}</text>"#,
            px((t + b) / 2.0),
            px((t + b) / 2.0),
            escape(&self.y_label)
        );
    }

    fn render_legend(&self, s: &mut String, f: &Frame) {
        let entries: Vec<(&str, Colour, Option<Style>)> = self
            .bands
            .iter()
            .map(|b| (b.label.as_str(), b.colour, None))
            .chain(
                self.series
                    .iter()
                    .map(|x| (x.label.as_str(), x.colour, Some(x.style))),
            )
            .filter(|(label, _, _)| !label.is_empty())
            .collect();
        if entries.is_empty() {
            return;
        }
        let longest = entries
            .iter()
            .map(|(l, _, _)| l.chars().count())
            .max()
            .unwrap_or(0) as f64;
        let box_w = 40.0 + 6.6 * longest;
        let box_h = 8.0 + 18.0 * entries.len() as f64;
        let x = f.left + f.width - box_w - 8.0;
        let y = f.top + 8.0;
        let _ = writeln!(s, r#"<g class="legend">"#);
        let _ = writeln!(
            s,
            r##"<rect x="{}" y="{}" width="{}" height="{}" fill="white" fill-opacity="0.85" stroke="#999"/>"##,
            px(x),
            px(y),
            px(box_w),
            px(box_h)
        );
        for (i, (label, colour, style)) in entries.iter().enumerate() {
            let cy = y + 13.0 + 18.0 * i as f64;
            match style {
                None => {
                    let _ = writeln!(
                        s,
                        r#"<rect x="{}" y="{}" width="22" height="10" fill="{colour}" fill-opacity="0.2"/>"#,
                        px(x + 8.0),
                        px(cy - 5.0)
                    );
                }
                Some(Style::Dots) => {
                    let _ = writeln!(
                        s,
                        r#"<circle cx="{}" cy="{}" r="2.5" fill="{colour}"/>"#,
                        px(x + 19.0),
                        px(cy)
                    );
                }
                Some(st) => {
                    let dash = if *st == Style::Dashed {
                        r#" stroke-dasharray="6 4""#
                    } else {
                        ""
                    };
                    let _ = writeln!(
                        s,
                        r#"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="{colour}" stroke-width="2"{dash}/>"#,
                        px(x + 8.0),
                        px(cy),
                        px(x + 30.0),
                        px(cy)
                    );
                }
            }
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}" dominant-baseline="middle">{}</text>"#,
                px(x + 36.0),
                px(cy),
                escape(label)
            );
        }
        let _ = writeln!(s, "</g>");
    }
}

fn render_series(s: &mut String, f: &Frame, series: &Series) {
    let _ = writeln!(
        s,
        r#"<g class="series" data-label="{}">"#,
        escape(&series.label)
    );
    for run in finite_runs(&series.points) {
        match series.style {
            Style::Dots => {
                for (x, y) in run {
                    let _ = writeln!(
                        s,
                        r#"<circle cx="{}" cy="{}" r="1.6" fill="{}"/>"#,
                        px(f.x(x)),
                        px(f.y(y)),
                        series.colour
                    );
                }
            }
            style => {
                let mut pts = String::new();
                for (x, y) in run {
                    let _ = write!(pts, "{},{} ", px(f.x(x)), px(f.y(y)));
                }
                let dash = if style == Style::Dashed {
                    r#" stroke-dasharray="6 4""#
                } else {
                    ""
                };
                let _ = writeln!(
                    s,
                    r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="1.6"{dash}/>"#,
                    pts.trim_end(),
                    series.colour
                );
            }
        }
    }
    let _ = writeln!(s, "</g>");
}

fn render_band(s: &mut String, f: &Frame, band: &Band) {
    let _ = writeln!(
        s,
        r#"<g class="band" data-label="{}">"#,
        escape(&band.label)
    );
    // One polygon per run of finite points.
    let mut run: Vec<(f64, f64, f64)> = Vec::new();
    let flush = |run: &mut Vec<(f64, f64, f64)>, s: &mut String| {
        if run.len() >= 2 {
            let mut pts = String::new();
            for &(x, _, hi) in run.iter() {
                let _ = write!(pts, "{},{} ", px(f.x(x)), px(f.y(hi)));
            }
            for &(x, lo, _) in run.iter().rev() {
                let _ = write!(pts, "{},{} ", px(f.x(x)), px(f.y(lo)));
            }
            let _ = writeln!(
                s,
                r#"<polygon points="{}" fill="{}" fill-opacity="0.2" stroke="none"/>"#,
                pts.trim_end(),
                band.colour
            );
        }
        run.clear();
    };
    for &(x, lo, hi) in &band.points {
        if x.is_finite() && lo.is_finite() && hi.is_finite() {
            run.push((x, lo, hi));
        } else {
            flush(&mut run, s);
        }
    }
    flush(&mut run, s);
    let _ = writeln!(s, "</g>");
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Checks that every tag is closed in order and that text holds no raw
    /// `<` or stray `&`. Returns the element names seen.
    fn check_well_formed(svg: &str) -> Result<Vec<String>, String> {
        let mut stack: Vec<String> = Vec::new();
        let mut seen = Vec::new();
        let mut rest = svg;
        while let Some(open) = rest.find('<') {
            let text = &rest[..open];
            check_text(text)?;
            let after = &rest[open..];
            let close = after.find('>').ok_or("unclosed tag")?;
            let tag = &after[1..close];
            if let Some(name) = tag.strip_prefix('/') {
                let top = stack.pop().ok_or(format!("</{name}> without opening"))?;
                if top != name.trim() {
                    return Err(format!("</{name}> closes <{top}>"));
                }
            } else {
                let self_closing = tag.ends_with('/');
                let name: String = tag
                    .trim_end_matches('/')
                    .split_whitespace()
                    .next()
                    .ok_or("empty tag")?
                    .to_string();
                // Attribute values must have balanced quotes.
                if !tag.matches('"').count().is_multiple_of(2) {
                    return Err(format!("unbalanced quotes in <{name}>"));
                }
                seen.push(name.clone());
                if !self_closing {
                    stack.push(name);
                }
            }
            rest = &after[close + 1..];
        }
        check_text(rest)?;
        if stack.is_empty() {
            Ok(seen)
        } else {
            Err(format!("unclosed: {stack:?}"))
        }
    }

    fn check_text(text: &str) -> Result<(), String> {
        if text.contains('>') {
            return Err(format!("raw > in text {text:?}"));
        }
        for (i, _) in text.match_indices('&') {
            let entity = &text[i..];
            if !["&amp;", "&lt;", "&gt;", "&quot;", "&apos;"]
                .iter()
                .any(|e| entity.starts_with(e))
            {
                return Err(format!("stray & in {text:?}"));
            }
        }
        Ok(())
    }

    fn sample() -> Figure {
        let mut fig = Figure::new("Loss <port> & \"starboard\"", "time (s)", "loss (-)");
        let t: Vec<f64> = (0..50).map(|i| i as f64).collect();
        fig.band(
            "port ±1σ",
            PALETTE[0],
            t.iter().map(|&x| (x, 0.2, 0.3)).collect(),
        );
        fig.line(
            "port",
            PALETTE[0],
            Style::Line,
            t.iter().map(|&x| (x, 0.25)).collect(),
        );
        let mut with_gap: Vec<(f64, f64)> = t.iter().map(|&x| (x, 0.01 * x)).collect();
        with_gap[20].1 = f64::NAN;
        fig.line("starboard", PALETTE[1], Style::Dashed, with_gap);
        fig.line(
            "measured",
            PALETTE[2],
            Style::Dots,
            vec![(1.0, 0.1), (2.0, 0.2)],
        );
        fig
    }

    #[test]
    fn output_is_well_formed_and_has_every_series() {
        let svg = sample().render();
        let names = check_well_formed(&svg).unwrap_or_else(|e| panic!("{e}\n{svg}"));
        assert_eq!(names[0], "svg");
        // Title escaped, legend entries and series groups present.
        assert!(svg.contains("Loss &lt;port&gt; &amp; &quot;starboard&quot;"));
        for label in ["port ±1σ", "port", "starboard", "measured"] {
            assert!(svg.contains(&format!(r#"data-label="{label}""#)), "{label}");
            assert!(svg.contains(&format!(">{label}</text>")), "legend {label}");
        }
        // The NaN split the dashed line in two polylines; the band is one polygon.
        assert_eq!(svg.matches("stroke-dasharray=\"6 4\"/>").count(), 3);
        assert_eq!(svg.matches("<polygon").count(), 1);
        assert_eq!(svg.matches("<circle").count(), 3, "2 dots + legend dot");
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        // Axes: ticks with labels.
        assert!(svg.contains(">0.25</text>") || svg.contains(">0.2</text>"));
        assert!(svg.contains(">time (s)</text>"));
        // Deterministic.
        assert_eq!(svg, sample().render());
    }

    #[test]
    fn empty_and_degenerate_figures_still_render() {
        let fig = Figure::new("empty", "x", "y");
        check_well_formed(&fig.render()).unwrap();
        let mut fig = Figure::new("flat", "x", "y");
        fig.equal_aspect = true;
        fig.line("one", PALETTE[0], Style::Line, vec![(1.0, 1.0), (1.0, 1.0)]);
        let svg = fig.render();
        check_well_formed(&svg).unwrap();
        assert!(!svg.contains("NaN"));
    }

    #[test]
    fn nice_ticks() {
        assert_eq!(nice_step(10.0, 5), 2.0);
        assert_eq!(nice_step(0.7, 7), 0.1);
        assert_eq!(nice_step(340.0, 8), 50.0);
        assert_eq!(
            ticks(-0.05, 0.31, 0.1),
            vec![0.0, 0.1, 0.2, 0.30000000000000004]
        );
        assert_eq!(tick_label(0.30000000000000004, 0.1), "0.3");
        assert_eq!(tick_label(250.0, 50.0), "250");
        assert_eq!(escape("a<b>&'\""), "a&lt;b&gt;&amp;&apos;&quot;");
    }
}
