//! The study file of `study compare`: a scene, a hand motion, a run length and the axes to vary.
//!
//! ```toml
//! scene = "../scenes/spoon-cup.toml"   # relative to the study file
//! # motion = "hand.csv"                # a recording in the replay format; default: the scene's waypoints
//! duration_s = 2.0                     # simulated seconds per configuration
//! error_budget = 0.1                   # force error (relative to the reference) a ranked configuration may have
//!
//! [axes]                               # every axis optional; absent = the scene's value
//! integrator = ["backward_euler", "rk4"]
//! backend = ["lod", "parry"]
//! error_threshold = [0.0, 0.025]
//! mass_kg = [0.01, 0.1]
//! coupling_stiffness_n_per_m = [200.0]
//! contact_stiffness_n_per_m = [2000.0]
//! contact_hz = [250.0]
//! haptic_hz = [1000.0]
//! ```
//!
//! Unknown fields are refused and every error names the field it is about.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use haptic_core::Real;
use haptic_dynamics::IntegratorKind;
use serde::Deserialize;

/// A collision back-end of the study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum Backend {
    /// The native multiresolution back-end.
    Lod,
    /// parry3d.
    Parry,
}

/// The study file as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StudyToml {
    scene: PathBuf,
    motion: Option<PathBuf>,
    #[serde(default = "default_duration")]
    duration_s: Real,
    #[serde(default = "default_budget")]
    error_budget: Real,
    #[serde(default)]
    axes: AxesToml,
}

fn default_duration() -> Real {
    2.0
}

fn default_budget() -> Real {
    0.1
}

/// The axes as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct AxesToml {
    integrator: Option<Vec<String>>,
    backend: Option<Vec<String>>,
    error_threshold: Option<Vec<Real>>,
    mass_kg: Option<Vec<Real>>,
    coupling_stiffness_n_per_m: Option<Vec<Real>>,
    contact_stiffness_n_per_m: Option<Vec<Real>>,
    contact_hz: Option<Vec<Real>>,
    haptic_hz: Option<Vec<Real>>,
}

/// A validated study.
#[derive(Debug, Clone)]
pub(crate) struct Study {
    /// The scene file (resolved).
    pub(crate) scene: PathBuf,
    /// A recording to replay as the device, or `None` for the scene's hand.
    pub(crate) motion: Option<PathBuf>,
    /// Simulated seconds per configuration.
    pub(crate) duration_s: Real,
    /// The force error a configuration may have to be ranked first.
    pub(crate) error_budget: Real,
    /// The axes; `None` keeps the scene's value.
    pub(crate) integrators: Vec<IntegratorKind>,
    pub(crate) backends: Vec<Backend>,
    pub(crate) thresholds: Option<Vec<Real>>,
    pub(crate) masses_kg: Option<Vec<Real>>,
    pub(crate) coupling_stiffness: Option<Vec<Real>>,
    pub(crate) contact_stiffness: Option<Vec<Real>>,
    pub(crate) contact_hz: Option<Vec<Real>>,
    pub(crate) haptic_hz: Option<Vec<Real>>,
}

/// The longest run a study may ask for (s).
pub(crate) const MAX_DURATION_S: Real = 600.0;

/// One combination of the axes (`None`: the scene's value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Config {
    pub(crate) integrator: IntegratorKind,
    pub(crate) backend: Backend,
    pub(crate) error_threshold: Option<Real>,
    pub(crate) mass_kg: Option<Real>,
    pub(crate) coupling_stiffness_n_per_m: Option<Real>,
    pub(crate) contact_stiffness_n_per_m: Option<Real>,
    pub(crate) contact_hz: Option<Real>,
    pub(crate) haptic_hz: Option<Real>,
}

/// Checks every value of an optional axis with `rule`, naming the field.
fn axis(
    field: &str,
    values: Option<Vec<Real>>,
    rule: (&str, fn(Real) -> bool),
) -> anyhow::Result<Option<Vec<Real>>> {
    let Some(v) = values else { return Ok(None) };
    if v.is_empty() {
        bail!("axes.{field}: empty (leave it out to keep the scene's value)");
    }
    if let Some(bad) = v.iter().find(|x| !(rule.1)(**x)) {
        bail!("axes.{field}: {bad} is out of range (expected {})", rule.0);
    }
    for (i, a) in v.iter().enumerate() {
        if v[..i].contains(a) {
            bail!("axes.{field}: {a} is listed twice");
        }
    }
    Ok(Some(v))
}

