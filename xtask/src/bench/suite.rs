//! `cargo xtask bench collision --suite [--quick]`: the collision benchmark on every scene of a
//! generalization suite, so that an accuracy or speed figure is never read off the one scene it
//! was tuned on.
//!
//! - From the repository's meshes: the jaws and the spoon in the cup (as `bench collision`), the
//!   round peg inserted 4 mm into its hole, the fork and the spoon lowered into the mug, the
//!   fork laid on the outside of the teacup's wall (a few small contacts, at coarse levels fewer
//!   than the clusters), and the fork laid on the back of Keenan Crane's Spot scaled to 8.5 cm,
//!   `δ` = 2 mm (a smooth obstacle smaller than the tool, its triangles smaller than `δ` and its
//!   surface curved on that scale: the hardest scene of the suite); and Spot lowered upright
//!   onto a bowl it cannot enter (`shapes::socket`, 48 segments), its feet on the flat rim
//!   whose coarse pieces overhang the bowl's opening (`lod/overhang.rs`).
//! - The peg in its hole remeshed (`shapes::split_at_midpoints` for the peg,
//!   `shapes::split_at_centroids` for the hole, whose thin fans are what meshing tools leave),
//!   on the same poses: the repository's meshes against the same surfaces tessellated
//!   otherwise, with its `tessellation_error_rel`.
//! - Generated in code (`shapes.rs`), each at two tessellations (density 1 and 2, about 4× the
//!   triangles), on the same poses: a 2 cm box face-on-face on a slab, a pair of spur gears in
//!   mesh (20 and 35 teeth, module 1 mm, 0.19 mm clearance) with the smaller gear rocking and
//!   sliding within its backlash, and an M8-like threaded rod turned a full turn in its nut
//!   (0.1 mm nominal radial clearance; the faceted threads cut the profile's corners, so the
//!   gap between the meshes varies along the turn and may close: penetrations are part of the
//!   scene), and a round peg in a bushing 0.1 mm wider whose walls' tessellations line up
//!   nowhere (40 and 33 segments), its contacts all around the wall cancelling.
//! - Per scene, parry and LOD at each threshold, as `bench collision` measures one scene; the
//!   poses are fewer (100, `--quick`: 12) and replayed once.
//! - `tessellation_error_rel`: for the generated pairs and the remeshed peg, per pose, `|W_fine − W_coarse| /
//!   |W_coarse|` of the reference wrenches (LOD at threshold 0), `W = (F, T / r)`; its median
//!   over the poses is reported on both tessellations' rows. Each reference clusters along its
//!   own chain of warm starts, so the figure includes the clustering's own variability.
//! - `clustering_variability_rel_*` per scene: the reference's contacts clustered cold against
//!   its chain of warm starts: how far two clusterings of the same contacts differ. Where it is
//!   large, errors of that size come from where Lloyd's method draws its boundaries rather than
//!   from the contacts (the error columns cluster from shared seeds, so they can be smaller).
//! - `force_cancellation_median` per scene: the reference's `Σ |fᵢ| / |Σ fᵢ|`, median over the
//!   poses (`wrench::force_cancellation`). Where it is large, the net wrench is a small residual
//!   of opposed forces, and a relative error of the contacts' forces grows by up to that factor
//!   in the net wrench's.
//! - Output: `DIR/suite.json` (every row with its scene, the fields of `collision.json`'s rows,
//!   and `tessellation_error_rel`; per scene its builds and speed-up; `suite_worst`, the worst
//!   figure over the scenes for each of issue 15's goals) and `DIR/suite_<scene>.svg`.

use std::time::Instant;

use haptic_core::Real;
use serde::Serialize;

use super::collision::{self, Row};
use crate::common;

mod scenes;
use scenes::{
    Entry, ball_in_socket, bolt_and_nut, boxes, file_scene, fork_on_cup, fork_on_spot, gears,
    peg_in_bushing, peg_in_hole, ring_on_cone, spot_on_bowl, utensil_in_mug,
};

/// A row of `suite.json`.
#[derive(Serialize)]
struct SuiteRow<'a> {
    scene: &'a str,
    #[serde(flatten)]
    row: &'a Row,
    /// Median `|W_fine − W_coarse| / |W_coarse|` of the generated shape (`null` for file meshes).
    tessellation_error_rel: Option<Real>,
}

