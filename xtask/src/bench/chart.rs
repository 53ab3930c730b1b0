//! The work-precision chart of one scene's collision rows: median query time against median
//! wrench error, LOD at each threshold, parry as a line at its own time.

use std::path::Path;

use haptic_core::Real;

use super::collision::Row;
use crate::plot::{self, Chart, Scale, Series};

/// The LOD rows' points (median error, median time in ms) with their thresholds as labels.
/// Thresholds that land on the same point (a scene whose walk stops at the same nodes at every
/// threshold) share one point and one label, "0.4, 1, 2.5 %", instead of labels printed over one
/// another.
fn labelled_points(lod_rows: &[&Row]) -> (Vec<(f64, f64)>, Vec<String>) {
    let near = |a: f64, b: f64, within: f64| (a / b).ln().abs() < within;
    let mut points: Vec<(f64, f64)> = Vec::new();
    let mut thresholds: Vec<Vec<String>> = Vec::new();
    for r in lod_rows {
        let point = (r.wrench_error_rel_median, r.median_s * 1e3);
        let threshold = crate::plot::tick_label(r.threshold * 100.0);
        match (points.last(), thresholds.last_mut()) {
            (Some(last), Some(labels))
                if near(point.0, last.0, 0.02) && near(point.1, last.1, 0.05) =>
            {
                labels.push(threshold);
            }
            _ => {
                points.push(point);
                thresholds.push(vec![threshold]);
            }
        }
    }
    let labels = thresholds
        .iter()
        .map(|t| format!("{} %", t.join(", ")))
        .collect();
    (points, labels)
}

/// The work-precision chart of one scene's rows.
pub(super) fn work_precision_chart(
    path: &Path,
    scene_name: &str,
    rows: &[Row],
    rule: haptic_collision::StoppingRule,
) -> anyhow::Result<()> {
    let lod_rows: Vec<&Row> = rows
        .iter()
        .filter(|r| r.backend == "lod" && r.wrench_error_rel_median > 0.0)
        .collect();
    let (lod_points, lod_labels) = labelled_points(&lod_rows);
    // Parry has one point: drawn as a horizontal line at its median time across the LOD range
    // (a single point would not show in a line chart); its own error is in the legend.
    let parry = rows.iter().find(|r| r.backend == "parry");
    let parry_ms = parry.map_or(Real::NAN, |r| r.median_s) * 1e3;
    let parry_err = parry.map_or(Real::NAN, |r| r.wrench_error_rel_median);
    let xs = lod_points.iter().map(|p| p.0).filter(|x| *x > 0.0);
    let (x0, x1) = xs.fold((Real::INFINITY, 0.0 as Real), |(lo, hi), x| {
        (lo.min(x), hi.max(x))
    });
    // At least 0.4 of a decade wide, so that it shows where every LOD point coincides.
    let parry_points = if x0.is_finite() {
        vec![(x0.min(x1 / 1.6), parry_ms), (x1.max(x0 * 1.6), parry_ms)]
    } else {
        Vec::new()
    };
    plot::line_chart(
        path,
        &Chart {
            title: &format!(
                "Collision queries, {scene_name}: time against wrench error (reference: every contact at threshold 0)"
            ),
            x_label: "median wrench error relative to the all-pairs reference",
            y_label: "median query time (ms)",
            x_scale: Scale::Log,
            y_scale: Scale::Log,
        },
        &[
            Series::new(
                format!("LOD, {rule} stopping rule (threshold beside each point)"),
                lod_points,
            )
            .with_point_labels(lod_labels),
            Series::new(
                format!("parry (median time; its own error {parry_err:.2})"),
                parry_points,
            ),
        ],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(threshold: Real, error: Real, median_s: Real) -> Row {
        Row {
            backend: "lod",
            threshold,
            median_s,
            p99_s: median_s,
            contacts_mean: 0.0,
            contacts_max: 0,
            raw_contacts_max: 0,
            node_pairs_mean: 0.0,
            wrench_error_rel_median: error,
            wrench_error_rel_p90: error,
            wrench_error_rel_max: error,
            wrench_error_rel_median_chained: error,
            wrench_error_rel_p90_chained: error,
            wrench_error_rel_unclustered_median: error,
            wrench_error_rel_unclustered_p90: error,
            force_ratio_median: 1.0,
            build_s: 0.0,
        }
    }

    /// Thresholds that give the same point share one label; the others keep their own.
    #[test]
    fn coincident_thresholds_share_one_label() {
        let rows = [
            row(0.0, 0.02, 110e-6),
            row(0.004, 0.057, 75e-6),
            row(0.01, 0.057, 76e-6),
            row(0.025, 0.057, 75e-6),
            row(0.05, 0.09, 40e-6),
        ];
        let refs: Vec<&Row> = rows.iter().collect();
        let (points, labels) = labelled_points(&refs);
        assert_eq!(labels, ["0 %", "0.4, 1, 2.5 %", "5 %"]);
        assert_eq!(points.len(), 3);
        assert!((points[1].1 - 0.075).abs() < 1e-12, "{points:?}");
    }
}
