//! Line charts as SVG (plotters, no system fonts needed).

use std::path::Path;

use plotters::prelude::*;

/// One named curve.
pub struct Series {
    /// Legend label.
    pub name: String,
    /// Points `(x, y)`.
    pub points: Vec<(f64, f64)>,
    /// A label per point (drawn beside it, marked with a dot), or none.
    pub point_labels: Vec<String>,
    /// Whether the points are joined by a line (a curve) or drawn alone (a scatter).
    pub joined: bool,
}

impl Series {
    /// A series from a name and points.
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            name: name.into(),
            points,
            point_labels: Vec::new(),
            joined: true,
        }
    }

    /// A scatter: points drawn alone, for points that are not a curve (one per configuration).
    pub fn scatter(name: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self {
            joined: false,
            ..Self::new(name, points)
        }
    }

    /// The same series with a label beside each point (as many labels as points), for curves
    /// whose points mean something (each threshold of a work-precision curve).
    pub fn with_point_labels(mut self, labels: Vec<String>) -> Self {
        self.point_labels = labels;
        self
    }
}

/// A tick label that reads at a glance: up to three significant digits, no float noise
/// (`9.999999999999999e-5` is `1e-4`), plain notation from 0.001 to 10,000.
pub fn tick_label(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return if v == 0.0 {
            "0".to_owned()
        } else {
            format!("{v}")
        };
    }
    let a = v.abs();
    let exp = a.log10().floor();
    // Round to three significant digits first, so that 9.9999e-5 becomes 1e-4.
    let scale = 10f64.powf(exp - 2.0);
    let r = (v / scale).round() * scale;
    let (a, exp) = (r.abs(), r.abs().log10().floor());
    if (1e-3..1e4).contains(&a) {
        let decimals = (2.0 - exp).max(0.0) as usize;
        let s = format!("{r:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_owned()
        } else {
            s
        }
    } else {
        let mantissa = r / 10f64.powf(exp);
        let m = format!("{mantissa:.2}");
        let m = m.trim_end_matches('0').trim_end_matches('.');
        format!("{m}e{}", exp as i32)
    }
}

/// Tick positions of a base-10 log axis over `[lo, hi]`: 1, 2 and 5 times the powers of ten
/// (1, 2, 3, 5 when the range spans less than a decade and a half; every integer mantissa when
/// that still gives fewer than three), at least two. None for a range that is not positive and
/// finite (a log axis has none).
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi >= lo) {
        return Vec::new();
    }
    let within = |mantissas: &[f64]| {
        let mut out = Vec::new();
        let (e0, e1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
        for e in e0..=e1 {
            for m in mantissas {
                let v = m * 10f64.powi(e);
                if v >= lo * (1.0 - 1e-9) && v <= hi * (1.0 + 1e-9) {
                    out.push(v);
                }
            }
        }
        out
    };
    let mut out = if hi / lo < 30.0 {
        within(&[1.0, 2.0, 3.0, 5.0])
    } else if hi / lo < 1e4 {
        within(&[1.0, 2.0, 5.0])
    } else {
        within(&[1.0])
    };
    if out.len() < 3 {
        out = within(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    }
    if out.len() < 2 {
        out = vec![lo, (lo * hi).sqrt(), hi];
    }
    out
}

/// Axis scale.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Scale {
    /// Linear axis.
    Linear,
    /// Base-10 logarithmic axis (non-positive values are dropped).
    Log,
}

/// A chart description.
pub struct Chart<'a> {
    /// Title above the plot.
    pub title: &'a str,
    /// X-axis label.
    pub x_label: &'a str,
    /// Y-axis label.
    pub y_label: &'a str,
    /// X-axis scale.
    pub x_scale: Scale,
    /// Y-axis scale.
    pub y_scale: Scale,
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

fn keep(scale: Scale, v: f64) -> bool {
    v.is_finite() && (scale == Scale::Linear || v > 0.0)
}

fn range(scale: Scale, vals: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| keep(scale, *v)) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (if scale == Scale::Log { 1e-3 } else { 0.0 }, 1.0);
    }
    if hi <= lo {
        return match scale {
            Scale::Log => (lo / 2.0, lo * 2.0),
            Scale::Linear => (lo - 1.0, lo + 1.0),
        };
    }
    match scale {
        Scale::Log => (lo / 1.2, hi * 1.2),
        Scale::Linear => {
            let pad = 0.05 * (hi - lo);
            (lo - pad, hi + pad)
        }
    }
}