/// One scene in `suite.json`.
#[derive(Serialize)]
struct SuiteScene {
    name: String,
    description: String,
    tool_triangles: usize,
    obstacle_triangles: usize,
    delta_m: Real,
    /// The tool's bounding radius `r` (m): LOD stops a pair at `s_a + s_b ≤ threshold × r`, so
    /// at 2.5 % its pieces may stand `0.025 r / δ` penalty bands from their surfaces.
    tool_bounding_radius_m: Real,
    lod_build_s: Real,
    parry_build_s: Real,
    speedup_lod_2_5_percent_vs_parry: Real,
    tessellation_error_rel: Option<Real>,
    tessellation_error_rel_p90: Option<Real>,
    /// The reference's own contacts clustered cold against its chain of warm starts, median
    /// and p90 of the relative wrench difference: how far two clusterings of the same contacts
    /// differ on this scene (`collision.json`'s field of the same name).
    clustering_variability_rel_median: Real,
    clustering_variability_rel_p90: Real,
    /// How many times the reference's net force is smaller than the forces of its contacts,
    /// median over the poses (`collision.json`'s field of the same name).
    force_cancellation_median: Real,
}

/// The worst figure over the scenes, for each goal (as issue 15's acceptance reads them; a NaN
/// anywhere makes its figure NaN, written `null`).
#[derive(Serialize, Clone, Copy, Debug)]
pub(super) struct SuiteWorst {
    /// LOD at 2.5 %: the larger of the median errors seeded from the reference's
    /// representatives and along the run's own chain of warm starts.
    wrench_error_rel_median: Real,
    /// LOD at 2.5 %, along its own chain of warm starts (also in the figure above).
    wrench_error_rel_median_chained: Real,
    /// LOD at 2.5 %: the larger of the two p90s.
    wrench_error_rel_p90: Real,
    tessellation_error_rel_median: Real,
    /// Most raw contacts of one LOD query, any threshold.
    contacts_max: usize,
    speedup_lod_2_5_vs_parry_min: Real,
    /// The longest build of any back-end (LOD or parry).
    build_s_max: Real,
}

/// `suite.json`.
#[derive(Serialize)]
struct SuiteReport<'a> {
    quick: bool,
    /// The scenes asked for with `--only`, or `null` for the whole suite (whose worst figures
    /// are then the goals).
    only: Option<Vec<String>>,
    /// The LOD walk's stopping rule (`--stopping-rule`).
    stopping_rule: &'static str,
    poses_per_scene: usize,
    passes: usize,
    wrench: &'static str,
    seconds: Real,
    scenes: Vec<SuiteScene>,
    rows: Vec<SuiteRow<'a>>,
    suite_worst: SuiteWorst,
}

/// Keeps the scenes of `entries` named in `only` (`--only`), in the suite's order.
///
/// # Errors
/// A name that is not a scene of the suite, listing the names that are.
fn select(entries: &mut Vec<Entry>, only: &[String]) -> anyhow::Result<()> {
    if let Some(unknown) = only
        .iter()
        .find(|o| !entries.iter().any(|e| &e.scene.name == *o))
    {
        let names: Vec<&str> = entries.iter().map(|e| e.scene.name.as_str()).collect();
        anyhow::bail!(
            "--only: `{unknown}` is not a scene of the suite (scenes: {})",
            names.join(", ")
        );
    }
    entries.retain(|e| only.contains(&e.scene.name));
    Ok(())
}

