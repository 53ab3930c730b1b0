//! `cargo xtask study …`: the paper's experiments.

mod compare;
mod contact_run;
mod cup;
pub(crate) mod free_space;
mod jaws;
mod report;
pub(crate) mod work_precision;

use crate::OutArgs;

/// Which study.
#[derive(clap::Subcommand, Debug)]
pub enum Study {
    /// Fig. 3: integrators against tool mass in free space, on the built-in hand motion or a
    /// recorded one (`--trajectory FILE`).
    FreeSpace(free_space::FreeSpaceArgs),
    /// Fig. 4: the spoon in the cup.
    Cup(OutArgs),
    /// Fig. 6: the jaws.
    Jaws(OutArgs),
    /// Integrators' error against run time (work-precision diagrams).
    WorkPrecision(OutArgs),
    /// Every combination of a study file's axes on your own scene, ranked by run time within an
    /// error budget (`--study FILE`; examples in `xtask/studies/`).
    Compare(compare::CompareArgs),
    /// Every study, and a report.
    All(OutArgs),
}

/// Runs a study.
pub fn run(which: Study) -> anyhow::Result<()> {
    match which {
        Study::FreeSpace(a) => free_space::run(&a),
        Study::Cup(a) => cup::run(&a),
        Study::Jaws(a) => jaws::run(&a),
        Study::WorkPrecision(a) => work_precision::run(&a),
        Study::Compare(a) => compare::run(&a),
        Study::All(a) => {
            free_space::run(&free_space::FreeSpaceArgs {
                out: a.clone(),
                trajectory: None,
                write_trajectory: None,
            })?;
            cup::run(&a)?;
            jaws::run(&a)?;
            report::write(&a)
        }
    }
}
