//! `cargo xtask study compare --study FILE [--out DIR] [--quick]`: every combination of the
//! study file's axes (integrator, back-end, threshold, tool mass, coupling and contact
//! stiffness, contact and haptic rate) run in virtual time on the user's scene and hand motion,
//! each against a reference, ranked by run time within an error budget.
//!
//! **Reference.** One per distinct physical setting (tool mass, coupling and contact stiffness):
//! full-Newton backward Euler at four times the study's finest haptic rate (twice with
//! `--quick`; at most 20 kHz),
//! exact contacts (LOD at threshold 0) queried at every haptic step. `force_error_rel` is the RMS
//! of the difference between the force a configuration sends and the reference's, sampled at
//! 1 kHz, over the reference's RMS.
//!
//! **Stable**: the run ends without error, no integration step fails, the tool is never reset,
//! the coupling stretches less than 10 cm and the tool sinks less than 5 mm; otherwise the rule
//! that failed is reported.
//!
//! **Run time**: after the parallel pass, every configuration runs again alone (best of two;
//! one with `--quick`), so that the times do not share the cores; the contact stage's time is
//! the sum of its queries' costs, the haptic stage's the sum of its steps'.
//!
//! **Ranking**: stable configurations within the error budget first, fastest first (total
//! seconds per simulated second; times in the same 10 % step are a tie, decided by the error);
//! then the other stable ones by error; then the unstable ones. parry has no error threshold: it
//! runs once per combination of the other axes. A reference that is not stable, or that sends no force,
//! stops the study with an error.
//!
//! Output: `DIR/compare.json`, `DIR/compare.md`, `DIR/compare-work-precision.svg` (run time
//! against error, one labelled point per stable configuration) and `DIR/compare-force.svg` (force
//! over time for the reference and the three best configurations).

mod run;
mod spec;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context;
use haptic_core::Real;
use haptic_runtime::Scene;
use rayon::prelude::*;
use serde::Serialize;

use crate::common::write_json;
use crate::plot::{Chart, Scale, Series, line_chart, tick_label};
use run::{Measured, SAMPLE_HZ, configure, force_error_rel, reference_of, rms};
use spec::{Backend, Config, Study};

/// Arguments of `study compare`.
#[derive(clap::Args, Debug, Clone)]
pub struct CompareArgs {
    /// The study file (TOML; see `xtask/studies/`).
    #[arg(long)]
    pub study: PathBuf,
    /// Output options.
    #[command(flatten)]
    pub out: crate::OutArgs,
}

/// One configuration's row of `compare.json`.
#[derive(Serialize)]
struct Row {
    /// Rank by the ranking rule (it depends on timing, so it is not part of the JSON rows, which
    /// are bit-for-bit reproducible apart from their timing fields).
    #[serde(skip)]
    rank: usize,
    integrator: &'static str,
    backend: Backend,
    /// The LOD back-end's error threshold; none for parry.
    error_threshold: Option<Real>,
    mass_kg: Real,
    coupling_stiffness_n_per_m: Real,
    contact_stiffness_n_per_m: Real,
    contact_hz: Real,
    haptic_hz: Real,
    stable: bool,
    /// The stability rule that failed, if any.
    failed_rule: Option<&'static str>,
    /// The run's error, if it ended with one.
    error: Option<String>,
    max_penetration_m: Real,
    /// Newton steps that did not converge and took the semi-implicit step instead
    /// (`SafetyConfig::semi_implicit_fallback`, on as for any user); 0 for the other integrators.
    solver_fallbacks: u64,
    rms_force_n: Real,
    force_error_rel: Option<Real>,
    within_error_budget: bool,
    contact_rate_hz: Real,
    seconds_per_simulated_second: Real,
    haptic_seconds_per_simulated_second: Real,
    contact_seconds_per_simulated_second: Real,
}

/// `compare.json`.
#[derive(Serialize)]
struct Report {
    study: String,
    scene: String,
    motion: Option<String>,
    duration_s: Real,
    error_budget: Real,
    quick: bool,
    reference: &'static str,
    rows: Vec<Row>,
    /// Row indices best first (the ranking uses run time, so it varies between runs).
    ranking_by_time: Vec<usize>,
}