/// Runs the suite (or the scenes named in `only`), writes `suite.json` and the charts, and
/// returns its worst figures (which `cargo xtask bench` also writes into `perf.json`).
pub(super) fn run(
    out: &crate::OutArgs,
    only: Option<&[String]>,
    rule: haptic_collision::StoppingRule,
) -> anyhow::Result<SuiteWorst> {
    let started = Instant::now();
    let dir = out.dir("collision")?;
    let (n, passes) = if out.quick {
        (12, 1)
    } else {
        (collision::POSES / 2, 1)
    };
    let mut entries = vec![
        file_scene("jaws", n)?,
        file_scene("spoon-cup", n)?,
        utensil_in_mug("fork", n)?,
        utensil_in_mug("spoon", n)?,
        fork_on_cup(n)?,
        fork_on_spot(n)?,
        spot_on_bowl(n)?,
    ];
    entries.splice(2..2, peg_in_hole(n)?);
    entries.extend(boxes(n)?);
    entries.extend(gears(n)?);
    entries.extend(bolt_and_nut(n)?);
    entries.extend(peg_in_bushing(n)?);
    entries.extend(ball_in_socket(n)?);
    entries.extend(ring_on_cone(n)?);

    if let Some(only) = only {
        select(&mut entries, only)?;
    }
    let mut measured = Vec::new();
    for e in &entries {
        let m = collision::measure(&e.scene, passes, rule)?;
        super::chart::work_precision_chart(
            &dir.join(format!("suite_{}.svg", e.scene.name)),
            &e.scene.name,
            &m.rows,
            rule,
        )?;
        measured.push(m);
    }
    // Tessellation error of each generated shape: fine against coarse, pose by pose.
    // `None` where the scene has no partner tessellation in this run (`--only`).
    let tessellation = |name: &str| -> anyhow::Result<Option<(Real, Real)>> {
        let find = |d: usize| {
            entries
                .iter()
                .zip(&measured)
                .find(|(e, _)| e.family.is_some_and(|f| f == (name, d)))
        };
        let (Some((_, coarse)), Some((_, fine))) = (find(1), find(2)) else {
            return Ok(None);
        };
        let errors = super::wrench::pose_errors(
            fine.reference.wrenches.iter().map(Some),
            coarse.reference.wrenches.iter().map(Some),
            coarse.radius_m,
        )?;
        Ok(Some((
            collision::quantile(&errors, 0.5),
            collision::quantile(&errors, 0.9),
        )))
    };
    let mut scenes = Vec::new();
    let mut rows = Vec::new();
    for (e, m) in entries.iter().zip(&measured) {
        let t = match e.family {
            Some((name, _)) => tessellation(name)?,
            None => None,
        };
        scenes.push(SuiteScene {
            name: e.scene.name.clone(),
            description: e.scene.description.clone(),
            tool_triangles: e.scene.tool.triangles().len(),
            obstacle_triangles: e.scene.obstacle.triangles().len(),
            delta_m: e.scene.delta_m,
            tool_bounding_radius_m: m.radius_m,
            lod_build_s: m.lod_build_s,
            parry_build_s: m.parry_build_s,
            speedup_lod_2_5_percent_vs_parry: m.speedup_2_5,
            tessellation_error_rel: t.map(|t| t.0),
            tessellation_error_rel_p90: t.map(|t| t.1),
            clustering_variability_rel_median: collision::quantile(&m.reference.cold_errors, 0.5),
            clustering_variability_rel_p90: collision::quantile(&m.reference.cold_errors, 0.9),
            force_cancellation_median: collision::quantile(&m.reference.cancellation, 0.5),
        });
        for r in &m.rows {
            rows.push(SuiteRow {
                scene: &e.scene.name,
                row: r,
                tessellation_error_rel: t.map(|t| t.0),
            });
        }
    }
    let at_2_5 = || {
        rows.iter()
            .filter(|r| r.row.backend == "lod" && (r.row.threshold - 0.025).abs() < 1e-12)
    };
    // A NaN is a figure that could not be measured: it makes the worst one NaN too.
    let max = |v: &mut dyn Iterator<Item = Real>| {
        v.fold(0.0, |m: Real, x| {
            if m.is_nan() || x.is_nan() {
                Real::NAN
            } else {
                m.max(x)
            }
        })
    };
    // The larger of two figures, NaN if either is.
    let worse = |a: Real, b: Real| {
        if a.is_nan() || b.is_nan() {
            Real::NAN
        } else {
            a.max(b)
        }
    };
    let worst = SuiteWorst {
        wrench_error_rel_median: max(&mut at_2_5().map(|r| {
            worse(
                r.row.wrench_error_rel_median,
                r.row.wrench_error_rel_median_chained,
            )
        })),
        wrench_error_rel_median_chained: max(
            &mut at_2_5().map(|r| r.row.wrench_error_rel_median_chained)
        ),
        wrench_error_rel_p90: max(&mut at_2_5().map(|r| {
            worse(
                r.row.wrench_error_rel_p90,
                r.row.wrench_error_rel_p90_chained,
            )
        })),
        tessellation_error_rel_median: max(&mut scenes
            .iter()
            .filter_map(|s| s.tessellation_error_rel)),
        contacts_max: rows
            .iter()
            .filter(|r| r.row.backend == "lod")
            .map(|r| r.row.contacts_max)
            .max()
            .unwrap_or(0),
        speedup_lod_2_5_vs_parry_min: scenes
            .iter()
            .map(|s| s.speedup_lod_2_5_percent_vs_parry)
            .fold(Real::INFINITY, Real::min),
        build_s_max: max(&mut scenes.iter().map(|s| s.lod_build_s.max(s.parry_build_s))),
    };
    println!();
    println!(
        "{:<18} {:>8} {:>8} {:>10} {:>10} {:>12} {:>12} {:>13} {:>9} {:>9} {:>8}",
        "scene",
        "tool",
        "obstacle",
        "err 2.5 %",
        "chained",
        "unclustered",
        "clustering",
        "cancellation",
        "contacts",
        "speed-up",
        "build s"
    );
    for (s, m) in scenes.iter().zip(&measured) {
        let r = m
            .rows
            .iter()
            .find(|r| r.backend == "lod" && (r.threshold - 0.025).abs() < 1e-12);
        let cmax = m
            .rows
            .iter()
            .filter(|r| r.backend == "lod")
            .map(|r| r.contacts_max)
            .max()
            .unwrap_or(0);
        println!(
            "{:<18} {:>8} {:>8} {:>10.3} {:>10.3} {:>12.3} {:>12.3} {:>13.1} {:>9} {:>8.1}× {:>8.2}{}",
            s.name,
            s.tool_triangles,
            s.obstacle_triangles,
            r.map_or(Real::NAN, |r| r.wrench_error_rel_median),
            r.map_or(Real::NAN, |r| r.wrench_error_rel_median_chained),
            r.map_or(Real::NAN, |r| r.wrench_error_rel_unclustered_median),
            s.clustering_variability_rel_median,
            s.force_cancellation_median,
            cmax,
            s.speedup_lod_2_5_percent_vs_parry,
            s.lod_build_s,
            s.tessellation_error_rel
                .map_or(String::new(), |t| format!("   tessellation {t:.3}")),
        );
    }
    println!(
        "(unclustered: the penalty integrated over the contacts themselves, the back-end's own error; clustering: the reference's own contacts clustered cold against its warm chain; where it is large, errors of that size come from where Lloyd's method draws its boundaries, not from the contacts; cancellation: the reference's forces over its net force, the factor by which the contacts' own relative errors can grow in the net wrench's)"
    );
    println!(
        "worst: error at 2.5 % {:.3} (chained {:.3}; goal 0.05), p90 {:.3} (goal 0.10), tessellation {:.3} (goal 0.05), contacts {} (goal 256), speed-up {:.1}× (goal 20×), build {:.2} s (goal 2 s)",
        worst.wrench_error_rel_median,
        worst.wrench_error_rel_median_chained,
        worst.wrench_error_rel_p90,
        worst.tessellation_error_rel_median,
        worst.contacts_max,
        worst.speedup_lod_2_5_vs_parry_min,
        worst.build_s_max
    );
    let report = SuiteReport {
        quick: out.quick,
        only: only.map(<[String]>::to_vec),
        stopping_rule: rule.name(),
        poses_per_scene: n,
        passes,
        wrench: collision::WRENCH,
        seconds: started.elapsed().as_secs_f64(),
        scenes,
        rows,
        suite_worst: worst,
    };
    common::write_json(&dir.join("suite.json"), &report)?;
    Ok(worst)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(entries: &[Entry]) -> Vec<&str> {
        entries.iter().map(|e| e.scene.name.as_str()).collect()
    }

    #[test]
    fn only_keeps_the_scenes_named_in_the_suites_order() {
        let mut entries = boxes(2).unwrap();
        entries.extend(gears(2).unwrap());
        let only = ["gears-fine".to_owned(), "boxes-coarse".to_owned()];
        select(&mut entries, &only).unwrap();
        assert_eq!(names(&entries), ["boxes-coarse", "gears-fine"]);
    }

    #[test]
    fn only_refuses_a_name_that_is_not_a_scene() {
        let mut entries = boxes(2).unwrap();
        let err = select(&mut entries, &["box".to_owned()])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("`box`") && err.contains("boxes-coarse, boxes-fine"),
            "{err}"
        );
        assert_eq!(entries.len(), 2, "nothing removed on an error");
    }
}
