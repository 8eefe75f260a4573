//! Runs one case of the accuracy report and prints the result:
//! `cargo run --release --example report_case -- <case> <model> <level> [dt fraction]`,
//! case one of cantilever, frequency, stretch, indentation, sphere, column; model one of msm, lshm-node,
//! lshm-cluster, deb, deb-corotated, pba, nh; level 0 (coarsest) to 5.
//!
//! `cargo run --release --example report_case -- extreme <n> <model> [cube side]` runs
//! extreme case n (0 twist, 1 squash, 2 stiff at 1 ms, 3 stiff at auto, 4 dt 10x, 5 needle
//! jerk, 6 needle rotation, 7 insert/extract cycles) at the full report's size.

use needlesim::core::scene::BackendChoice;
use needlesim_report::cases::{run_case, CaseId, ModelId, RunSpec};
use needlesim_report::extreme::{run_extreme, ExtremeCase, ExtremeSize};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: report_case <case> <model> <level> [dt fraction] | report_case extreme <n> <model> [cube side]";
    let model_arg = |i: usize| {
        ModelId::ALL
            .into_iter()
            .find(|m| Some(m.label()) == args.get(i).map(String::as_str))
            .ok_or(usage)
    };
    if args.first().map(String::as_str) == Some("extreme") {
        let n: usize = args.get(1).ok_or(usage)?.parse()?;
        let case = *ExtremeCase::ALL.get(n).ok_or(usage)?;
        let model = model_arg(2)?;
        let size = ExtremeSize {
            cube_side: args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(7),
            needle_spacing: 0.025,
            cycles: 1000,
        };
        let r = run_extreme(case, model, &size)?;
        println!("{r:#?}");
        return Ok(());
    }
    let case = CaseId::ALL
        .into_iter()
        .find(|c| Some(c.label()) == args.first().map(String::as_str))
        .ok_or(usage)?;
    let model = model_arg(1)?;
    let level: usize = args.get(2).ok_or(usage)?.parse()?;
    let dt_fraction: f64 = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(0.5);
    let spec = RunSpec {
        level,
        dt_fraction,
        backend: BackendChoice::CpuParallel,
    };
    let r = run_case(case, model, &spec)?;
    println!("{r:#?}");
    Ok(())
}