/// The first stability rule a run breaks, if any.
fn failed_rule(m: &Measured, contact_hz: Real) -> Option<&'static str> {
    let s = match &m.summary {
        Err(_) => return Some("run_error"),
        Ok(s) => s,
    };
    if s.contact_rate_hz < 0.5 * contact_hz {
        Some("contact_rate_not_reached")
    } else if s.solver_failures > 0 {
        Some("step_failed")
    } else if m.resets > 0 {
        Some("tool_reset")
    } else if s.zero_force_steps > 0 {
        Some("zero_force_step")
    } else if s.max_coupling_deviation_m > 0.1 {
        Some("deviation_over_10_cm")
    } else if s.max_penetration_m > 5e-3 {
        Some("penetration_over_5_mm")
    } else {
        None
    }
}

/// The physical setting of a configuration, the key of its reference.
fn physics_key(c: &Config) -> String {
    let v = |x: Option<Real>, unit: &str| {
        x.map_or("the scene's".to_owned(), |x| {
            format!("{} {unit}", tick_label(x))
        })
    };
    format!(
        "tool mass {}, coupling stiffness {}, contact stiffness {}",
        v(c.mass_kg, "kg"),
        v(c.coupling_stiffness_n_per_m, "N/m"),
        v(c.contact_stiffness_n_per_m, "N/m")
    )
}