/// Where a point's label starts, in pixels from the point: to its right, or to its left in the
/// plot's right fifth, where a label to the right would run off the image (13 px text, about
/// 0.55 em a character).
fn label_dx(chart: &Chart<'_>, x0: f64, x1: f64, x: f64, text: &str) -> i32 {
    if fraction(chart.x_scale, x0, x1, x) > 0.8 {
        -6 - (7.2 * text.chars().count() as f64).ceil() as i32
    } else {
        6
    }
}

/// A point label's box in pixels: left, top, right, bottom.
type LabelBox = (i32, i32, i32, i32);

/// A point label's height in pixels (13 px text).
const LABEL_PX: i32 = 13;

/// Where a point's label goes, in pixels from the point at `at` (pixels): `dx` to the side
/// ([`label_dx`]) and above the point, or where that box would overlap a label already in
/// `placed`, the first of below it, further above and further below that overlaps none (above,
/// if every one does). Its box joins `placed`. Two thresholds whose points lie a few pixels
/// apart (the jaws at 2.5 % and 5 %, both capped at `δ`) keep readable labels.
fn place_label(at: (i32, i32), dx: i32, text: &str, placed: &mut Vec<LabelBox>) -> (i32, i32) {
    let width = (7.2 * text.chars().count() as f64).ceil() as i32;
    let boxed = |dy: i32| {
        let (left, top) = (at.0 + dx, at.1 + dy);
        (left, top, left + width, top + LABEL_PX)
    };
    let overlaps = |b: &LabelBox| {
        placed
            .iter()
            .any(|p| b.0 < p.2 && p.0 < b.2 && b.1 < p.3 && p.1 < b.3)
    };
    let dy = [-16, 4, -30, 18]
        .into_iter()
        .find(|&dy| !overlaps(&boxed(dy)))
        .unwrap_or(-16);
    placed.push(boxed(dy));
    (dx, dy)
}

/// Where on the plot `v` (within `lo..hi`) falls, from 0 to 1, along an axis of `scale`.
fn fraction(scale: Scale, lo: f64, hi: f64, v: f64) -> f64 {
    match scale {
        Scale::Linear => (v - lo) / (hi - lo),
        Scale::Log => (v / lo).ln() / (hi / lo).ln(),
    }
}

/// The legend's place: of the four corners and the middle of the right side (plotters'
/// default), the one whose box (about 40 % of the width and 25 % of the height) holds the
/// fewest data points and the fewest samples of the lines between them, so that the legend
/// hides neither.
fn legend_position(
    chart: &Chart<'_>,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    series: &[Series],
) -> SeriesLabelPosition {
    use SeriesLabelPosition::{LowerLeft, LowerRight, MiddleRight, UpperLeft, UpperRight};
    // Each candidate's box in plot fractions: (x from, x to, y from, y to), y up.
    let boxes = [
        (MiddleRight, (0.6, 1.0, 0.375, 0.625)),
        (UpperRight, (0.6, 1.0, 0.75, 1.0)),
        (UpperLeft, (0.0, 0.4, 0.75, 1.0)),
        (LowerRight, (0.6, 1.0, 0.0, 0.25)),
        (LowerLeft, (0.0, 0.4, 0.0, 0.25)),
    ];
    // The points in plot fractions, and along each line between two of them (straight in
    // those fractions, as drawn) 15 samples.
    const SAMPLES: usize = 16;
    let mut points: Vec<(f64, f64)> = Vec::new();
    for s in series {
        let placed: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter(|p| keep(chart.x_scale, p.0) && keep(chart.y_scale, p.1))
            .map(|p| {
                (
                    fraction(chart.x_scale, x0, x1, p.0),
                    fraction(chart.y_scale, y0, y1, p.1),
                )
            })
            .collect();
        points.extend_from_slice(&placed);
        for w in placed.windows(2) {
            let ((ax, ay), (bx, by)) = (w[0], w[1]);
            points.extend((1..SAMPLES).map(|k| {
                let t = k as f64 / SAMPLES as f64;
                (ax + t * (bx - ax), ay + t * (by - ay))
            }));
        }
    }
    let hidden = |b: &(f64, f64, f64, f64)| {
        points
            .iter()
            .filter(|(x, y)| *x >= b.0 && *x <= b.1 && *y >= b.2 && *y <= b.3)
            .count()
    };
    boxes
        .iter()
        .min_by_key(|(_, b)| hidden(b))
        .map_or(MiddleRight, |(pos, _)| pos.clone())
}