impl Study {
    /// Reads and validates a study file; relative paths are resolved against its folder.
    ///
    /// # Errors
    /// An unreadable or malformed file, an unknown field, an axis value out of range, an
    /// unknown integrator or back-end, an empty axis, a missing scene or recording.
    pub(crate) fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading the study {}", path.display()))?;
        let raw: StudyToml =
            toml::from_str(&text).with_context(|| format!("study {}", path.display()))?;
        let base = path.parent().unwrap_or_else(|| Path::new("."));
        let scene = base.join(&raw.scene);
        if !scene.is_file() {
            bail!("scene: {} does not exist", scene.display());
        }
        if !(raw.duration_s.is_finite() && raw.duration_s > 0.0 && raw.duration_s <= MAX_DURATION_S)
        {
            bail!(
                "duration_s: {} (expected > 0 and at most {MAX_DURATION_S} s)",
                raw.duration_s
            );
        }
        let motion = raw.motion.map(|m| base.join(m));
        if let Some(m) = &motion {
            if !m.is_file() {
                bail!("motion: {} does not exist", m.display());
            }
            // Read it now, so that a malformed recording stops the study before it runs.
            let replay = haptic_device::ReplayDevice::open(m)
                .with_context(|| format!("motion: {}", m.display()))?;
            let (t0, t1) = replay.time_span_s();
            if t1 - t0 < raw.duration_s {
                eprintln!(
                    "warning: motion {} lasts {:.2} s, less than duration_s = {} s: the hand holds its last pose after it",
                    m.display(),
                    t1 - t0,
                    raw.duration_s
                );
            }
        }
        if !(raw.error_budget.is_finite() && raw.error_budget > 0.0) {
            bail!("error_budget: {} (expected > 0)", raw.error_budget);
        }
        let a = raw.axes;
        let integrators = match a.integrator {
            None => vec![IntegratorKind::LinearizedBackwardEuler],
            Some(v) if v.is_empty() => bail!("axes.integrator: empty"),
            Some(v) => {
                let kinds: Vec<IntegratorKind> = v
                    .iter()
                    .map(|s| {
                        s.parse().map_err(|_| {
                            anyhow::anyhow!(
                                "axes.integrator: unknown integrator `{s}` (backward_euler, newton_backward_euler, rk4 or forward_euler)"
                            )
                        })
                    })
                    .collect::<anyhow::Result<_>>()?;
                for (i, k) in kinds.iter().enumerate() {
                    if kinds[..i].contains(k) {
                        bail!("axes.integrator: {k} is listed twice");
                    }
                }
                kinds
            }
        };
        let backends = match a.backend {
            None => vec![Backend::Lod],
            Some(v) if v.is_empty() => bail!("axes.backend: empty"),
            Some(v) => v
                .iter()
                .map(|s| match s.as_str() {
                    "lod" => Ok(Backend::Lod),
                    "parry" => Ok(Backend::Parry),
                    other => bail!("axes.backend: unknown back-end `{other}` (lod or parry)"),
                })
                .collect::<anyhow::Result<Vec<_>>>()?,
        };
        if backends.len() == 2 && backends[0] == backends[1] {
            bail!("axes.backend: listed twice");
        }
        let positive: (&str, fn(Real) -> bool) = ("> 0", |x| x.is_finite() && x > 0.0);
        Ok(Self {
            scene,
            motion,
            duration_s: raw.duration_s,
            error_budget: raw.error_budget,
            integrators,
            backends,
            thresholds: axis(
                "error_threshold",
                a.error_threshold,
                ("in [0, 1)", |x| (0.0..1.0).contains(&x)),
            )?,
            masses_kg: axis("mass_kg", a.mass_kg, positive)?,
            coupling_stiffness: axis(
                "coupling_stiffness_n_per_m",
                a.coupling_stiffness_n_per_m,
                positive,
            )?,
            contact_stiffness: axis(
                "contact_stiffness_n_per_m",
                a.contact_stiffness_n_per_m,
                positive,
            )?,
            contact_hz: axis(
                "contact_hz",
                a.contact_hz,
                ("in [1, 20000] Hz", |x| (1.0..=20_000.0).contains(&x)),
            )?,
            haptic_hz: axis(
                "haptic_hz",
                a.haptic_hz,
                ("in [100, 20000] Hz", |x| (100.0..=20_000.0).contains(&x)),
            )?,
        })
    }

    /// Every combination of the axes, in a fixed order.
    pub(crate) fn configurations(&self) -> Vec<Config> {
        let opt = |v: &Option<Vec<Real>>| -> Vec<Option<Real>> {
            v.as_ref()
                .map_or(vec![None], |v| v.iter().map(|x| Some(*x)).collect())
        };
        let mut out = Vec::new();
        for &integrator in &self.integrators {
            for &backend in &self.backends {
                // The threshold is the LOD back-end's: parry runs once, with none.
                let thresholds = match backend {
                    Backend::Lod => opt(&self.thresholds),
                    Backend::Parry => vec![None],
                };
                for error_threshold in thresholds {
                    for mass_kg in opt(&self.masses_kg) {
                        for coupling in opt(&self.coupling_stiffness) {
                            for contact in opt(&self.contact_stiffness) {
                                for contact_hz in opt(&self.contact_hz) {
                                    for haptic_hz in opt(&self.haptic_hz) {
                                        out.push(Config {
                                            integrator,
                                            backend,
                                            error_threshold,
                                            mass_kg,
                                            coupling_stiffness_n_per_m: coupling,
                                            contact_stiffness_n_per_m: contact,
                                            contact_hz,
                                            haptic_hz,
                                        });
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn study(text: &str) -> anyhow::Result<Study> {
        let dir = std::env::temp_dir().join(format!("haptic-compare-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("scene.toml"), "").unwrap();
        static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let path = dir.join(format!("s{n}.toml"));
        std::fs::write(&path, text).unwrap();
        Study::load(&path)
    }

    #[test]
    fn a_grid_is_every_combination() {
        let s = study(
            "scene = \"scene.toml\"\n[axes]\nintegrator = [\"be\", \"rk4\"]\nbackend = [\"lod\", \"parry\"]\nmass_kg = [0.01, 0.1, 1.0]\n",
        )
        .unwrap();
        let c = s.configurations();
        assert_eq!(c.len(), 12);
        let t = study(
            "scene = \"scene.toml\"\n[axes]\nbackend = [\"lod\", \"parry\"]\nerror_threshold = [0.0, 0.025, 0.05]\n",
        )
        .unwrap();
        assert_eq!(
            t.configurations().len(),
            4,
            "three LOD thresholds and one parry run"
        );
        assert_eq!(c[0].integrator, IntegratorKind::LinearizedBackwardEuler);
        assert_eq!(c[11].mass_kg, Some(1.0));
        assert!(c.iter().all(|c| c.error_threshold.is_none()));
    }

    #[test]
    fn bad_input_names_the_field() {
        let cases = [
            ("scene = \"nope.toml\"\n", "scene"),
            ("scene = \"scene.toml\"\nmotion = \"nope.csv\"\n", "motion"),
            ("scene = \"scene.toml\"\nduration_s = -1.0\n", "duration_s"),
            (
                "scene = \"scene.toml\"\n[axes]\nintegrator = [\"leapfrog\"]\n",
                "axes.integrator",
            ),
            (
                "scene = \"scene.toml\"\n[axes]\nbackend = [\"bullet\"]\n",
                "axes.backend",
            ),
            (
                "scene = \"scene.toml\"\n[axes]\nmass_kg = []\n",
                "axes.mass_kg",
            ),
            (
                "scene = \"scene.toml\"\n[axes]\nmass_kg = [0.1, -1.0]\n",
                "axes.mass_kg",
            ),
            (
                "scene = \"scene.toml\"\n[axes]\nerror_threshold = [1.5]\n",
                "axes.error_threshold",
            ),
            (
                "scene = \"scene.toml\"\n[axes]\nhaptic_hz = [50000.0]\n",
                "axes.haptic_hz",
            ),
            ("scene = \"scene.toml\"\n[axes]\nspeed = [1.0]\n", "speed"),
            (
                "scene = \"scene.toml\"\n[axes]\nmass_kg = [0.1, 0.1]\n",
                "axes.mass_kg",
            ),
            (
                "scene = \"scene.toml\"\n[axes]\ncontact_hz = [1e-9]\n",
                "axes.contact_hz",
            ),
            (
                "scene = \"scene.toml\"\n[axes]\nhaptic_hz = [1.0]\n",
                "axes.haptic_hz",
            ),
            ("scene = \"scene.toml\"\nduration_s = 1e13\n", "duration_s"),
        ];
        for (text, field) in cases {
            let e = format!("{:#}", study(text).unwrap_err());
            assert!(e.contains(field), "{text:?}: {e}");
        }
    }
}