/// Runs a study.
pub fn run(args: &CompareArgs) -> anyhow::Result<()> {
    let study = Study::load(&args.study)?;
    let configs = study.configurations();
    // --quick keeps the motion (a shorter run may never reach the contact) and makes the
    // reference coarser: twice the finest haptic rate instead of four times.
    let duration_s = study.duration_s;
    let reference_factor = if args.out.quick { 2.0 } else { 4.0 };
    let dir = args.out.dir("compare")?;
    let scene =
        Scene::load(&study.scene).with_context(|| format!("scene {}", study.scene.display()))?;
    let base = scene.assemble()?;
    // Every configuration's values are checked before anything runs.
    for c in &configs {
        configure(&base, c).with_context(|| format!("configuration {c:?}"))?;
    }
    let lod = crate::common::lod_backend(&base.tool_mesh, &base.obstacles)?
        .with_stopping_rule(base.stopping_rule);
    let finest_hz = configs
        .iter()
        .map(|c| c.haptic_hz.unwrap_or(base.config.haptic_rate_hz))
        .fold(0.0, Real::max);
    let mut references: BTreeMap<String, Config> = BTreeMap::new();
    for c in &configs {
        references
            .entry(physics_key(c))
            .or_insert_with(|| reference_of(c, finest_hz, reference_factor));
    }
    println!(
        "study {}: {} configurations and {} reference(s) on `{}`, {duration_s} s each, in virtual time",
        args.study.display(),
        configs.len(),
        references.len(),
        scene.name
    );
    let jobs: Vec<Config> = references
        .values()
        .copied()
        .chain(configs.iter().copied())
        .collect();
    let bar = indicatif::ProgressBar::new(jobs.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} configurations {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let measured: Vec<anyhow::Result<Measured>> = jobs
        .par_iter()
        .map(|c| {
            let m = run::run(&study, &base, &lod, c, duration_s);
            bar.inc(1);
            m
        })
        .collect();
    bar.finish_and_clear();
    let mut measured = measured.into_iter();
    let mut reference_forces: BTreeMap<String, Vec<haptic_core::Vec3>> = BTreeMap::new();
    for (key, c) in &references {
        let m = measured.next().expect("one result per job")?;
        let (_, contact_hz) = configure(&base, c)?;
        if let Some(rule) = failed_rule(&m, contact_hz) {
            let detail = m.summary.as_ref().err().cloned().unwrap_or_default();
            anyhow::bail!(
                "the reference ({key}) is not stable ({rule}{}{detail}): no error can be measured against it",
                if detail.is_empty() { "" } else { ": " }
            );
        }
        if rms(&m.forces) < run::MIN_REFERENCE_RMS_N {
            anyhow::bail!(
                "the reference ({key}) sends no force (RMS below {} N): there is nothing to compare with. A recording from an input-only device carries zero force limits.",
                run::MIN_REFERENCE_RMS_N
            );
        }
        reference_forces.insert(key.clone(), m.forces);
    }
    let results: Vec<Measured> = measured.collect::<anyhow::Result<_>>()?;
    // Timing: the parallel pass shares the cores; time every configuration again, one at a time,
    // and keep the best of `repeats` runs.
    let repeats = if args.out.quick { 1 } else { 2 };
    println!("timing each configuration alone ({repeats} run(s) each)");
    let bar = indicatif::ProgressBar::new(configs.len() as u64);
    let mut timings = Vec::with_capacity(configs.len());
    for c in &configs {
        let mut best: Option<(Real, Real, Real)> = None;
        for _ in 0..repeats {
            let m = run::run(&study, &base, &lod, c, duration_s)?;
            if best.is_none_or(|b| m.wall_s < b.0) {
                best = Some((m.wall_s, m.haptic_s, m.contact_s));
            }
        }
        timings.push(best.expect("at least one run"));
        bar.inc(1);
    }
    bar.finish_and_clear();

    let mut rows = Vec::new();
    let mut forces_by_row = Vec::new();
    for ((c, m), (wall_s, haptic_s, contact_s)) in configs.iter().zip(results).zip(timings) {
        let (p, contact_hz) = configure(&base, c)?;
        let rule = failed_rule(&m, contact_hz);
        let reference = &reference_forces[&physics_key(c)];
        let err = force_error_rel(&m.forces, reference);
        let (pen, rate, fallbacks, error) = match &m.summary {
            Ok(s) => (
                s.max_penetration_m,
                s.contact_rate_hz,
                s.solver_fallbacks,
                None,
            ),
            Err(e) => (Real::NAN, Real::NAN, 0, Some(e.clone())),
        };
        rows.push(Row {
            rank: 0,
            integrator: c.integrator.name(),
            backend: c.backend,
            error_threshold: match c.backend {
                Backend::Lod => Some(p.config.query.error_threshold),
                Backend::Parry => None,
            },
            mass_kg: p.body.mass_kg(),
            coupling_stiffness_n_per_m: p.coupling.stiffness_n_per_m,
            contact_stiffness_n_per_m: p.penalty.stiffness_n_per_m,
            contact_hz,
            haptic_hz: p.config.haptic_rate_hz,
            stable: rule.is_none(),
            failed_rule: rule,
            error,
            max_penetration_m: pen,
            solver_fallbacks: fallbacks,
            rms_force_n: rms(&m.forces),
            force_error_rel: err,
            within_error_budget: rule.is_none() && err.is_some_and(|e| e <= study.error_budget),
            contact_rate_hz: rate,
            seconds_per_simulated_second: wall_s / duration_s,
            haptic_seconds_per_simulated_second: haptic_s / duration_s,
            contact_seconds_per_simulated_second: contact_s / duration_s,
        });
        forces_by_row.push(m.forces);
    }
    // Rank: within budget by speed, then stable by error, then unstable by error.
    let keys: Vec<RankKey> = rows.iter().map(RankKey::of).collect();
    let order = rank_order(&keys);
    for (rank, &i) in order.iter().enumerate() {
        rows[i].rank = rank + 1;
    }

    write_markdown(
        &dir.join("compare.md"),
        &study,
        &args.study,
        &rows,
        &order,
        duration_s,
    )?;
    plots(
        &dir,
        &rows,
        &order,
        &forces_by_row,
        &reference_forces,
        &configs,
    )?;
    let report = Report {
        study: args.study.display().to_string(),
        scene: study.scene.display().to_string(),
        motion: study.motion.as_ref().map(|m| m.display().to_string()),
        duration_s,
        error_budget: study.error_budget,
        quick: args.out.quick,
        reference: "per tool mass, coupling and contact stiffness: newton_backward_euler at 4x (--quick: 2x) the finest haptic rate (at most 20 kHz), LOD at threshold 0 queried every haptic step",
        rows,
        ranking_by_time: order,
    };
    write_json(&dir.join("compare.json"), &report)?;
    Ok(())
}

fn label(r: &Row) -> String {
    format!(
        "{} {} {} {}",
        r.integrator,
        match r.backend {
            Backend::Lod => format!(
                "lod {}%",
                tick_label(r.error_threshold.unwrap_or(0.0) * 100.0)
            ),
            Backend::Parry => "parry".to_owned(),
        },
        format_args!("{} g", tick_label(r.mass_kg * 1e3)),
        format_args!("{} Hz", tick_label(r.contact_hz))
    )
}

fn write_markdown(
    path: &std::path::Path,
    study: &Study,
    study_path: &std::path::Path,
    rows: &[Row],
    order: &[usize],
    duration_s: Real,
) -> anyhow::Result<()> {
    let mut md = String::new();
    writeln!(
        md,
        "# Comparison: {}\n\nScene `{}`, {} s of virtual time per configuration, {} configurations. \
         Error: RMS of the force sent minus the reference's, over the reference's RMS (the \
         reference: full-Newton backward Euler at a fine step, exact contacts every step, same \
         mass and stiffnesses). Ranked: stable configurations within the error budget ({}) \
         fastest first, then the other stable ones by error, then the unstable ones.\n",
        study_path.display(),
        study.scene.display(),
        duration_s,
        rows.len(),
        study.error_budget
    )?;
    writeln!(
        md,
        "| rank | integrator | back-end | threshold | mass | k coupling | k contact | contact Hz | haptic Hz | stable | force error | max penetration | s / simulated s (haptic + contact) |"
    )?;
    writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|---|---|")?;
    for &i in order {
        let r = &rows[i];
        writeln!(
            md,
            "| {} | {} | {:?} | {} | {} g | {} N/m | {} N/m | {} | {} | {} | {} | {} mm | {} ({} + {}) |",
            r.rank,
            r.integrator,
            r.backend,
            r.error_threshold
                .map_or("–".to_owned(), |t| format!("{} %", tick_label(t * 100.0))),
            tick_label(r.mass_kg * 1e3),
            tick_label(r.coupling_stiffness_n_per_m),
            tick_label(r.contact_stiffness_n_per_m),
            tick_label(r.contact_hz),
            tick_label(r.haptic_hz),
            r.failed_rule
                .map_or("yes".to_owned(), |f| format!("no ({f})")),
            r.force_error_rel.map_or("–".to_owned(), tick_label),
            tick_label(r.max_penetration_m * 1e3),
            tick_label(r.seconds_per_simulated_second),
            tick_label(r.haptic_seconds_per_simulated_second),
            tick_label(r.contact_seconds_per_simulated_second),
        )?;
    }
    writeln!(
        md,
        "\nPlots: `compare-work-precision.svg` (run time against error), `compare-force.svg` (force sent, the reference and the three best)."
    )?;
    std::fs::write(path, md)?;
    println!("wrote {}", path.display());
    for &i in order.iter().take(5) {
        let r = &rows[i];
        println!(
            "  #{:<3} {:<48} error {:>6}  {} s/s{}",
            r.rank,
            label(r),
            r.force_error_rel.map_or("–".to_owned(), tick_label),
            tick_label(r.seconds_per_simulated_second),
            if r.stable { "" } else { "  unstable" }
        );
    }
    Ok(())
}

fn plots(
    dir: &std::path::Path,
    rows: &[Row],
    order: &[usize],
    forces: &[Vec<haptic_core::Vec3>],
    references: &BTreeMap<String, Vec<haptic_core::Vec3>>,
    configs: &[Config],
) -> anyhow::Result<()> {
    let stable: Vec<&Row> = rows
        .iter()
        .filter(|r| r.stable && r.force_error_rel.is_some_and(|e| e > 0.0))
        .collect();
    let mut by_integrator: BTreeMap<&str, Series> = BTreeMap::new();
    for r in &stable {
        let s = by_integrator
            .entry(r.integrator)
            .or_insert_with(|| Series::scatter(r.integrator, Vec::new()));
        s.points.push((
            r.force_error_rel.unwrap_or(Real::NAN),
            r.seconds_per_simulated_second,
        ));
        s.point_labels.push(format!("#{}", r.rank));
    }
    let series: Vec<Series> = by_integrator.into_values().collect();
    line_chart(
        &dir.join("compare-work-precision.svg"),
        &Chart {
            title: "Run time against force error, stable configurations (labels: rank)",
            x_label: "force error relative to the reference",
            y_label: "wall time per simulated second (s)",
            x_scale: Scale::Log,
            y_scale: Scale::Log,
        },
        &series,
    )?;
    let t = |i: usize| (i + 1) as Real / SAMPLE_HZ;
    let mut lines = Vec::new();
    for &i in order.iter().take(3) {
        lines.push(Series::new(
            format!("#{} {}", rows[i].rank, label(&rows[i])),
            forces[i]
                .iter()
                .enumerate()
                .map(|(k, f)| (t(k), f.norm()))
                .collect(),
        ));
    }
    // The references of the plotted configurations' physical settings, drawn last (on top).
    let mut drawn: Vec<String> = Vec::new();
    for &i in order.iter().take(3) {
        let key = physics_key(&configs[i]);
        if drawn.contains(&key) {
            continue;
        }
        let reference = &references[&key];
        lines.push(Series::new(
            format!("reference, {} g", tick_label(rows[i].mass_kg * 1e3)),
            reference
                .iter()
                .enumerate()
                .map(|(k, f)| (t(k), f.norm()))
                .collect(),
        ));
        drawn.push(key);
    }
    line_chart(
        &dir.join("compare-force.svg"),
        &Chart {
            title: "Force sent to the device: the three best configurations and their references",
            x_label: "time (s)",
            y_label: "|F| (N)",
            x_scale: Scale::Linear,
            y_scale: Scale::Linear,
        },
        &lines,
    )?;
    Ok(())
}

/// Where a configuration ranks (see [`rank_order`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct RankKey {
    /// 0 within the error budget, 1 stable, 2 unstable.
    class: u8,
    /// Within the budget, the run time in steps of 10 % (`⌊ln t / ln 1.1⌋`); 0 otherwise.
    time_step: Real,
    /// The force error (infinite where there is none).
    error: Real,
}

