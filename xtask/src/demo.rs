//! `cargo xtask demo`: a simulated hand moves a tool into contact through the full multirate
//! runtime (haptic thread + contact thread), and the telemetry is summarised.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use haptic_core::{CollisionBackend, Integrator};
use haptic_dynamics::{
    ForwardEuler, IntegratorKind, LinearizedBackwardEuler, NewtonBackwardEuler, PenaltyModel, Rk4,
};
use haptic_runtime::recording::RecordingHeader;
use haptic_runtime::{
    ContactLatency, PipelineBuilder, RunRecorder, RuntimeError, Scene, SceneParts, Summary,
};
use indicatif::{ProgressBar, ProgressStyle};

use crate::common::repo_root;

/// Arguments of the demo.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Scene: `spoon-cup`, `jaws` or a TOML file.
    #[arg(long, default_value = "spoon-cup")]
    pub scene: String,
    /// Seconds to run.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Integrator: be, newton-be, rk4, fe.
    #[arg(long, default_value = "be")]
    pub integrator: String,
    /// Collision back-end: lod or parry.
    #[arg(long, default_value = "lod")]
    pub backend: String,
    /// Step in simulated time instead of real time.
    #[arg(long)]
    pub virtual_time: bool,
    /// Haptic rate (Hz), instead of the scene's (up to 20,000).
    #[arg(long)]
    pub haptic_hz: Option<f64>,
    /// A time budget per contact update (ms): the error threshold is then picked update by
    /// update to fit it, instead of the scene's (e.g. 4 for a 250 Hz contact thread).
    #[arg(long)]
    pub query_budget_ms: Option<f64>,
    /// Do not ask the OS for real-time scheduling and core pinning (to measure without them).
    #[arg(long)]
    pub no_realtime_scheduling: bool,
    /// Write the telemetry summary as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Record the run to this file, for `cargo xtask view`.
    #[arg(long)]
    pub record: Option<PathBuf>,
}

/// The scene file of a named scene, or the path given.
fn scene_path(name: &str) -> PathBuf {
    match name {
        "spoon-cup" | "jaws" => repo_root()
            .join("xtask")
            .join("scenes")
            .join(format!("{name}.toml")),
        other => PathBuf::from(other),
    }
}

/// Runs the demo.
pub fn run(args: &DemoArgs) -> anyhow::Result<()> {
    if !(args.seconds.is_finite() && args.seconds > 0.0) {
        bail!("--seconds must be positive");
    }
    let path = scene_path(&args.scene);
    let scene = Scene::load(&path).with_context(|| format!("scene {}", path.display()))?;
    let t0 = Instant::now();
    let mut parts = scene.assemble()?;
    if let Some(hz) = args.haptic_hz {
        parts.config.haptic_rate_hz = hz;
    }
    if args.no_realtime_scheduling {
        parts.config.realtime_scheduling = false;
    }
    parts.config.validate().context("--haptic-hz")?;
    if let Some(ms) = args.query_budget_ms {
        parts.config.query_budget =
            Some(haptic_runtime::QueryBudget::new(ms * 1e-3).context("--query-budget-ms")?);
    }
    if parts.config.query_budget.is_some() && args.backend == "parry" {
        bail!(
            "a time budget picks the LOD back-end's error threshold; parry has none (use --backend lod)"
        );
    }
    println!(
        "scene `{}`: tool {} triangles, {:.1} g; {} obstacle(s), {} triangles",
        scene.name,
        parts.tool_mesh.triangles().len(),
        parts.body.mass_kg() * 1e3,
        parts.obstacles.len(),
        parts
            .obstacles
            .iter()
            .map(|(m, _)| m.triangles().len())
            .sum::<usize>(),
    );
    for (field, report) in &parts.load_reports {
        if let Some(repairs) = crate::common::mesh_repairs(report) {
            println!("{field}: {repairs}");
        }
    }
    let kind: IntegratorKind = args.integrator.parse()?;
    let header = match &args.record {
        Some(_) => Some(crate::recording::header_for_scene(
            &scene,
            &parts.tool_mesh_offset_m,
            vec![
                ("integrator".to_owned(), kind.name().to_owned()),
                ("back-end".to_owned(), args.backend.clone()),
                (
                    "contact rate".to_owned(),
                    if args.virtual_time {
                        format!("{} Hz (virtual time)", parts.contact_hz.unwrap_or(250.0))
                    } else {
                        "as fast as it runs (real time)".to_owned()
                    },
                ),
                (
                    "error threshold".to_owned(),
                    match &parts.config.query_budget {
                        Some(b) => format!(
                            "picked per update for a {} ms budget (each update records its own)",
                            b.budget_s * 1e3
                        ),
                        None => format!("{}", parts.config.query.error_threshold),
                    },
                ),
            ],
            parts.config.haptic_rate_hz,
            1000.0,
        )?),
        None => None,
    };
    let summary = match args.backend.as_str() {
        "lod" => {
            let backend = crate::common::lod_backend(&parts.tool_mesh, &parts.obstacles)?
                .with_stopping_rule(parts.stopping_rule);
            with_integrator(kind, backend, &parts, args, header.as_ref())
        }
        "parry" => {
            let backend = haptic_collision::ParryBackend::new(&parts.tool_mesh, &parts.obstacles)?;
            println!("parry meshes built in {:.2} s", t0.elapsed().as_secs_f64());
            with_integrator(kind, backend, &parts, args, header.as_ref())
        }
        other => bail!("unknown back-end `{other}`: use lod or parry"),
    };
    let summary = match summary {
        Ok(s) => s,
        Err(e) => {
            // A run that stopped on a device failure or a panic still has its telemetry.
            if let Some(s) = e
                .downcast_ref::<RuntimeError>()
                .and_then(RuntimeError::summary)
            {
                print_summary(s);
            }
            return Err(e);
        }
    };
    print_summary(&summary);
    if let Some(json) = &args.json {
        if let Some(dir) = json.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)?;
        }
        std::fs::write(json, serde_json::to_string_pretty(&summary)?)?;
        println!("summary written to {}", json.display());
    }
    Ok(())
}

