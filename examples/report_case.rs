//! Runs one reference case of the accuracy report and prints the result:
//! `cargo run --release --example report_case -- <case> <model> <level> [dt fraction]`,
//! case one of cantilever, frequency, stretch, indentation; model one of msm, lshm-node,
//! lshm-cluster, deb, deb-corotated, pba; level 0 (coarsest) to 5.

use needlesim::core::scene::BackendChoice;
use needlesim::report::cases::{run_case, CaseId, ModelId, RunSpec};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: report_case <case> <model> <level> [dt fraction]";
    let case = CaseId::ALL
        .into_iter()
        .find(|c| Some(c.label()) == args.first().map(String::as_str))
        .ok_or(usage)?;
    let model = ModelId::ALL
        .into_iter()
        .find(|m| Some(m.label()) == args.get(1).map(String::as_str))
        .ok_or(usage)?;
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