impl RankKey {
    fn of(r: &Row) -> Self {
        Self::new(
            r.within_error_budget,
            r.stable,
            r.seconds_per_simulated_second,
            r.force_error_rel,
        )
    }

    fn new(within_budget: bool, stable: bool, seconds: Real, error: Option<Real>) -> Self {
        Self {
            class: u8::from(!within_budget) + u8::from(!stable),
            time_step: if within_budget {
                (seconds.ln() / 1.1_f64.ln()).floor()
            } else {
                0.0
            },
            error: error.unwrap_or(Real::INFINITY),
        }
    }
}

/// The configurations in rank order: within the error budget by speed, times in the same 10 %
/// step being a tie on this machine that the error decides; then the stable ones by error; then
/// the unstable ones by error. Times are compared by step, not as "within 10 % of each other",
/// which is not transitive (1.0, 1.08 and 1.16 s): a sort needs a total order, and panics
/// without one.
fn rank_order(keys: &[RankKey]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..keys.len()).collect();
    order.sort_by(|&a, &b| {
        let (ka, kb) = (&keys[a], &keys[b]);
        ka.class
            .cmp(&kb.class)
            .then(ka.time_step.total_cmp(&kb.time_step))
            .then(ka.error.total_cmp(&kb.error))
    });
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_within_budget_rank_by_time_step_then_error_and_the_rest_by_error() {
        let key = RankKey::new;
        let keys = [
            key(false, false, 0.1, Some(0.01)), // unstable: last
            key(false, true, 0.1, Some(0.3)),   // stable, outside the budget
            key(true, true, 2.0, Some(0.01)),   // slower step
            key(true, true, 1.01, Some(0.04)),  // same step as the next: the error decides
            key(true, true, 1.02, Some(0.02)),
            key(false, true, 9.0, Some(0.2)),
        ];
        assert_eq!(rank_order(&keys), [4, 3, 2, 5, 1, 0]);
    }

    #[test]
    fn times_that_are_each_within_ten_percent_of_the_next_still_sort() {
        // 1.00, 1.03, 1.06, ...: each within 10 % of its neighbours, not of every other one.
        // Comparing pairs "within 10 %" gave no total order and the sort panicked.
        let keys: Vec<RankKey> = (0..60)
            .map(|i| {
                let t = 1.03_f64.powi(i);
                let error = ((i * 37) % 11) as Real * 0.01;
                RankKey::new(true, true, t, Some(error))
            })
            .collect();
        let order = rank_order(&keys);
        for w in order.windows(2) {
            let (a, b) = (&keys[w[0]], &keys[w[1]]);
            assert!(
                a.time_step < b.time_step || (a.time_step == b.time_step && a.error <= b.error),
                "{a:?} before {b:?}"
            );
        }
        // Any order of the same keys ranks them the same way.
        let reversed: Vec<RankKey> = keys.iter().rev().copied().collect();
        let back: Vec<usize> = rank_order(&reversed)
            .into_iter()
            .map(|i| keys.len() - 1 - i)
            .collect();
        let same_keys =
            |x: &[usize], y: &[usize]| x.iter().zip(y).all(|(&i, &j)| keys[i] == keys[j]);
        assert!(same_keys(&order, &back));
    }
}