/// Static dispatch on the integrator: the haptic loop is monomorphised for each.
fn with_integrator<B>(
    kind: IntegratorKind,
    backend: B,
    parts: &SceneParts,
    args: &DemoArgs,
    header: Option<&RecordingHeader>,
) -> anyhow::Result<Summary>
where
    B: CollisionBackend + Send,
{
    match kind {
        IntegratorKind::LinearizedBackwardEuler => {
            run_pipeline(LinearizedBackwardEuler, backend, parts, args, header)
        }
        IntegratorKind::NewtonBackwardEuler => {
            run_pipeline(NewtonBackwardEuler::default(), backend, parts, args, header)
        }
        IntegratorKind::Rk4 => run_pipeline(Rk4, backend, parts, args, header),
        IntegratorKind::ForwardEuler => run_pipeline(ForwardEuler, backend, parts, args, header),
    }
}

fn run_pipeline<I, B>(
    integrator: I,
    backend: B,
    parts: &SceneParts,
    args: &DemoArgs,
    header: Option<&RecordingHeader>,
) -> anyhow::Result<Summary>
where
    I: Integrator + Send,
    B: CollisionBackend + Send,
{
    let mut pipeline = PipelineBuilder::new(parts.body, parts.tool_pose)
        .integrator(integrator)
        .backend(backend)
        .contact_model(PenaltyModel::new(parts.penalty)?)
        .device(parts.hand_device()?)
        .coupling(parts.coupling)
        .config(parts.config)
        .build()?;
    println!(
        "running {:.1} s {} with {}, {} back-end, haptic {:.0} Hz",
        args.seconds,
        if args.virtual_time {
            "in virtual time"
        } else {
            "in real time"
        },
        args.integrator,
        args.backend,
        parts.config.haptic_rate_hz,
    );
    let bar = ProgressBar::new((args.seconds * 1000.0) as u64);
    bar.set_style(ProgressStyle::with_template(
        "{bar:40} {pos:>5}/{len} ms  {msg}",
    )?);
    let summary = if args.virtual_time {
        let latency = ContactLatency::FixedRate {
            rate_hz: parts.contact_hz.unwrap_or(250.0),
        };
        if let (Some(path), Some(header)) = (&args.record, header) {
            let file = std::io::BufWriter::new(
                std::fs::File::create(path)
                    .with_context(|| format!("creating {}", path.display()))?,
            );
            let mut recorder = RunRecorder::new(file, header, parts.config.query.error_threshold)?;
            let outcome = pipeline.run_virtual_observed(args.seconds, latency, &mut recorder);
            let s = crate::recording::finish_recording(outcome, recorder, path)?;
            bar.finish_and_clear();
            println!(
                "recorded to {} (view it with `cargo xtask view {}`)",
                path.display(),
                path.display()
            );
            s
        } else {
            let mut last_ms = 0;
            let s = pipeline.run_virtual(args.seconds, latency, |t, _| {
                let ms = (t * 1000.0) as u64;
                if ms >= last_ms + 50 {
                    bar.set_position(ms);
                    last_ms = ms;
                }
            })?;
            bar.finish_and_clear();
            s
        }
    } else {
        let progress = |snap: &haptic_runtime::Snapshot| {
            bar.set_position((snap.time_s * 1000.0) as u64);
            bar.set_message(format!(
                "{} contacts, {} clusters, {:.2} N",
                snap.raw_contact_count, snap.cluster_count, snap.max_force_n
            ));
        };
        let s = if let (Some(path), Some(header)) = (&args.record, header) {
            let file = std::io::BufWriter::new(
                std::fs::File::create(path)
                    .with_context(|| format!("creating {}", path.display()))?,
            );
            let mut recorder = RunRecorder::new(file, header, parts.config.query.error_threshold)?;
            let outcome = pipeline.run_realtime_recorded(args.seconds, progress, &mut recorder);
            let s = crate::recording::finish_recording(outcome, recorder, path)?;
            println!(
                "recorded to {} (view it with `cargo xtask view {}`)",
                path.display(),
                path.display()
            );
            s
        } else {
            pipeline.run_realtime(args.seconds, progress)?
        };
        bar.finish_and_clear();
        s
    };
    Ok(summary)
}

fn print_summary(s: &Summary) {
    print!("{s}");
}