/// Draws `series` into an SVG file at `path`.
pub fn line_chart(path: &Path, chart: &Chart<'_>, series: &[Series]) -> anyhow::Result<()> {
    let xs = series.iter().flat_map(|s| s.points.iter().map(|p| p.0));
    let ys = series.iter().flat_map(|s| s.points.iter().map(|p| p.1));
    let (x0, x1) = range(chart.x_scale, xs);
    let (y0, y1) = range(chart.y_scale, ys);
    let root = SVGBackend::new(path, (900, 560)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut builder = ChartBuilder::on(&root);
    // A title that fits the 900 px width: about 0.55 em per character.
    let title_px = (22.0_f64).min(860.0 / (0.55 * chart.title.chars().count().max(1) as f64));
    builder
        .caption(chart.title, ("sans-serif", title_px.max(11.0) as u32))
        .margin(16)
        .x_label_area_size(52)
        .y_label_area_size(84);
    macro_rules! draw {
        ($ctx:expr) => {{
            let mut ctx = $ctx.map_err(|e| anyhow::anyhow!("{e}"))?;
            ctx.configure_mesh()
                .x_desc(chart.x_label)
                .y_desc(chart.y_label)
                .x_label_formatter(&|v| tick_label(*v))
                .y_label_formatter(&|v| tick_label(*v))
                .label_style(("sans-serif", 14))
                .axis_desc_style(("sans-serif", 16))
                .draw()
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            let mut placed: Vec<LabelBox> = Vec::new();
            for (i, s) in series.iter().enumerate() {
                let color = PALETTE[i % PALETTE.len()];
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|p| keep(chart.x_scale, p.0) && keep(chart.y_scale, p.1))
                    .collect();
                if s.joined {
                    ctx.draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                        .map_err(|e| anyhow::anyhow!("{e}"))?
                        .label(s.name.clone())
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                        });
                } else {
                    ctx.draw_series(pts.iter().map(|p| Circle::new(*p, 4, color.filled())))
                        .map_err(|e| anyhow::anyhow!("{e}"))?
                        .label(s.name.clone())
                        .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
                }
                if !s.point_labels.is_empty() {
                    let labelled: Vec<((f64, f64), (i32, i32), &String)> = s
                        .points
                        .iter()
                        .zip(&s.point_labels)
                        .filter(|(p, _)| keep(chart.x_scale, p.0) && keep(chart.y_scale, p.1))
                        .map(|(p, text)| {
                            let dx = label_dx(chart, x0, x1, p.0, text);
                            (
                                *p,
                                place_label(ctx.backend_coord(p), dx, text, &mut placed),
                                text,
                            )
                        })
                        .collect();
                    ctx.draw_series(labelled.into_iter().map(|(p, offset, text)| {
                        EmptyElement::at(p)
                            + Circle::new((0, 0), 4, color.filled())
                            + Text::new(text.clone(), offset, ("sans-serif", LABEL_PX))
                    }))
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
                }
            }
            ctx.configure_series_labels()
                .position(legend_position(chart, (x0, x1), (y0, y1), series))
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        }};
    }
    // Log ticks only for log axes (`range` makes their bounds positive).
    match (chart.x_scale, chart.y_scale) {
        (Scale::Linear, Scale::Linear) => draw!(builder.build_cartesian_2d(x0..x1, y0..y1)),
        (Scale::Linear, Scale::Log) => draw!(builder.build_cartesian_2d(
            x0..x1,
            (y0..y1).log_scale().with_key_points(log_ticks(y0, y1))
        )),
        (Scale::Log, Scale::Linear) => draw!(builder.build_cartesian_2d(
            (x0..x1).log_scale().with_key_points(log_ticks(x0, x1)),
            y0..y1
        )),
        (Scale::Log, Scale::Log) => draw!(builder.build_cartesian_2d(
            (x0..x1).log_scale().with_key_points(log_ticks(x0, x1)),
            (y0..y1).log_scale().with_key_points(log_ticks(y0, y1))
        )),
    }
    root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
    println!("wrote {}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_legend_goes_where_it_hides_no_point() {
        let chart = Chart {
            title: "t",
            x_label: "x",
            y_label: "y",
            x_scale: Scale::Log,
            y_scale: Scale::Log,
        };
        let pos = |pts: Vec<(f64, f64)>| {
            let xr = range(Scale::Log, pts.iter().map(|p| p.0));
            let yr = range(Scale::Log, pts.iter().map(|p| p.1));
            legend_position(&chart, xr, yr, &[Series::new("s", pts)])
        };
        // The jaws' work-precision points: one at the middle of the right side, so the legend
        // leaves plotters' default place.
        let jaws = vec![
            (0.014, 66.0),
            (0.047, 20.0),
            (0.033, 16.0),
            (0.052, 8.2),
            (0.074, 2.5),
        ];
        assert!(!matches!(
            pos(jaws.clone()),
            SeriesLabelPosition::MiddleRight
        ));
        // Points along the diagonal leave the upper-left and lower-right corners free; the
        // first of those in the order tried is taken.
        let diagonal: Vec<(f64, f64)> = (1..=9).map(|k| (k as f64, k as f64)).collect();
        assert!(matches!(pos(diagonal), SeriesLabelPosition::UpperLeft));
        // Nothing in the middle of the right side, points nor line: the default stays.
        assert!(matches!(
            pos(vec![(100.0, 1.0), (1.0, 1.0), (1.0, 100.0), (100.0, 100.0)]),
            SeriesLabelPosition::MiddleRight
        ));
        // A line across the middle of the right side, its two points elsewhere: the legend
        // leaves it (the peg's chart, whose legend covered its LOD line).
        assert!(!matches!(
            pos(vec![(1.0, 100.0), (100.0, 1.0)]),
            SeriesLabelPosition::MiddleRight
        ));
    }

    #[test]
    fn tick_labels_read_at_a_glance() {
        assert_eq!(tick_label(9.999999999999999e-5), "1e-4");
        assert_eq!(tick_label(0.30000000000000004), "0.3");
        assert_eq!(tick_label(2.5e-6), "2.5e-6");
        assert_eq!(tick_label(1234.0), "1230");
        assert_eq!(tick_label(0.001), "0.001");
        assert_eq!(tick_label(0.0), "0");
        assert_eq!(tick_label(-0.05), "-0.05");
        assert_eq!(tick_label(20000.0), "2e4");
    }

    #[test]
    fn log_ticks_cover_short_ranges() {
        assert_eq!(log_ticks(0.04, 0.2), vec![0.05, 0.1, 0.2]);
        assert_eq!(log_ticks(0.504, 0.927).len(), 4); // 0.6 to 0.9
        let t = log_ticks(1e-4, 1.0);
        assert!(
            t.contains(&1e-4) && t.contains(&1.0) && t.len() >= 5,
            "{t:?}"
        );
        assert!(log_ticks(0.011, 0.019).len() >= 2);
        // Not a log range: no ticks, and no endless loop.
        assert!(log_ticks(0.0, 1.0).is_empty());
        assert!(log_ticks(-1.0, 1.0).is_empty());
        assert!(log_ticks(f64::NAN, 1.0).is_empty());
    }

    /// The numeric `<text>` labels of an SVG with their `x` and `y` attributes.
    fn numeric_labels(svg: &str) -> Vec<(f64, f64, String)> {
        let attr = |tag: &str, name: &str| -> Option<f64> {
            let start = tag.find(&format!(" {name}=\""))? + name.len() + 3;
            tag[start..].split('"').next()?.parse().ok()
        };
        svg.split("<text")
            .skip(1)
            .filter_map(|t| {
                let (tag, rest) = t.split_once('>')?;
                let text = rest.split('<').next()?.trim();
                text.parse::<f64>().ok()?;
                Some((attr(tag, "x")?, attr(tag, "y")?, text.to_owned()))
            })
            .collect()
    }

    /// `pts` labelled with `labels` (log x, `y_scale` y) drawn to an SVG, and each label's
    /// text box `(left, top, right, bottom)` in it (13 px text, about 7.2 px a character).
    fn drawn_label_boxes(
        name: &str,
        pts: Vec<(f64, f64)>,
        labels: &[&str],
        y_scale: Scale,
    ) -> Vec<(f64, f64, f64, f64)> {
        let dir = std::env::temp_dir().join(format!("haptic-plot-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("{name}.svg"));
        let labels: Vec<String> = labels.iter().map(|l| l.to_string()).collect();
        line_chart(
            &path,
            &Chart {
                title: name,
                x_label: "error",
                y_label: "time (ms)",
                x_scale: Scale::Log,
                y_scale,
            },
            &[Series::new("lod", pts).with_point_labels(labels.clone())],
        )
        .unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        let attr = |tag: &str, name: &str| -> f64 {
            let start = tag.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
            tag[start..].split('"').next().unwrap().parse().unwrap()
        };
        labels
            .iter()
            .map(|label| {
                // plotters writes a text element's content on its own line.
                let at = svg
                    .find(&format!(">\n{label}\n<"))
                    .expect("the label is drawn");
                let tag = &svg[svg[..at].rfind("<text").unwrap()..at];
                let (x, y) = (attr(tag, "x"), attr(tag, "y"));
                (x, y, x + 7.2 * label.chars().count() as f64, y + 13.0)
            })
            .collect()
    }

    /// A point's label stays inside the image, the rightmost one included.
    #[test]
    fn point_labels_stay_inside_the_image() {
        let pts = vec![(1e-6, 0.09), (1e-4, 0.085), (2e-3, 0.08)];
        let boxes = drawn_label_boxes("inside", pts, &["0.4 %", "1 %", "2.5, 5 %"], Scale::Linear);
        for b in &boxes {
            assert!(b.0 >= 0.0 && b.2 <= 900.0, "{b:?}");
        }
    }

    /// A label whose box would overlap one already placed moves below its point, then further
    /// out; one that overlaps nothing stays above.
    #[test]
    fn labels_move_off_one_another() {
        let mut placed = Vec::new();
        assert_eq!(place_label((100, 100), 6, "2.5 %", &mut placed), (6, -16));
        assert_eq!(place_label((102, 98), 6, "5 %", &mut placed), (6, 4));
        assert_eq!(place_label((101, 99), 6, "1 %", &mut placed), (6, -30));
        assert_eq!(place_label((400, 100), 6, "0 %", &mut placed), (6, -16));
        let boxes = placed.clone();
        for (i, a) in boxes.iter().enumerate() {
            for b in &boxes[i + 1..] {
                let overlap = a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3;
                assert!(!overlap, "{a:?} {b:?}");
            }
        }
    }

    /// Two points a few pixels apart get labels whose boxes do not overlap in the drawn SVG.
    #[test]
    fn near_points_keep_readable_labels() {
        let pts = vec![(0.01, 1.0), (0.0101, 1.01), (0.5, 3.0)];
        let boxes = drawn_label_boxes("near", pts, &["2.5 %", "5 %", "0 %"], Scale::Log);
        let (a, b) = (boxes[0], boxes[1]);
        let overlap = a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3;
        assert!(!overlap, "{boxes:?}");
    }

    /// Every chart kind holds tick labels on both axes, and none with float noise.
    #[test]
    fn charts_have_tick_labels_on_both_axes() {
        let dir = std::env::temp_dir().join(format!("haptic-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (i, (xs, ys)) in [
            (Scale::Linear, Scale::Linear),
            (Scale::Log, Scale::Log),
            (Scale::Linear, Scale::Log),
            (Scale::Log, Scale::Linear),
        ]
        .into_iter()
        .enumerate()
        {
            let path = dir.join(format!("c{i}.svg"));
            let pts: Vec<(f64, f64)> = (1..40)
                .map(|k| (1e-4 * 1.3f64.powi(k), 0.07 * 1.1f64.powi(k)))
                .collect();
            line_chart(
                &path,
                &Chart {
                    title: "A chart with a title long enough that it would not fit at the default size",
                    x_label: "x (s)",
                    y_label: "y (N)",
                    x_scale: xs,
                    y_scale: ys,
                },
                &[Series::new("curve", pts)],
            )
            .unwrap();
            let svg = std::fs::read_to_string(&path).unwrap();
            let labels = numeric_labels(&svg);
            // The x axis's labels share a row (the lowest one), the y axis's a column (the
            // leftmost one): at least three on each.
            let bottom = labels.iter().map(|l| l.1).fold(f64::MIN, f64::max);
            let left = labels.iter().map(|l| l.0).fold(f64::MAX, f64::min);
            let on_x = labels.iter().filter(|l| (l.1 - bottom).abs() < 1.0).count();
            let on_y = labels.iter().filter(|l| (l.0 - left).abs() < 1.0).count();
            assert!(on_x >= 3, "{xs:?}/{ys:?}: x-axis labels in {labels:?}");
            assert!(on_y >= 3, "{xs:?}/{ys:?}: y-axis labels in {labels:?}");
            assert!(!svg.contains("99999"), "float noise in {xs:?}/{ys:?}");
        }
    }
}
